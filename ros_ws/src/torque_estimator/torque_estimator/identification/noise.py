"""The sensors' noise, measured on the record itself: what the observers' gains and the estimators' thresholds read.

A rig file's ``sensors:`` section is the noise of the drive's own measurement chain; a datasheet does
not give it and a borrowed one (another rig's ADC) sets every gain wrong. The record shows it: in
each run, the second difference d_k = x_k - (x_{k-1} + x_{k+1}) / 2 of a channel removes anything
smooth (a speed ramp, a load held) and leaves 1.5 x the white noise's variance; its mean square, trimmed of
what lies beyond 5 rms, is robust to the steps and reversals a record has (:func:`white_noise`).

Ripples periodic in the shaft's angle grow in the second difference with speed: the white noise is
that of the quietest speed band (:func:`white_noise`).

A channel that falls on a grid (an ADC's or an encoder's step) is quantised: the step is the
smallest spacing that most neighbouring distinct values share (:func:`quantum`, None when the
values are not on a grid), its variance step^2 / 12 is part of what the second difference saw, and
the rest is the white noise (the sensors section keeps the two apart: NoiseFigures adds them back).

A record of runs each held at one speed and load is judged on each run's spread about its mean instead
(:func:`held_noise`): a drive that averages its channels (an EPOS's) correlates neighbouring samples,
and a second difference would see little of what a sample deviates by.

The encoder: the worm angle's step is 2 pi / counts per turn (:func:`encoder_counts`, None when the
angle is no encoder's, e.g. the velocity integrated).

No ROS; numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worm_model.physics.units import FloatArray

#: fewest samples a run needs to add to the noise estimate
MIN_RUN = 8
#: a channel is on a grid when this share of its samples lies within GRID_TOLERANCE steps of it
GRID_SHARE = 0.99
GRID_TOLERANCE = 0.01
#: changes smaller than this fraction of a channel's largest value are round-off (a difference of floats)
ROUND_OFF = 1e-9
#: second differences beyond this many rms are a step, not noise (_robust_variance)
TRIM = 5.0
#: speed bins of the noise's speed law (white_noise)
SPEED_BINS = 10


def _second_differences(x: FloatArray, run: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d_k of every run's consecutive kept samples, the index k of each)."""
    ds, ks = [], []
    for r in np.unique(run):
        idx = np.flatnonzero((run == r) & keep)
        if len(idx) < MIN_RUN:
            continue
        xr = x[idx]
        consecutive = np.diff(idx) == 1
        both = consecutive[:-1] & consecutive[1:]
        ds.append((xr[1:-1] - 0.5 * (xr[:-2] + xr[2:]))[both])
        ks.append(idx[1:-1][both])
    return (np.concatenate(ds), np.concatenate(ks)) if ds else (np.zeros(0), np.zeros(0, dtype=int))


def _robust_variance(d: np.ndarray) -> float:
    """The mean square of ``d`` without its outliers (a load step, a reversal): samples beyond TRIM x the rms are
    dropped, again until none is. A trimmed mean square, not the median absolute deviation: a quantised
    channel's differences fall on a grid, and so would its median."""
    keep = np.ones(len(d), dtype=bool)
    for _ in range(20):
        ms = float(np.mean(d[keep] ** 2)) if keep.any() else 0.0
        inside = d ** 2 <= TRIM ** 2 * ms
        if ms == 0.0 or np.array_equal(inside, keep):
            return ms
        keep = inside
    return ms


def white_noise(x: FloatArray, run: np.ndarray, mask: np.ndarray | None = None,
                speed: FloatArray | None = None) -> float:
    """sigma of the white part of channel ``x`` (module docstring), over the runs' samples in ``mask`` (default:
    all finite); NaN with too few samples.

    ``speed`` [rad/s]: the worm speed of every sample. Ripples periodic in the shaft's angle (a tacho's
    commutator, cogging, runout) pass the second difference more the faster they turn, and a drive's own
    averaging may grow with speed: the second difference's robust variance is taken in SPEED_BINS bins of
    equal count, and the white noise is the quietest bin's.
    """
    x = np.asarray(x, dtype=float)
    keep = np.isfinite(x) if mask is None else (np.asarray(mask) & np.isfinite(x))
    d, k = _second_differences(x, run, keep)
    if len(d) < MIN_RUN:
        return math.nan
    if speed is None or len(d) < SPEED_BINS * MIN_RUN:
        return math.sqrt(_robust_variance(d) / 1.5)
    w = np.abs(np.asarray(speed, dtype=float)[k])
    edges = np.quantile(w, np.linspace(0.0, 1.0, SPEED_BINS + 1))
    which = np.clip(np.searchsorted(edges, w, side="right") - 1, 0, SPEED_BINS - 1)
    variances = []
    for b in range(SPEED_BINS):
        part = d[which == b]
        if len(part) >= MIN_RUN:
            variances.append(_robust_variance(part))
    return math.sqrt(min(variances) / 1.5)


def quantum(x: FloatArray) -> float | None:
    """The grid step of channel ``x`` (module docstring), None when its values are not on a grid: the smallest
    change between consecutive samples (round-off aside), if (nearly) every sample lies a whole number of it
    from the first."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if len(x) < MIN_RUN:
        return None
    scale = max(float(np.max(np.abs(x))), 1e-300)
    changes = np.abs(np.diff(x))
    changes = changes[changes > ROUND_OFF * scale]
    if len(changes) < MIN_RUN:
        return None
    step = float(np.min(changes))
    steps = (x - x[0]) / step
    on_grid = np.abs(steps - np.round(steps)) < GRID_TOLERANCE
    return step if np.mean(on_grid) >= GRID_SHARE else None


def encoder_counts(theta: FloatArray) -> int | None:
    """Counts per worm turn of the encoder the angle came from, None when it is on no grid."""
    step = quantum(theta)
    if step is None:
        return None
    counts = 2.0 * math.pi / step
    return int(round(counts)) if abs(counts - round(counts)) < 0.01 * counts and counts >= 4 else None


@dataclass(frozen=True)
class ChannelNoise:
    """One channel's measured noise: the white sigma and the grid step (None: not quantised), SI."""

    white: float
    step: float | None

    @classmethod
    def of(cls, x: FloatArray, run: np.ndarray, mask: np.ndarray | None = None,
           speed: FloatArray | None = None) -> "ChannelNoise":
        """The channel's noise (module docstring): the second difference's sigma less the quantisation's."""
        total = white_noise(x, run, mask, speed)
        step = quantum(x)
        quantisation = 0.0 if step is None else step * step / 12.0
        white = math.sqrt(max(total * total - quantisation, 0.0)) if math.isfinite(total) else math.nan
        return cls(white, step)

    @property
    def total(self) -> float:
        """sigma [SI] with the quantisation added back."""
        return math.sqrt(self.white ** 2 + (0.0 if self.step is None else self.step ** 2 / 12.0))


@dataclass(frozen=True)
class SensorNoise:
    """What :func:`measure` found: the drive current [A], the speed [rad/s] and the encoder (counts per turn)."""

    current: ChannelNoise
    speed: ChannelNoise
    encoder_counts: int | None

    def lines(self) -> list[str]:
        def step(c: ChannelNoise, unit: str) -> str:
            return f", on a grid of {c.step:.4g} {unit}" if c.step is not None else ", not quantised"

        out = [f"sensors (measured on the record): current noise {self.current.white:.3g} A{step(self.current, 'A')}; "
               f"speed noise {self.speed.white:.3g} rad/s{step(self.speed, 'rad/s')}"]
        if self.encoder_counts is not None:
            out[0] += f"; encoder {self.encoder_counts} counts per turn"
        return out


def held_noise(x: FloatArray, run: np.ndarray) -> float:
    """sigma of a channel over runs each held at one operating point (identification.steady): the median over the
    runs of its sample standard deviation about the run's mean. What a sample deviates from its point is what an
    estimator fed these samples sees, whatever made it (noise, a ripple the model does not have, a drive's own
    averaging, which correlates neighbours and hides them from a second difference)."""
    x = np.asarray(x, dtype=float)
    spreads = [float(np.std(x[run == r], ddof=1)) for r in np.unique(run) if np.sum(run == r) >= MIN_RUN]
    return float(np.median(spreads)) if spreads else math.nan


def measure_held(current: FloatArray, omega: FloatArray, theta: FloatArray | None, run: np.ndarray) -> SensorNoise:
    """The sensors' noise of a record of held runs (:func:`held_noise`, less each grid's quantisation)."""
    def channel(x: FloatArray) -> ChannelNoise:
        total, step = held_noise(x, run), quantum(x)
        quantisation = 0.0 if step is None else step * step / 12.0
        return ChannelNoise(math.sqrt(max(total * total - quantisation, 0.0)) if math.isfinite(total) else math.nan,
                            step)

    return SensorNoise(channel(current), channel(omega), encoder_counts(theta) if theta is not None else None)


def measure(current: FloatArray, omega: FloatArray, theta: FloatArray | None, run: np.ndarray,
            moving: np.ndarray | None = None) -> SensorNoise:
    """The sensors' noise of a record (module docstring); ``moving``: the samples to judge them on (a drive held
    at rest shows a quantised channel's noise as none)."""
    return SensorNoise(ChannelNoise.of(current, run, moving, omega), ChannelNoise.of(omega, run, moving, omega),
                       encoder_counts(theta) if theta is not None else None)


__all__ = ["ChannelNoise", "SensorNoise", "encoder_counts", "held_noise", "measure", "measure_held", "quantum",
           "white_noise"]
