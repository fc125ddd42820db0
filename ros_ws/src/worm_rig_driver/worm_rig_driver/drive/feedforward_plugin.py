"""Find the estimator a rig runs beside its speed loop (RigLoop's ``feedforward``), by entry point.

The estimators live in torque_estimator, which depends on this package; this
package must not import it back. So a package that provides a rig feedforward
registers a factory under the entry-point group ``worm_rig_driver.feedforward``
(torque_estimator's setup.py: ``torque_estimator =
torque_estimator.control.rig_feedforward:build``), the way ros2cli finds its
verbs, and sim_node / driver_node look it up at start when their parameter
``feedforward_estimator`` names a method. The factory is called as
``factory(method, calibration_file, rig, sample_period)`` and returns a
:class:`~worm_rig_driver.drive.rig_loop.RigFeedforward`; it raises ValueError
(or OSError) with a one-line reason for a method or file it cannot use.
Plain Python; no ROS.
"""
from __future__ import annotations

from importlib.metadata import entry_points

from worm_model.physics.parameters import Rig

from worm_rig_driver.drive.rig_loop import RigFeedforward
from worm_rig_driver.errors import FeedforwardUnavailable

GROUP = "worm_rig_driver.feedforward"


def load_rig_feedforward(method: str, calibration_file: str, rig: Rig, sample_period: float) -> RigFeedforward:
    """The rig feedforward of estimator ``method`` over ``calibration_file`` ("" for none), from the first
    installed provider that takes it.

    Raises:
        FeedforwardUnavailable: no provider installed, or every provider refused (their reasons joined).
    """
    providers = sorted(entry_points(group=GROUP), key=lambda ep: ep.name)
    if not providers:
        raise FeedforwardUnavailable(f"no package provides a rig feedforward (entry points {GROUP}); "
                                     "install torque_estimator")
    reasons = []
    for provider in providers:
        try:
            return provider.load()(method, calibration_file, rig, sample_period)
        except (ValueError, OSError) as err:
            reasons.append(f"{provider.name}: {err}")
    raise FeedforwardUnavailable("; ".join(reasons))


__all__ = ["GROUP", "load_rig_feedforward"]
