"""Causal filters for live sample streams (plain Python, one sample at a time)."""
from __future__ import annotations

import math


class FilteredDerivative:
    """Low-passed signal and its derivative, from uniformly spaced samples.

    A first-order low-pass (time constant tau [s]) on the signal, then a
    backward difference of the filtered value, low-passed again: enough to take
    a usable acceleration [rad/s^2] out of a noisy tachogenerator speed [rad/s].
    A non-finite input is skipped (the state is kept).
    """

    def __init__(self, time_constant: float, period: float) -> None:
        if time_constant < 0 or period <= 0:
            raise ValueError(f"need time_constant >= 0 and period > 0, got {time_constant}, {period}")
        self.period = period
        self.blend = 1.0 if time_constant == 0 else 1.0 - math.exp(-period / time_constant)
        self.value: float | None = None
        self.derivative = 0.0

    def update(self, sample: float) -> tuple[float, float]:
        """Feed one sample; returns (filtered value, filtered derivative per second)."""
        if not math.isfinite(sample):
            return (math.nan if self.value is None else self.value), self.derivative
        if self.value is None:
            self.value = sample
            return self.value, 0.0
        previous = self.value
        self.value += self.blend * (sample - self.value)
        raw = (self.value - previous) / self.period
        self.derivative += self.blend * (raw - self.derivative)
        return self.value, self.derivative
