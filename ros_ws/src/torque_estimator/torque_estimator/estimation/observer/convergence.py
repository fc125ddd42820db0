"""Convergence: whether a Kalman filter's τ_d variance is still settling after a start or a detected jump.

An estimate is TRANSIENT while its filter is still converging: from the filter's start (its prior
variance is the whole torque range) and after each detected load step (the correction adds the step's
own uncertainty). What the variance settles to is the filter's own: it depends on every state and noise
the filter carries (the tacho ripple, the back-EMF error, the ADC instants) and on the operating point,
so no separate model predicts it: the steady-state Riccati solution of the reduced model of
observer.bounds (steady_filter) is 4 to 17 times smaller on the bundled rig, and with it as the reference
an observer started on a drive already running (estimator_node started after the rig) would flag every
estimate TRANSIENT until the first load step.

So the reference is the variance itself, as the filter runs. Converging ends when the variance is back
within twice its value before the jump, or when it has stopped falling: it fell by less than
``fall`` (a fraction) over the last ``window`` samples. That second test ends a start (no value before
it) and a jump after which the operating point moved. While not converging, the reference follows the
variance, so a later jump is judged against the variance just before it. No ROS.
"""
from __future__ import annotations

import math
from collections import deque

#: [samples] over which the variance must have fallen by at least FALL to count as still converging
WINDOW = 50
#: fraction; on the bundled rig at 150 rad/s the observer's variance stops falling by 2 % per 50 samples
#: ~0.6 s after its start, within 5 % of its steady value
FALL = 0.02


class Convergence:
    """Tracks one filter's τ_d variance [(N m)²], one :meth:`transient` call per estimate (module docstring)."""

    def __init__(self, window: int = WINDOW, fall: float = FALL) -> None:
        self.fall = fall
        self._history: deque[float] = deque(maxlen=window + 1)
        self.reference = math.inf  # [(N m)²] the variance before the last jump, or the last settled one
        self.converging = True

    def start(self, reference: float = math.inf) -> None:
        """The filter (re)started (no reference), or a jump was detected with ``reference`` the variance
        just before its correction."""
        self.reference = reference
        self.converging = True
        self._history.clear()

    def transient(self, variance: float) -> bool:
        """Whether the estimate of τ_d ``variance`` is still converging; updates the reference."""
        history = self._history
        history.append(variance)
        if self.converging:
            stopped = len(history) == history.maxlen and variance >= (1.0 - self.fall) * history[0]
            back = variance <= 2.0 * self.reference < math.inf  # no reference after a start
            self.converging = not (back or stopped)
        if not self.converging:
            self.reference = variance
        return self.converging


__all__ = ["FALL", "WINDOW", "Convergence"]
