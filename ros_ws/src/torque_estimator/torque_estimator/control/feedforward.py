"""Which load estimate the speed loop may be fed, and as what torque at the worm.

The rig runs the speed PI itself (worm_rig_driver.drive); the controller node
sends it a set-point and a feedforward torque. That torque is the estimated load
tau_d reflected through the gearbox to the worm at the set-point speed (Eq. 28
with a_w = 0: worm_model.physics.steady_state.balancing_torque), and only an
estimate that passes :class:`FeedforwardGate` is used. Plain Python; no ROS.
Signs: tau_d is positive when it opposes positive worm rotation; the torque at
the worm is positive when it turns the worm positively.
"""
from __future__ import annotations

import math

from torque_estimator.estimation.base import EstimateFlags


class FeedforwardGate:
    """Which load estimate the controller may feed forward (controller_node's rule, plain).

    The latest estimate offered is held. It is used for a control period at
    time ``now`` only if feedforward is enabled, its torque is finite, it is not
    flagged INVALID_INPUT or OUT_OF_CALIBRATION (an extrapolated value is not
    trusted as a command), and its sample's stamp is at most ``timeout`` [s]
    older than ``now`` (when the command goes out: controller_node takes its
    clock, so an estimate that arrives late is as stale as a stalled estimator's):
    a stale torque must not stay in the loop. Otherwise the PI alone holds the speed.
    AMBIGUOUS and TRANSIENT estimates are used: the nearest branch is the best
    guess, and a transient estimate still points the right way. An estimate of a
    load larger than ``max_load`` [N m] (what the rig can meet; the estimator may
    not have flagged it) is not used either: an implausible torque must not reach
    the drive as a command.
    """

    UNUSABLE = EstimateFlags.INVALID_INPUT | EstimateFlags.OUT_OF_CALIBRATION

    def __init__(self, timeout: float, enabled: bool = True, max_load: float = math.inf) -> None:
        self.timeout = timeout
        self.enabled = enabled
        self.max_load = max_load
        self._torque: float | None = None
        self._flags = 0
        self._stamp = 0.0

    def offer(self, torque: float, flags: int, stamp: float) -> None:
        """Hold a new estimate: τ_d [N m], EstimateFlags bits, stamp of the sample it came from [s]."""
        self._torque, self._flags, self._stamp = float(torque), int(flags), float(stamp)

    def load(self, now: float) -> float | None:
        """The usable held τ_d [N m] for a control period at time ``now`` [s], or None."""
        torque = self._torque
        if (not self.enabled or torque is None or self._flags & self.UNUSABLE or not math.isfinite(torque)
                or abs(torque) > self.max_load):
            return None
        return torque if now - self._stamp <= self.timeout else None


__all__ = ["FeedforwardGate"]
