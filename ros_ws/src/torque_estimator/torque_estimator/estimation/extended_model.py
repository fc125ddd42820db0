"""Model-based τ_d estimator: invert the extended model's quasi-static current (issue 7).

Units and signs as :mod:`torque_estimator.estimation.database`: ω_w [rad/s], i [A]
(the inertia-compensated drive current, as LiveEstimator hands it over), τ_d [N·m]
positive opposing positive worm rotation.

The model is a worm_model ``ExtendedModel`` read from a parameter file written by
``residuals`` (rig sections + ``effects:``); without a file it is the rig with no
effects, i.e. the paper's model (Eqs 28–30).

Construction (once): the model's drive current i(ω, τ_d) at α = 0 is tabulated on a
uniform grid per rotation direction: |ω| in [0, ω_max] (``speed_points``; ω_max the
database's largest |ω|, −|ω| on the negative side, −1e−9 at 0), τ_d over the
database's calibrated torque range [min τ_load, max τ_load] (``torque_points``).
Periodic effects (runout, tooth-pass, cogging ripple) are averaged out: when the model
has any, every entry is the mean current over ``angles`` = 7 worm angles spread evenly
over one gear turn (a harmonic of order q per gear turn cancels unless 7 divides q;
the NMRV030's 30 teeth and one start give q = 1, 30, 30·k); without periodic effects
θ = 0 is used. The thermal effect is evaluated at its reference oil temperature
(every table entry is its own run, so the first-order warming is 0).

Per sample (ω, i):

1. Direction σ = sign(ω), or sign(i) at ω = 0 (as the k-NN).
2. Column: the table's current along τ_d at |ω|, linear between the two bracketing
   speed rows (bilinear overall). |ω| > ω_max: the edge row, OUT_OF_CALIBRATION.
3. Crossings of i along the column, each solved linearly inside its τ_d cell.
   One: that τ_d. Several (self-locking V, physics.md §8: two loads draw the same
   current): AMBIGUOUS; the estimate is the crossing with the largest σ·τ_d (the load
   opposing the motion most, the driving flank) and the uncertainty reaches the
   farthest other crossing.
   None: OUT_OF_CALIBRATION; i beyond an end of the column is extrapolated along
   the end cell's slope, i below the V's minimum (no load explains it) gives the
   τ_d of the minimum.
4. Uncertainty (1 sigma): u² = (σ_i / |∂i/∂τ_d|)² + (Δτ_table / √12)², σ_i =
   ``current_noise`` (default the rig's current_noise_std: a conservative figure for a
   smoothed live current) through the local slope, plus the table's τ_d step as a
   uniform quantisation; AMBIGUOUS: u = max(u, |τ_other − τ̂|).
5. NaN/inf input: τ̂ = u = NaN, INVALID_INPUT; never raises. TRANSIENT is the caller's.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from worm_model.physics.parameters import load_rig
from worm_model.residuals.extended import ExtendedModel

from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.base import EstimateFlags, TorqueEstimates

#: Worm angles averaged per table entry when the model has periodic effects.
ANGLES = 7
#: Samples per batch of the vectorised inversion (bounds memory: batch × torque_points floats).
_BATCH = 4096
#: |ω| [rad/s] used for the ω = 0 row of the negative-direction table (the model reads ω < 0).
_NEGATIVE_ZERO = 1e-9


def load_model(model_file: str | Path | None, rig_file: str | Path | None = None) -> ExtendedModel:
    """The ExtendedModel of ``model_file``; empty/None → ``rig_file`` (or the bundled rig), no effects."""
    if model_file:
        return ExtendedModel.load(model_file)
    return ExtendedModel(load_rig(rig_file or None))


class ExtendedModelEstimator:
    """τ_d by inverting the extended model's tabulated current; method in the module docstring.

    Args:
        database: the calibration map; gives the speed and torque range of the table.
        model_file: parameter file with an optional ``effects:`` section (ExtendedModel.load);
            empty/None → ``rig_file`` with no effects (the paper's model).
        rig_file: rig YAML used when ``model_file`` is empty; empty/None → bundled rig.
        model: an ExtendedModel to use instead of reading a file (tests, benches).
        speed_points, torque_points: table size per direction (≥ 2 each).
        angles: worm angles averaged when the model has periodic effects (≥ 1).
        current_noise: σ_i [A] for the uncertainty; None → rig.sensors.current_noise_std.

    Raises:
        ValueError: bad option, empty database or zero torque range.
        worm_model.physics.parameters.ParameterError: a bad model or rig file.
    """

    name = "extended_model"

    def __init__(self, database: CalibrationDatabase, model_file: str | Path | None = None,
                 rig_file: str | Path | None = None, *, model: ExtendedModel | None = None,
                 speed_points: int = 121, torque_points: int = 161, angles: int = ANGLES,
                 current_noise: float | None = None) -> None:
        if speed_points < 2 or torque_points < 2 or angles < 1:
            raise ValueError(f"need speed_points, torque_points >= 2 and angles >= 1, got "
                             f"{speed_points}, {torque_points}, {angles}")
        if len(database) == 0:
            raise ValueError("calibration database has no points")
        tau_lo, tau_hi = float(np.min(database.tau_load)), float(np.max(database.tau_load))
        if not tau_hi > tau_lo:
            raise ValueError("calibration database spans no torque range")
        self.model = model if model is not None else load_model(model_file, rig_file)
        rig = self.model.rig
        self.current_noise = float(rig.sensors.current_noise_std if current_noise is None else current_noise)
        if not (math.isfinite(self.current_noise) and self.current_noise >= 0):
            raise ValueError(f"current_noise must be finite and >= 0, got {current_noise!r}")
        #: ω_max [rad/s] of the table
        self.omega_max = float(np.max(np.abs(database.omega_worm))) or 1.0
        self.speeds = np.linspace(0.0, self.omega_max, speed_points)
        self.torques = np.linspace(tau_lo, tau_hi, torque_points)
        self.speed_step = float(self.speeds[1])
        self.torque_step = float(self.torques[1] - self.torques[0])
        periodic = any(effect.family == "periodic" for effect, _v, _g in self.model.effects)
        self.angles = int(angles) if periodic else 1
        #: direction (False: +, True: −) → current table [A], shape (speed_points, torque_points)
        self.tables = {negative: self._tabulate(negative) for negative in (False, True)}

    def _tabulate(self, negative: bool) -> NDArray[np.float64]:
        """Mean model current over the angles, α = 0, on the (|ω|, τ_d) grid of one direction."""
        rig = self.model.rig
        speed = -np.maximum(self.speeds, _NEGATIVE_ZERO) if negative else self.speeds
        gear_turn = 2.0 * math.pi / rig.gearbox.ratio  # worm angle [rad] of one gear turn
        theta = np.arange(self.angles) * gear_turn / self.angles
        w, tau, th = (a.ravel() for a in np.meshgrid(speed, self.torques, theta, indexing="ij"))
        signals = self.model.signals(w, 0.0, tau, th, run=np.arange(len(w)))
        current = np.asarray(self.model.current(signals), dtype=float)
        return current.reshape(len(speed), len(self.torques), self.angles).mean(axis=2)

    # ------------------------------------------------------------------ estimation
    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """Estimate τ_d [N·m] from ω_w [rad/s] and the inertia-free drive current i [A].

        Inputs broadcast; outputs have the broadcast shape (scalars → 0-d arrays).
        Never raises for NaN/inf samples.
        """
        omega, current = np.broadcast_arrays(np.asarray(omega_worm, dtype=np.float64),
                                             np.asarray(current_drive, dtype=np.float64))
        w, i = omega.ravel(), current.ravel()
        torque = np.full(len(w), np.nan)
        spread = np.full(len(w), np.nan)
        flags = np.zeros(len(w), dtype=np.int64)
        for start in range(0, len(w), _BATCH):
            part = slice(start, start + _BATCH)
            torque[part], spread[part], flags[part] = self._invert(w[part], i[part])
        shape = omega.shape
        return TorqueEstimates(torque.reshape(shape), spread.reshape(shape), flags.reshape(shape))

    def _invert(self, w: NDArray[np.float64], i: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Steps 1–5 of the module docstring for one batch."""
        m = len(w)
        valid = np.isfinite(w) & np.isfinite(i)
        flags = np.where(valid, 0, int(EstimateFlags.INVALID_INPUT)).astype(np.int64)
        w, i = np.where(valid, w, 0.0), np.where(valid, i, 0.0)
        negative = np.where(w != 0, w, i) < 0
        speed = np.abs(w)
        flags |= np.where(speed > self.omega_max, int(EstimateFlags.OUT_OF_CALIBRATION), 0)
        position = np.minimum(speed, self.omega_max) / self.speed_step
        row = np.minimum(position.astype(np.int64), len(self.speeds) - 2)
        frac = (position - row)[:, None]
        column = np.empty((m, len(self.torques)))
        for side in (False, True):
            rows = negative == side
            if rows.any():
                table = self.tables[side]
                column[rows] = (1.0 - frac[rows]) * table[row[rows]] + frac[rows] * table[row[rows] + 1]
        excess = column - i[:, None]  # (m, n_tau): model current minus measured
        left, right = excess[:, :-1], excess[:, 1:]
        crossing = (left == 0) | (np.sign(left) != np.sign(right)) & (right != 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            cell = np.clip(left / (left - right), 0.0, 1.0)
        cell = np.where(np.isfinite(cell), cell, 0.0)
        tau_at = self.torques[:-1] + cell * self.torque_step  # (m, n_tau - 1) candidate solutions
        sigma = np.where(negative, -1.0, 1.0)[:, None]
        count = crossing.sum(axis=1)

        # step 3: the crossing with the largest σ·τ (driving flank); the farthest other for AMBIGUOUS
        ranked = np.where(crossing, sigma * tau_at, -np.inf)
        best = ranked.argmax(axis=1)
        torque = np.take_along_axis(tau_at, best[:, None], axis=1)[:, 0]
        farthest = np.where(crossing, np.abs(tau_at - torque[:, None]), 0.0).max(axis=1)

        # no crossing: extrapolate beyond an end, or the V's minimum
        none = count == 0
        if none.any():
            flags[none] |= EstimateFlags.OUT_OF_CALIBRATION
            col, cur = column[none], i[none]
            nearest = np.abs(col - cur[:, None]).argmin(axis=1)
            low_end, high_end = nearest == 0, nearest == len(self.torques) - 1
            slope_lo = (col[:, 1] - col[:, 0]) / self.torque_step
            slope_hi = (col[:, -1] - col[:, -2]) / self.torque_step
            with np.errstate(divide="ignore", invalid="ignore"):
                extrapolated = np.where(low_end, self.torques[0] + (cur - col[:, 0]) / slope_lo,
                                        self.torques[-1] + (cur - col[:, -1]) / slope_hi)
            fallback = self.torques[nearest]
            torque[none] = np.where((low_end | high_end) & np.isfinite(extrapolated), extrapolated, fallback)

        # step 4: slope of the cell the estimate lies in
        cell_index = np.clip(((torque - self.torques[0]) / self.torque_step).astype(np.int64), 0,
                             len(self.torques) - 2)
        slope = np.abs(np.take_along_axis(column, cell_index[:, None] + 1, axis=1)[:, 0]
                       - np.take_along_axis(column, cell_index[:, None], axis=1)[:, 0]) / self.torque_step
        with np.errstate(divide="ignore"):
            noise = np.where(slope > 0, self.current_noise / slope, np.inf if self.current_noise else 0.0)
        spread = np.hypot(noise, self.torque_step / math.sqrt(12.0))
        ambiguous = count > 1
        flags[ambiguous] |= EstimateFlags.AMBIGUOUS
        spread = np.where(ambiguous, np.maximum(spread, farthest), spread)
        torque[~valid] = np.nan
        spread[~valid] = np.nan
        flags[~valid] = int(EstimateFlags.INVALID_INPUT)
        return torque, spread, flags


__all__ = ["ANGLES", "ExtendedModelEstimator", "load_model"]
