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
    trusted as a command), and it is at most ``timeout`` [s] old at ``now``: a
    stale torque must not stay in the loop. AMBIGUOUS and TRANSIENT estimates are
    used: the nearest branch is the best guess, and a transient estimate still
    points the right way. An estimate of a load larger than ``max_load`` [N m]
    (what the rig can meet; the estimator may not have flagged it) is not used
    either: an implausible torque must not reach the drive as a command.

    Age. An estimate carries the stamp of its rig sample, on the rig's clock;
    ``now`` and ``arrival`` are the controller's clock. The two clocks need not
    agree (a simulated rig that runs behind real time, another computer), so the
    gate keeps a lag: the least ``arrival - stamp`` seen, allowed to rise by at
    most ``max_drift`` [s per s] of the controller's clock (a rig falling behind
    real time, a clock slewing); an estimate's age at ``now`` is
    ``now - stamp - lag``. So an estimate that arrives later than the stream's
    best (a loaded machine, a slow link, one held in a queue while a link was
    down) is older by that much, one that never comes ages with the
    controller's clock, and a steady offset is not age. Without ``arrival`` (a
    replay, the benchmark's loop on one clock) the lag is 0 and the age is
    ``now - stamp``.
    """

    #: a plain int: IntFlag arithmetic costs microseconds, and load() runs on every rig sample
    UNUSABLE = int(EstimateFlags.INVALID_INPUT | EstimateFlags.OUT_OF_CALIBRATION)

    def __init__(self, timeout: float, enabled: bool = True, max_load: float = math.inf,
                 max_drift: float = 0.05) -> None:
        self.timeout = timeout
        self.enabled = enabled
        self.max_load = max_load
        self.max_drift = max_drift
        self._torque: float | None = None
        self._flags = 0
        self._stamp = 0.0
        self._lag: float | None = None
        self._last_arrival = 0.0

    def offer(self, torque: float, flags: int, stamp: float, arrival: float | None = None) -> None:
        """Hold a new estimate: τ_d [N m], EstimateFlags bits, stamp of the sample it came from [s, rig's
        clock], when it arrived [s, controller's clock] (None: on the rig's clock, no transit)."""
        self._torque, self._flags, self._stamp = float(torque), int(flags), float(stamp)
        if arrival is None or not math.isfinite(lag := arrival - stamp):
            arrival, lag = stamp, 0.0
        if self._lag is None or lag <= self._lag:
            self._lag = lag
        else:  # a later arrival than the best: only a bounded part of it may be the clocks drifting
            self._lag = min(lag, self._lag + self.max_drift * max(0.0, arrival - self._last_arrival))
        self._last_arrival = arrival

    @property
    def clock_lag(self) -> float:
        """The lag [s]: the rig's clock's offset + the best transit, as far as the estimates tell."""
        return self._lag or 0.0

    def age(self, now: float) -> float:
        """Age [s] at ``now`` (controller's clock) of the held estimate; inf if none."""
        return now - self._stamp - self.clock_lag if self._torque is not None else math.inf

    def load(self, now: float) -> float | None:
        """The usable held τ_d [N m] for a control period at time ``now`` [s], or None."""
        torque = self._torque
        if (not self.enabled or torque is None or self._flags & self.UNUSABLE or not math.isfinite(torque)
                or abs(torque) > self.max_load):
            return None
        return torque if self.age(now) <= self.timeout else None


__all__ = ["FeedforwardGate"]
