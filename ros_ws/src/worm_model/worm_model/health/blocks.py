"""Rig samples reduced to short blocks (50 ms by default): what the check and the live monitor both read.

A block is ``size`` consecutive samples of one run. Its statistics (:class:`Blocks`): the mean worm
speed and its least-squares slope (the acceleration), whether the worm kept one direction, the
mean drive current and its within-block variance, the mean load torque, the mean transmission
error (gear angle less i x worm angle, where a gear encoder exists), the means of sin and cos of the
gear's angle as the worm encoder gives it (i x worm angle: the phase of a once-per-gear-turn ripple,
wheel runout, whose period at low speed is longer than a point) and the mean oil temperature (where
measured). The sums behind them are formed once (:func:`block_sums`), whether the samples come
from a recorded run (:func:`blocks_from_data`: a run's samples cut into whole blocks) or one sample at
a time from n rigs side by side (:class:`BlockAccumulator`, the batch simulator), so both give the same
blocks.

Units: SI and degC; the transmission error in rad at the gear shaft.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from worm_model.physics.units import FloatArray
from worm_model.rig_data.schema import MeasuredData

#: default block length [s]
BLOCK_TIME = 0.05
#: the sums a block keeps, per block (arrays of the leading shape of the samples)
SUMS = ("w", "kw", "w_min", "w_max", "i", "i2", "di2", "d", "gs", "gc", "te", "te_n", "temp", "temp_n")


@dataclass
class Blocks:
    """Statistics of consecutive blocks, arrays of shape (m,) (or (m, rigs) before :meth:`rig`).

    t: block start [s]; duration [s]; omega [rad/s] mean; alpha [rad/s^2] slope of the speed;
    one_way: the speed kept one sign; current [A] mean; current_var [A^2] within the block;
    current_noise [A^2]: the variance of the current's white noise, half the mean square of its
    sample-to-sample differences (blind to ripples and drifts slower than a few samples);
    tau_load [N m] mean; gear_sin, gear_cos: means of sin, cos of i x theta_worm;
    te [rad] mean transmission error (NaN without a gear encoder);
    temperature [degC] mean (NaN where not measured); run: the run each block belongs to;
    size: samples per block.
    """

    t: FloatArray
    duration: float
    omega: FloatArray
    alpha: FloatArray
    one_way: np.ndarray
    current: FloatArray
    current_var: FloatArray
    current_noise: FloatArray
    tau_load: FloatArray
    gear_sin: FloatArray
    gear_cos: FloatArray
    te: FloatArray
    temperature: FloatArray
    run: np.ndarray
    size: int

    def __len__(self) -> int:
        return len(self.t)

    def rig(self, k: int) -> "Blocks":
        """The blocks of rig k of an accumulator's 2-D blocks."""
        cut = {f.name: (getattr(self, f.name)[:, k] if np.ndim(getattr(self, f.name)) == 2 else getattr(self, f.name))
               for f in fields(self)}
        return Blocks(**cut)

    def select(self, mask: np.ndarray) -> "Blocks":
        out = {f.name: (getattr(self, f.name)[mask] if np.ndim(getattr(self, f.name)) >= 1 else getattr(self, f.name))
               for f in fields(self)}
        return Blocks(**out)


def block_sums(omega, current, tau_load, gear_angle, te=None, temperature=None, axis: int = -1
               ) -> dict[str, FloatArray]:
    """The sums of :data:`SUMS` over ``axis`` (the samples of a block, in order); gear_angle [rad] = i theta_worm."""
    w = np.asarray(omega, dtype=float)
    k = np.arange(w.shape[axis], dtype=float).reshape([-1 if a == (axis % w.ndim) else 1 for a in range(w.ndim)])
    i = np.asarray(current, dtype=float)
    di = np.diff(i, axis=axis)
    out = {"w": w.sum(axis), "kw": (k * w).sum(axis), "w_min": w.min(axis), "w_max": w.max(axis),
           "i": i.sum(axis), "i2": (i * i).sum(axis), "di2": (di * di).sum(axis),
           "d": np.asarray(tau_load, dtype=float).sum(axis)}
    g = np.asarray(gear_angle, dtype=float)
    out["gs"], out["gc"] = np.sin(g).sum(axis), np.cos(g).sum(axis)
    for name, values in (("te", te), ("temp", temperature)):
        if values is None:
            out[name] = np.zeros_like(out["w"])
            out[name + "_n"] = np.zeros_like(out["w"])
        else:
            v = np.asarray(values, dtype=float)
            ok = np.isfinite(v)
            out[name] = np.where(ok, v, 0.0).sum(axis)
            out[name + "_n"] = ok.sum(axis).astype(float)
    return out


def finish(sums: dict[str, FloatArray], size: int, period: float, t: FloatArray, run: np.ndarray) -> Blocks:
    """Blocks from their sums (``size`` samples of ``period`` [s] each)."""
    n = float(size)
    omega = sums["w"] / n
    # least-squares slope over the sample index k = 0..n-1: (sum k w - (n-1)/2 sum w) / (n (n^2 - 1) / 12)
    slope = (sums["kw"] - 0.5 * (n - 1.0) * sums["w"]) / (n * (n * n - 1.0) / 12.0) if size > 1 \
        else np.zeros_like(omega)
    current = sums["i"] / n
    with np.errstate(invalid="ignore", divide="ignore"):
        te = np.where(sums["te_n"] > 0, sums["te"] / np.maximum(sums["te_n"], 1.0), np.nan)
        temperature = np.where(sums["temp_n"] > 0, sums["temp"] / np.maximum(sums["temp_n"], 1.0), np.nan)
    return Blocks(t=np.asarray(t, dtype=float), duration=size * period, omega=omega, alpha=slope / period,
                  one_way=(sums["w_min"] * sums["w_max"]) > 0.0, current=current,
                  current_var=np.maximum(sums["i2"] / n - current * current, 0.0),
                  current_noise=sums["di2"] / (2.0 * max(n - 1.0, 1.0)), tau_load=sums["d"] / n,
                  gear_sin=sums["gs"] / n, gear_cos=sums["gc"] / n, te=te,
                  temperature=temperature, run=np.asarray(run), size=size)


def transmission_error(ratio: float, theta_worm, theta_gear) -> FloatArray | None:
    """theta_gear - i theta_worm [rad] (worm-referenced gear angle less the worm's), None without a gear angle."""
    if theta_gear is None:
        return None
    return np.asarray(theta_gear, dtype=float) - ratio * np.asarray(theta_worm, dtype=float)


def blocks_from_data(data: MeasuredData, ratio: float, block_time: float = BLOCK_TIME) -> Blocks:
    """The whole blocks of every run of a recorded data set (a run's last partial block is left out).

    Args:
        ratio: the gearbox's speed ratio i (for the transmission error).
        block_time: block length [s]; at least 2 samples.
    """
    period = data.sample_period
    size = max(2, int(round(block_time / period))) if np.isfinite(period) and period > 0 else 2
    te_all = transmission_error(ratio, data.theta_worm, data.theta_gear)
    parts: list[tuple[dict[str, FloatArray], FloatArray, np.ndarray]] = []
    for run in np.unique(data.run):
        index = np.flatnonzero(data.run == run)
        m = len(index) // size
        if m == 0:
            continue
        take = index[: m * size]

        def cut(values):
            return None if values is None else (
                np.asarray(values, dtype=float)[take].reshape(m, size))  # noqa: B023 - cut runs only in this iteration

        sums = block_sums(cut(data.omega_worm), cut(data.current_drive), cut(data.tau_load),
                          ratio * cut(data.theta_worm), cut(te_all), cut(data.temperature), axis=1)
        parts.append((sums, data.t[take].reshape(m, size)[:, 0], np.full(m, run)))
    if not parts:
        empty = {name: np.zeros(0) for name in SUMS}
        return finish(empty, size, period, np.zeros(0), np.zeros(0, dtype=int))
    sums = {name: np.concatenate([p[0][name] for p in parts]) for name in SUMS}
    return finish(sums, size, period, np.concatenate([p[1] for p in parts]), np.concatenate([p[2] for p in parts]))


class BlockAccumulator:
    """Blocks of n rigs sampled side by side, one sample (arrays of shape (n,)) at a time.

    Only the sums of the block in progress and the finished blocks' statistics are kept, so a
    long batch of many rigs does not hold its samples. :meth:`blocks` gives (m, n) arrays;
    ``Blocks.rig(k)`` one rig's.
    """

    def __init__(self, n: int, period: float, ratio: float, block_time: float = BLOCK_TIME) -> None:
        self.n = n
        self.period = period
        self.ratio = ratio
        self.size = max(2, int(round(block_time / period)))
        self._rows: list[dict[str, FloatArray]] = []
        self._buffer: dict[str, np.ndarray] = {}
        self._k = 0
        self._t0 = 0.0
        self._t: list[float] = []

    def add(self, t: float, omega, current, tau_load, theta_worm, theta_gear=None, temperature=None) -> None:
        """One sample of every rig at time t [s]."""
        if self._k == 0:
            self._t0 = t
            self._buffer = {name: np.empty((self.size, self.n)) for name in ("w", "i", "d", "g", "te", "temp")}
        b, k = self._buffer, self._k
        b["w"][k], b["i"][k], b["d"][k], b["g"][k] = omega, current, tau_load, self.ratio * np.asarray(theta_worm)
        te = transmission_error(self.ratio, theta_worm, theta_gear)
        b["te"][k] = np.nan if te is None else te
        b["temp"][k] = np.nan if temperature is None else temperature
        self._k += 1
        if self._k == self.size:
            self._rows.append(block_sums(b["w"], b["i"], b["d"], b["g"], b["te"], b["temp"], axis=0))
            self._t.append(self._t0)
            self._k = 0

    def blocks(self) -> Blocks:
        """Every finished block: arrays (m, n); ``t`` and ``run`` (one run) are (m,)."""
        sums = {name: np.array([row[name] for row in self._rows]).reshape(-1, self.n) for name in SUMS}
        m = len(self._t)
        return finish(sums, self.size, self.period, np.array(self._t), np.zeros(m, dtype=int))


__all__ = ["BLOCK_TIME", "BlockAccumulator", "Blocks", "block_sums", "blocks_from_data", "finish",
           "transmission_error"]
