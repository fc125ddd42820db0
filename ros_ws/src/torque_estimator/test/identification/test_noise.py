"""The sensors' noise measured on a record (torque_estimator.identification.noise): synthetic channels with a known
white noise, grid step and encoder, through ramps, steps, ripples, gaps and a drive's own averaging.

Tolerances from ten seeds of each case (the largest deviation noted in each test, the bound a little above it).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from torque_estimator.identification.noise import (MIN_RUN, ChannelNoise, SensorNoise, encoder_counts, held_noise,
                                                   measure, measure_held, quantum, white_noise)

SIGMA = 0.02  # [A] the white noise of the synthetic current
LSB = 0.02639  # [A] the NMRV030 rig's current step (rig file: current_lsb)
SEEDS = range(10)


def _record(seed: int, *, steps: bool = False, ripple: float = 0.0, step: float | None = None, runs: int = 4,
            n: int = 2000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(channel, run, worm speed) of ``runs`` runs of 2 s at 1 kHz: a speed ramp 20 -> 320 rad/s, a smooth signal
    (slow sine and a term following the ramp) plus white noise SIGMA; ``steps``: a load step up and a larger one
    down in each run; ``ripple``: an angle-periodic ripple whose amplitude grows with the speed squared; ``step``:
    the channel rounded to that grid."""
    rng = np.random.default_rng(seed)
    xs, run, speed = [], [], []
    for r in range(runs):
        t = np.arange(n) * 1e-3
        w = 20.0 + 300.0 * t / t[-1]
        x = 0.3 + 0.2 * np.sin(np.pi * t) + 0.001 * w + rng.normal(0.0, SIGMA, n)
        if steps:
            x += 0.5 * (t > 0.7) - 0.8 * (t > 1.3)
        x += ripple * (w / 320.0) ** 2 * np.sin(8.0 * w * t)
        xs.append(np.round(x / step) * step if step else x)
        run.append(np.full(n, r))
        speed.append(w)
    return np.concatenate(xs), np.concatenate(run), np.concatenate(speed)


def test_white_noise_through_ramps_and_steps() -> None:
    """The second difference removes the ramps and the sine; the trimmed mean square removes the load steps (their
    differences would add 37 % to the variance). Measured: 0.987..1.015 x SIGMA, steps or not."""
    for seed in SEEDS:
        x, run, _w = _record(seed)
        assert white_noise(x, run) == pytest.approx(SIGMA, rel=0.02), seed
        x, run, _w = _record(seed, steps=True)
        assert white_noise(x, run) == pytest.approx(SIGMA, rel=0.02), seed


def test_the_quietest_speed_band() -> None:
    """A ripple growing with speed passes the second difference: over all samples it reads 1.38 x SIGMA; with
    the speeds, the quietest of the SPEED_BINS bands reads 0.946..1.006 x SIGMA (ten seeds; the minimum of ten
    bins leans low)."""
    for seed in SEEDS:
        x, run, w = _record(seed, ripple=0.05)
        assert 0.93 * SIGMA < white_noise(x, run, speed=w) < 1.02 * SIGMA, seed
    x, run, w = _record(0, ripple=0.05)
    assert white_noise(x, run) > 1.3 * SIGMA


def test_masked_samples_leave_gaps_not_differences() -> None:
    """A steep ramp (1 per sample) with every tenth sample masked out: no second difference spans a gap (one
    would read half the slope, 25 x SIGMA). Measured 0.991..1.014 x SIGMA."""
    for seed in range(5):
        rng = np.random.default_rng(seed)
        x = np.arange(5000.0) + rng.normal(0.0, SIGMA, 5000)
        mask = np.arange(5000) % 10 != 0
        assert white_noise(x, np.zeros(5000, dtype=int), mask) == pytest.approx(SIGMA, rel=0.02), seed


def test_too_few_samples_and_nan() -> None:
    """Runs shorter than MIN_RUN add nothing (NaN when nothing is left); NaN samples are left out."""
    x, run, _w = _record(0)
    short = np.arange(len(x)) % (MIN_RUN - 1)  # every run of MIN_RUN - 1 samples
    assert math.isnan(white_noise(x, np.cumsum(short == 0)))
    holed = x.copy()
    holed[::50] = np.nan
    assert white_noise(holed, run) == pytest.approx(SIGMA, rel=0.02)


def test_quantum_and_the_white_part_of_a_quantised_channel() -> None:
    """Rounded to the NMRV030 current step: the step is found (to round-off), the second difference sees
    SIGMA^2 + LSB^2 / 12 (1.054..1.092 x SIGMA) and the white part, without the step's share, is SIGMA
    (0.983..1.023 x)."""
    for seed in SEEDS:
        x, run, _w = _record(seed, step=LSB)
        assert quantum(x) == pytest.approx(LSB, rel=1e-9)
        c = ChannelNoise.of(x, run)
        assert c.step == pytest.approx(LSB, rel=1e-9)
        assert c.white == pytest.approx(SIGMA, rel=0.03), seed
        assert c.total == pytest.approx(math.sqrt(SIGMA ** 2 + LSB ** 2 / 12), rel=0.03), seed
        assert c.total == pytest.approx(white_noise(x, run), rel=1e-12)


def test_a_channel_off_any_grid() -> None:
    """Continuous values, a constant, too few samples, or a grid only 98 % of the samples lie on: no step."""
    x, run, _w = _record(0)
    assert quantum(x) is None and ChannelNoise.of(x, run).step is None
    assert ChannelNoise.of(x, run).total == ChannelNoise.of(x, run).white
    assert quantum(np.full(100, 0.7)) is None
    assert quantum(np.arange(MIN_RUN - 1) * 0.1) is None
    on_grid = np.round(np.random.default_rng(1).normal(0.0, 1.0, 1000) / 0.1) * 0.1
    assert quantum(on_grid) == pytest.approx(0.1, rel=1e-9)
    on_grid[::50] += 0.037  # 2 % off the grid
    assert quantum(on_grid) is None


@pytest.mark.parametrize("counts", [500, 2048, 4096])
def test_encoder_counts(counts: int) -> None:
    """An angle on a grid of 2 pi / counts: its counts per turn; the angle integrated from a velocity: none."""
    rng = np.random.default_rng(counts)
    angle = np.cumsum(rng.normal(0.01, 0.02, 3000))
    step = 2 * math.pi / counts
    assert encoder_counts(np.round(angle / step) * step) == counts
    assert encoder_counts(angle) is None


def test_held_noise_sees_what_a_drive_averaging_hides() -> None:
    """Six runs held at one level each, the samples a moving average of 8 (an EPOS's): the spread about each run's
    mean is the sample sigma (0.978..1.028 x over six seeds), which the second difference sees less than a third
    of. measure_held takes the grid's share off (step 0.005)."""
    sigma0 = 0.06
    sample_sigma = sigma0 / math.sqrt(8)
    for seed in range(6):
        rng = np.random.default_rng(seed)
        xs, run = [], []
        for r, level in enumerate([0.2, 0.5, -0.3, 1.1, 0.7, -0.9]):
            e = np.convolve(rng.normal(0.0, sigma0, 607), np.ones(8) / 8, mode="valid")
            xs.append(level + e)
            run.append(np.full(len(e), r))
        x, runs = np.concatenate(xs), np.concatenate(run)
        assert held_noise(x, runs) == pytest.approx(sample_sigma, rel=0.04), seed
        assert white_noise(x, runs) < 0.35 * sample_sigma
        stepped = np.round(x / 0.005) * 0.005
        noise = measure_held(stepped, 100.0 * x, None, runs)
        assert noise.current.step == pytest.approx(0.005, rel=1e-9) and noise.speed.step is None
        assert noise.current.white == pytest.approx(sample_sigma, rel=0.04), seed
        expected = math.sqrt(max(held_noise(stepped, runs) ** 2 - 0.005 ** 2 / 12, 0.0))
        assert noise.current.white == pytest.approx(expected, rel=1e-12)
        assert noise.speed.white == pytest.approx(100.0 * held_noise(x, runs), rel=1e-12)
        assert noise.encoder_counts is None
    assert math.isnan(held_noise(np.ones(MIN_RUN - 1), np.zeros(MIN_RUN - 1, dtype=int)))


def test_measure_a_record_and_its_line() -> None:
    """measure: the current's white noise and step, the speed's, each judged in the quietest speed band, and the
    encoder's counts; lines() says them. The quietest of ten bands leans low on a noise the same at every speed:
    measured 0.901..0.974 x SIGMA (current, its step's share taken off) and 0.926..0.959 x (speed), ten seeds."""
    for seed in SEEDS:
        current, run, w = _record(seed, step=LSB)
        omega = w + np.random.default_rng(seed + 100).normal(0.0, 0.5, len(w))
        noise = measure(current, omega, None, run)
        assert 0.88 * SIGMA < noise.current.white < 1.0 * SIGMA, seed
        assert 0.9 * 0.5 < noise.speed.white < 1.0 * 0.5, seed
        assert noise.current.step == pytest.approx(LSB) and noise.speed.step is None and noise.encoder_counts is None
    angle = np.cumsum(np.random.default_rng(8).normal(0.005, 0.01, len(w)))  # slow enough for 1-count changes
    theta = np.round(angle / (2 * math.pi / 2048)) * (2 * math.pi / 2048)
    noise = measure(current, omega, theta, run)
    assert isinstance(noise, SensorNoise) and noise.encoder_counts == 2048
    line, = noise.lines()
    assert f"current noise {noise.current.white:.3g} A, on a grid of 0.02639 A" in line
    assert f"speed noise {noise.speed.white:.3g} rad/s, not quantised" in line
    assert line.endswith("; encoder 2048 counts per turn")
    assert "encoder" not in measure(current, omega, None, run).lines()[0]


def test_measure_on_the_moving_samples() -> None:
    """A drive held at rest shows a quantised channel as constant: over all samples the quietest band (the rest)
    reads no noise at all; judged on the moving samples, the noise is there (within the band's 0.88..1.0 x)."""
    current, run, w = _record(2, step=LSB)
    omega = w + np.random.default_rng(5).normal(0.0, 0.5, len(w))
    rest = np.arange(len(w)) % 2000 < 600  # the first 0.6 s of every run standing, the current on one step
    current[rest], omega[rest] = 5 * LSB, 0.0
    assert measure(current, omega, None, run).current.white == 0.0
    moving = measure(current, omega, None, run, ~rest)
    assert 0.88 * SIGMA < moving.current.white < 1.0 * SIGMA and 0.9 * 0.5 < moving.speed.white < 0.5
