"""FilteredDerivative: low-pass + filtered backward difference, non-finite samples skipped."""
from __future__ import annotations

import math

import numpy as np
import pytest

from worm_model.live.filters import FilteredDerivative

PERIOD = 1e-3


def test_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError):
        FilteredDerivative(-0.01, PERIOD)
    with pytest.raises(ValueError):
        FilteredDerivative(0.01, 0.0)


def test_first_sample_initialises_without_a_derivative() -> None:
    f = FilteredDerivative(0.01, PERIOD)
    assert f.update(3.5) == (3.5, 0.0)


@pytest.mark.parametrize("slope", [250.0, -40.0])
def test_derivative_of_a_ramp_converges_to_the_slope(slope: float) -> None:
    tau = 0.01
    f = FilteredDerivative(tau, PERIOD)
    n = int(30 * tau / PERIOD)  # 30 time constants (two cascaded first-order lags)
    history = [f.update(slope * k * PERIOD) for k in range(n)]
    value, derivative = history[-1]
    assert derivative == pytest.approx(slope, rel=1e-6)
    # the filtered value lags the ramp by the filter's delay (~tau), not more
    lag = (slope * (n - 1) * PERIOD - value) / slope
    assert 0.5 * tau < lag < 1.5 * tau
    # and it approaches monotonically from 0 (no overshoot on a ramp)
    derivatives = np.array([d for _, d in history])
    assert np.all(np.abs(derivatives) <= abs(slope) * (1 + 1e-9))


def test_low_pass_step_follows_the_first_order_law() -> None:
    tau = 0.02
    f = FilteredDerivative(tau, PERIOD)
    f.update(0.0)
    for k in range(1, 6):
        value, _ = f.update(1.0)
        assert value == pytest.approx(1.0 - math.exp(-k * PERIOD / tau), rel=1e-12)


def test_zero_time_constant_is_a_plain_backward_difference() -> None:
    f = FilteredDerivative(0.0, PERIOD)
    samples = [0.0, 1.0, 4.0, 9.0]
    out = [f.update(x) for x in samples]
    assert [v for v, _ in out] == samples
    assert [d for _, d in out][1:] == pytest.approx(np.diff(samples) / PERIOD)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_samples_are_skipped(bad: float) -> None:
    samples = [0.0, 0.3, 0.5, 0.9, 1.0]
    clean = FilteredDerivative(0.005, PERIOD)
    gappy = FilteredDerivative(0.005, PERIOD)
    for k, x in enumerate(samples):
        expected = clean.update(x)
        if k == 2:
            before = (gappy.value, gappy.derivative)
            out = gappy.update(bad)
            assert out == before  # returns the kept state, finite
            assert (gappy.value, gappy.derivative) == before
        assert gappy.update(x) == expected


def test_non_finite_first_sample_reports_nan_then_initialises() -> None:
    f = FilteredDerivative(0.01, PERIOD)
    value, derivative = f.update(math.nan)
    assert math.isnan(value) and derivative == 0.0
    assert f.update(2.0) == (2.0, 0.0)


def test_noise_on_the_derivative_is_attenuated() -> None:
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 0.5, 5000)  # tacho-like noise [rad/s] on a constant speed
    f = FilteredDerivative(0.01, PERIOD)
    derivatives = np.array([f.update(100.0 + x)[1] for x in noise])[1000:]
    raw = np.diff(noise) / PERIOD
    assert derivatives.std() < 0.05 * raw.std()  # more than 20x quieter than a raw difference
