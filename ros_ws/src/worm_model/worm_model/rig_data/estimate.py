"""One sample's load-torque estimate: the one record of an estimate on its way from an estimator to the topics.

Every per-sample estimator makes it (torque_estimator's LiveEstimator for the maps, the observers' streams), the
rig's feedforward returns it, and the publishers (worm_rig_driver.nodes.estimate_topics, the standard outputs)
read it. A NamedTuple: named fields at the cost of a tuple (the graph makes one per sample at 1 kHz).

Signs: ``torque`` is tau_d on the gear shaft [N m], positive where it opposes positive worm rotation; speeds
positive in the worm's positive rotation. ``flags`` are torque_estimator.estimation.base.EstimateFlags bits
(worm_rig_driver.robot.standard_outputs names the ones the standard outputs leave out). No ROS.
"""
from __future__ import annotations

import math
from typing import NamedTuple


class Estimate(NamedTuple):
    """One sample's estimate (module docstring)."""

    torque: float  #: [N m] tau_d; NaN for an invalid input
    uncertainty: float  #: [N m] its 1-sigma spread (AMBIGUOUS: wide enough to reach the other candidate)
    flags: int  #: EstimateFlags bits
    omega_worm: float  #: [rad/s] the filtered worm speed the estimate is at
    current_drive: float  #: [A] the filtered (and, for a map, inertia-compensated) drive current it is at
    other: float = math.nan  #: [N m] the other candidate load where two explain the sample (AMBIGUOUS), else NaN
    disturbance: float = math.nan  #: [N m] an observer's lumped disturbance on the worm at it, else NaN
    jump: bool = False  #: an observer detected a load step at this sample

    def with_torque(self, torque: float) -> "Estimate":
        """This estimate with tau_d [N m] replaced (a correction or a bias applied on the way)."""
        return Estimate(torque, *self[1:])


__all__ = ["Estimate"]
