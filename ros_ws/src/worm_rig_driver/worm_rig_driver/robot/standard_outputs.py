"""What the standard outputs (sensor_msgs/JointState effort, geometry_msgs/WrenchStamped torque) carry of a load
estimate: the load, only where the estimator trusts it; NaN otherwise, at once.

worm_msgs/TorqueEstimate carries every estimate with its quality flags: a consumer of our own type
decides. The standard types have no flags, and what reads them (a collision detector thresholding
a joint's external effort, an admittance controller, a feedforward) takes a number there as a
load. So an estimate flagged

* INVALID_INPUT (a NaN/inf input: nothing was measured),
* TRANSIENT (the estimator's own model does not hold: a speed reversal, an acceleration beyond
  the quasi-static map, the observer still converging after a detected step or a restart), or
* OUT_OF_CALIBRATION (beyond what the drive's load can be, or at speeds it never saw),

or a finite one larger than ``max_load`` (the controller's plausibility bound, 1.5 x the rig file's
max_load_torque), goes out as NaN, from the first such sample to the first trusted one. An AMBIGUOUS
estimate (the self-locking V, the filter on the branch it is on, its uncertainty reaching the other)
is the estimator's best value and goes out as it is.

Why NaN at once, not the last trusted value held for a while: it is what ROS 2's own components
write and read for "no value". ros2_control's joint_state_broadcaster publishes NaN for an interface
a joint does not have; the admittance_controller of ros2_controllers reads a force/torque sensor
with any NaN component as no wrench (zero) and its joint states with NaN as the last command; a
threshold ``abs(effort) > limit`` is False for NaN, so a collision detector does not fire on it;
our controller_node takes only finite values. A held value would be a load nobody measured,
reported as current for as long as the hold lasts, the very thing the standard outputs must not
carry; and a reversal's untrusted stretch (a few to some tens of samples) is shorter than any hold
that would bridge it usefully. A consumer that filters must skip NaN (the convention above).

Signs (ROS's, for both types): the torque the load applies to the joint in its positive direction,
-tau_d (tau_d positive opposing positive worm rotation, physics.md §2).

Plain Python; the flags are worm_msgs/TorqueEstimate's FLAG_* (torque_estimator's EstimateFlags).
"""
from __future__ import annotations

import math

#: worm_msgs/TorqueEstimate's FLAG_* bits
FLAG_OUT_OF_CALIBRATION, FLAG_AMBIGUOUS, FLAG_INVALID_INPUT, FLAG_TRANSIENT = 1, 2, 4, 8
#: the flags of an estimate the standard outputs do not carry as a load
UNTRUSTED = FLAG_OUT_OF_CALIBRATION | FLAG_INVALID_INPUT | FLAG_TRANSIENT


class StandardEffort:
    """The effort [N m] the standard outputs carry for each estimate (module docstring), and counts of
    what they withheld.

    Args:
        max_load: |tau_d| [N m] beyond which a finite, unflagged estimate is taken as implausible.
    """

    def __init__(self, max_load: float = math.inf) -> None:
        if not max_load > 0:
            raise ValueError(f"max_load must be > 0, got {max_load}")
        self.max_load = max_load
        self.carried = 0  # estimates that went out as a load
        self.withheld = 0  # estimates that went out as NaN

    def effort(self, torque: float, flags: int) -> float:
        """-tau_d of an estimate (tau_d [N m], its flags), or NaN where it is not trusted."""
        if flags & UNTRUSTED or not math.isfinite(torque) or abs(torque) > self.max_load:
            self.withheld += 1
            return math.nan
        self.carried += 1
        return -torque


__all__ = ["FLAG_AMBIGUOUS", "FLAG_INVALID_INPUT", "FLAG_OUT_OF_CALIBRATION", "FLAG_TRANSIENT", "UNTRUSTED",
           "StandardEffort"]
