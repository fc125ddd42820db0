"""What the standard outputs (sensor_msgs/JointState effort, geometry_msgs/WrenchStamped torque) carry of a load
estimate: the load, only where the estimator trusts it; NaN otherwise, from the first untrusted sample on.

worm_msgs/TorqueEstimate carries every estimate with its quality flags: a consumer of our own type
decides. The standard types have no flags, and what reads them (a collision detector thresholding
a joint's external effort, an admittance controller, a feedforward) takes a number there as a
load. So an estimate flagged

* INVALID_INPUT (a NaN/inf input: nothing was measured),
* TRANSIENT (the estimator's own model does not hold: a speed reversal, an acceleration beyond
  the quasi-static map, the observer still converging after a detected step or a restart),
* OUT_OF_CALIBRATION (beyond what the drive's load can be, or at speeds it never saw),
* AMBIGUOUS (a self-locking drive's two candidate loads, and nothing tells them apart: neither the
  load prior nor a load that persisted across a stop or a reversal), or
* STANDSTILL (a self-locked drive standing: its friction holds the load, the current shows nothing of
  it; the estimator holds its last moving value),

or a finite one larger than ``max_load`` (the controller's plausibility bound, 1.5 x the rig file's
max_load_torque), goes out as NaN, from the first such sample until SETTLE (10 ms) of trusted ones
in a row: the estimate is judged on every sample, published or not, and the samples at the edges
of a flagged stretch (a reversal's first and last few, where the estimator has lost its model or is
finding it again) are not trusted either. Nor is the first START (50 ms) after the estimator's start
or restart (a drive breaking away from standstill, where an observer has yet to find the load).

Why NaN from the first untrusted sample, not the last trusted value held for a while: it is what ROS 2's own components
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
FLAG_OUT_OF_CALIBRATION, FLAG_AMBIGUOUS, FLAG_INVALID_INPUT, FLAG_TRANSIENT, FLAG_STANDSTILL = 1, 2, 4, 8, 16
#: the flags of an estimate the standard outputs do not carry as a load
UNTRUSTED = FLAG_OUT_OF_CALIBRATION | FLAG_AMBIGUOUS | FLAG_INVALID_INPUT | FLAG_TRANSIENT | FLAG_STANDSTILL


#: [s] of trusted estimates needed after an untrusted one before the standard outputs carry a load again
SETTLE = 0.01
#: [s] of estimates needed after the estimator's start (or restart) before the standard outputs carry a load:
#: a drive starting from standstill breaks away and accelerates hard, where an observer has yet to find the load
START = 0.05


class StandardEffort:
    """The effort [N m] the standard outputs carry (module docstring), and counts of what they withheld.

    Every sample's estimate goes to :meth:`observe` (its flags, and its torque where it was computed),
    published or not; :meth:`effort` gives what a published one carries: -tau_d once ``settle`` [s] of
    samples in a row were trusted (the edges of a flagged stretch, a reversal's, are not: an estimator
    that has just lost its model recovers over a few samples), NaN otherwise.

    After the estimator's start, and after :meth:`restart` (its state started again: a new rig session),
    ``start`` [s] of samples go out as NaN whatever their flags.

    Args:
        max_load: |tau_d| [N m] beyond which a finite, unflagged estimate is taken as implausible.
        sample_period: [s] between the samples observed.
        settle: [s] of trusted samples needed after an untrusted one.
        start: [s] of samples needed after the estimator's (re)start.
    """

    def __init__(self, max_load: float = math.inf, sample_period: float = 1e-3, settle: float = SETTLE,
                 start: float = START) -> None:
        if not (max_load > 0 and sample_period > 0 and settle >= 0 and start >= 0):
            raise ValueError(f"need max_load > 0, sample_period > 0, settle >= 0, start >= 0; got {max_load}, "
                             f"{sample_period}, {settle}, {start}")
        self.max_load = max_load
        self.settle_samples = int(math.ceil(settle / sample_period - 1e-9))
        self.start_samples = int(math.ceil(start / sample_period - 1e-9))
        self._clean = 0  # trusted samples in a row (none yet: not trusted)
        self._since_start = 0  # samples since the estimator's (re)start
        self.carried = 0  # published estimates that went out as a load
        self.withheld = 0  # published estimates that went out as NaN

    def observe(self, flags: int, torque: float | None = None) -> None:
        """One sample's estimate: its EstimateFlags bits and tau_d [N m] (None: not computed for it)."""
        bad = flags & UNTRUSTED or (torque is not None and not (math.isfinite(torque) and abs(torque) <= self.max_load))
        self._clean = 0 if bad else self._clean + 1
        self._since_start += 1

    def restart(self) -> None:
        """The estimator started again (its state reset): the next ``start`` of samples are not trusted."""
        self._clean = self._since_start = 0

    @property
    def trusted(self) -> bool:
        """Whether the newest sample observed may go out as a load."""
        return self._clean > self.settle_samples and self._since_start > self.start_samples

    def effort(self, torque: float) -> float:
        """What the standard outputs carry for the newest sample observed, whose tau_d is ``torque`` [N m]:
        -tau_d, or NaN where it is not trusted."""
        if not self.trusted or not math.isfinite(torque) or abs(torque) > self.max_load:
            self.withheld += 1
            return math.nan
        self.carried += 1
        return -torque


__all__ = ["FLAG_AMBIGUOUS", "FLAG_INVALID_INPUT", "FLAG_OUT_OF_CALIBRATION", "FLAG_STANDSTILL", "FLAG_TRANSIENT",
           "SETTLE", "START", "UNTRUSTED", "StandardEffort"]
