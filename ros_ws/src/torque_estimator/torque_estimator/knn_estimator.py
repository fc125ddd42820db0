"""k-nearest-neighbour τ_d estimator over a calibration database (paper §3.3, Eqs 33–34).

Units and signs as in :mod:`torque_estimator.calibration_database`: ω_w
[rad/s], i [A], τ_d [N·m] positive opposing positive worm rotation.

Method, per sample (ω, i):

1. Direction. σ = sign(ω), or sign(i) when ω = 0 (physics.md §2; ω = i = 0
   counts as positive). Stored points are split the same way and a query
   only sees points of its own direction, so a slow query never averages
   +τ and −τ across zero speed. A direction without stored points gives
   NaN, flagged OUT_OF_CALIBRATION.
2. Scaling. Features are x = (ω / s_ω, i / s_i). Default
   (``feature_scale=None``, :func:`default_feature_scale`): s_ω is the median
   |Δω| between points adjacent in the speed grid (same direction, same
   torque setpoint), s_i the median |Δi| between points adjacent in the
   torque grid (same direction, same speed setpoint). A grid cell is then
   about a unit square, so the k = 4 nearest points are the cell's corners.
   (The std over the database would be dominated by the ±ω split between
   directions.) If a grid step cannot be formed the feature's std over the
   database is used, and 1 if that is 0.
3. Eq. 34: Euclidean distance d_j = |x − x_j| in scaled space; the k nearest
   stored points by :class:`scipy.spatial.cKDTree` (k is capped at the
   number of points of that direction).
4. Eq. 33: weights w_j = 1 / max(d_j, 1e-12) (``"inverse_distance"``) or
   w_j = 1 (``"uniform"``), normalised; τ̂ = Σ w_j τ_j.
5. Uncertainty (the std of the mixture of the neighbours' sample
   distributions): u² = Σ w_j (τ_j − τ̂)² + Σ w_j σ_j², σ_j = ``tau_std``
   (NaN counts as 0).
6. AMBIGUOUS (physics.md §8, self-locking V map). Sort the k neighbours' τ_j;
   if the largest gap between consecutive values exceeds
   ``ambiguity_ratio`` × Δτ_grid (median step of the sorted distinct
   ``torque_setpoints``), the neighbours form two branches split at the
   gap's midpoint. Only the nearest neighbour's branch is averaged (4, 5),
   and u = max(u_branch, |τ̂_other − τ̂|), τ̂_other the weighted mean of the
   other branch, so τ̂ ± u reaches the other branch (u ≥ gap / 2 always).
   The default ratio 2.5 lets one missing torque level (gap 2 Δτ) pass.
   Limitation: a grid so sheared that one speed step moves the current by
   more than about three torque steps also splits this way.
7. OUT_OF_CALIBRATION: the nearest stored point of the query's direction is
   farther than ``outside_margin`` × h, h the typical grid spacing in scaled
   units = the median distance from each stored point to its nearest other
   point (≈ 1 with the default scaling). The estimate is still returned.
8. NaN/inf in ω or i: τ̂ = u = NaN, INVALID_INPUT; never raises.

TRANSIENT is never set here: the map is quasi-static and this estimator
does not see acceleration; the caller sets it.
"""

from __future__ import annotations

from typing import Callable, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .calibration_database import CalibrationDatabase
from .estimator import EstimateFlags, TorqueEstimates

_TINY_DISTANCE: Final = 1e-12

#: weighting name → (distances (m, k) → unnormalised weights (m, k)).
WEIGHTINGS: Final[dict[str, Callable[[NDArray[np.float64]], NDArray[np.float64]]]] = {
    "inverse_distance": lambda d: 1.0 / np.maximum(d, _TINY_DISTANCE),
    "uniform": np.ones_like,
}


def direction(omega_worm: ArrayLike, current_drive: ArrayLike) -> NDArray[np.int8]:
    """σ = sign(ω_w), or sign(i) where ω_w = 0; +1 where both are 0 (or NaN)."""
    omega = np.asarray(omega_worm, dtype=np.float64)
    current = np.asarray(current_drive, dtype=np.float64)
    negative = np.where(omega != 0, omega < 0, current < 0)
    return np.where(negative, -1, 1).astype(np.int8)


def _rank(values: NDArray[np.float64]) -> NDArray[np.int64]:
    """Position of each value in ascending order (grid lists need not be sorted)."""
    return np.argsort(np.argsort(values, kind="stable"), kind="stable")


def _grid_step(values: NDArray[np.float64], along: NDArray[np.int64],
               across: NDArray[np.int64], side: NDArray[np.int8]) -> float:
    """Median |Δvalue| between points one step apart on the ``along`` grid axis,
    with equal ``across`` index and direction; NaN if there is no such pair."""
    order = np.lexsort((along, across, side))
    adjacent = ((np.diff(side[order]) == 0) & (np.diff(across[order]) == 0)
                & (np.diff(along[order]) == 1))
    steps = np.abs(np.diff(values[order]))[adjacent]
    return float(np.median(steps)) if steps.size else float("nan")


def default_feature_scale(database: CalibrationDatabase) -> tuple[float, float]:
    """(s_ω [rad/s], s_i [A]): the typical grid step of each feature (module doc, 2)."""
    side = direction(database.omega_worm, database.current_drive)
    speed = _rank(database.speed_setpoints)[database.setpoint_index[:, 0]]
    torque = _rank(database.torque_setpoints)[database.setpoint_index[:, 1]]
    scale = []
    for values, along, across in ((database.omega_worm, speed, torque),
                                  (database.current_drive, torque, speed)):
        step = _grid_step(values, along, across, side)
        if not (np.isfinite(step) and step > 0):
            step = float(np.std(values)) if len(values) else 0.0
        scale.append(step if step > 0 else 1.0)
    return scale[0], scale[1]


class _Branch:
    """The stored points of one direction, in scaled features, with their tree."""

    def __init__(self, features: NDArray[np.float64], tau: NDArray[np.float64],
                 tau_var: NDArray[np.float64]) -> None:
        self.tree = cKDTree(features)
        self.tau = tau
        self.tau_var = tau_var

    def nearest_other_distance(self) -> NDArray[np.float64]:
        """Distance from each stored point to its nearest other stored point."""
        if len(self.tau) < 2:
            return np.empty(0)
        return self.tree.query(self.tree.data, k=2)[0][:, 1]


class KnnEstimator:
    """k-NN τ_d estimator (paper Eqs 33–34); see the module docstring for formulas.

    Args:
        database: the calibration map.
        k: number of neighbours (≥ 1).
        weighting: ``"inverse_distance"`` or ``"uniform"``.
        feature_scale: (s_ω [rad/s], s_i [A]) dividing the features before the
            distance; None → :func:`default_feature_scale`.
        ambiguity_ratio: a gap between neighbour torques larger than this
            many torque-grid steps means two branches (AMBIGUOUS).
        outside_margin: nearest stored point farther than this many typical
            grid spacings means OUT_OF_CALIBRATION.

    Raises:
        ValueError: a bad option, an empty database, or fewer than two
            distinct ``torque_setpoints`` (no torque step for the ambiguity test).
    """

    name = "knn"

    def __init__(self, database: CalibrationDatabase, k: int = 4,
                 weighting: str = "inverse_distance",
                 feature_scale: tuple[float, float] | None = None,
                 ambiguity_ratio: float = 2.5, outside_margin: float = 1.5) -> None:
        if not (isinstance(k, (int, np.integer)) and k >= 1):
            raise ValueError(f"k must be an integer ≥ 1, got {k!r}")
        if weighting not in WEIGHTINGS:
            raise ValueError(f"weighting must be one of {sorted(WEIGHTINGS)}, got {weighting!r}")
        for option, value in (("ambiguity_ratio", ambiguity_ratio), ("outside_margin", outside_margin)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{option} must be finite and > 0, got {value!r}")
        if len(database) == 0:
            raise ValueError("calibration database has no points")
        scale = default_feature_scale(database) if feature_scale is None else feature_scale
        if len(scale) != 2 or not all(np.isfinite(s) and s > 0 for s in scale):
            raise ValueError(f"feature_scale must be two finite values > 0, got {feature_scale!r}")
        torque_steps = np.diff(np.unique(database.torque_setpoints))
        if torque_steps.size == 0:
            raise ValueError("calibration database needs at least two distinct torque_setpoints")

        self.k = int(k)
        self.weighting = weighting
        self.feature_scale: tuple[float, float] = (float(scale[0]), float(scale[1]))
        self.ambiguity_ratio = float(ambiguity_ratio)
        self.outside_margin = float(outside_margin)
        #: Δτ_grid [N·m], median step of the distinct torque setpoints.
        self.torque_step = float(np.median(torque_steps))
        self._weights = WEIGHTINGS[weighting]

        side = direction(database.omega_worm, database.current_drive)
        features = self._scaled(database.omega_worm, database.current_drive)
        tau_var = np.nan_to_num(np.square(database.tau_std), nan=0.0)
        self._branches: dict[int, _Branch] = {
            sign: _Branch(features[side == sign], database.tau_load[side == sign], tau_var[side == sign])
            for sign in (1, -1) if np.any(side == sign)
        }
        spacing = np.concatenate([b.nearest_other_distance() for b in self._branches.values()])
        #: h, typical grid spacing in scaled units.
        self.grid_spacing = float(np.median(spacing)) if spacing.size else 1.0

    def _scaled(self, omega: ArrayLike, current: ArrayLike) -> NDArray[np.float64]:
        return np.column_stack((np.asarray(omega) / self.feature_scale[0],
                                np.asarray(current) / self.feature_scale[1]))

    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """Estimate τ_d [N·m] from ω_w [rad/s] and i [A].

        Inputs broadcast; outputs have the broadcast shape (scalars → 0-d
        arrays). Flags are :class:`EstimateFlags` bits in an int64 array.
        Never raises for NaN/inf samples.
        """
        omega, current = np.broadcast_arrays(np.asarray(omega_worm, dtype=np.float64),
                                             np.asarray(current_drive, dtype=np.float64))
        shape = omega.shape
        omega, current = omega.ravel(), current.ravel()
        torque = np.full(omega.shape, np.nan)
        uncertainty = np.full(omega.shape, np.nan)
        flags = np.zeros(omega.shape, dtype=np.int64)

        valid = np.isfinite(omega) & np.isfinite(current)
        flags[~valid] = EstimateFlags.INVALID_INPUT
        side = direction(omega, current)
        for sign in (1, -1):
            rows = np.flatnonzero(valid & (side == sign))
            if rows.size == 0:
                continue
            branch = self._branches.get(sign)
            if branch is None:
                flags[rows] |= EstimateFlags.OUT_OF_CALIBRATION
                continue
            torque[rows], uncertainty[rows], flags[rows] = self._query(
                branch, self._scaled(omega[rows], current[rows]))
        return TorqueEstimates(torque.reshape(shape), uncertainty.reshape(shape), flags.reshape(shape))

    def _query(self, branch: _Branch, x: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Steps 3–7 of the module docstring for the scaled queries ``x`` (m, 2)."""
        k = min(self.k, len(branch.tau))
        dist, index = branch.tree.query(x, k=k)
        dist, index = dist.reshape(len(x), k), index.reshape(len(x), k)
        tau, tau_var = branch.tau[index], branch.tau_var[index]
        weight = self._weights(dist)

        ordered = np.sort(tau, axis=1)
        gaps = np.diff(ordered, axis=1)
        rows = np.arange(len(x))
        split = np.argmax(gaps, axis=1) if k > 1 else np.zeros(len(x), dtype=np.int64)
        ambiguous = (gaps[rows, split] > self.ambiguity_ratio * self.torque_step) if k > 1 \
            else np.zeros(len(x), dtype=bool)
        cut = 0.5 * (ordered[rows, split] + ordered[rows, np.minimum(split + 1, k - 1)])
        upper = tau > cut[:, None]
        same_branch = ~ambiguous[:, None] | (upper == upper[:, :1])

        estimate, spread = _weighted_mean_std(tau, tau_var, weight * same_branch)
        flags = np.where(ambiguous, int(EstimateFlags.AMBIGUOUS), 0)
        if np.any(ambiguous):
            other, _ = _weighted_mean_std(tau[ambiguous], tau_var[ambiguous],
                                          (weight * ~same_branch)[ambiguous])
            spread[ambiguous] = np.maximum(spread[ambiguous], np.abs(other - estimate[ambiguous]))
        flags |= np.where(dist[:, 0] > self.outside_margin * self.grid_spacing,
                          int(EstimateFlags.OUT_OF_CALIBRATION), 0)
        return estimate, spread, flags


def _weighted_mean_std(tau: NDArray[np.float64], tau_var: NDArray[np.float64],
                       weight: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Row-wise weighted mean and mixture std: u² = Σ w (τ − τ̂)² + Σ w σ², Σ w = 1."""
    weight = weight / weight.sum(axis=1, keepdims=True)
    mean = np.einsum("ij,ij->i", weight, tau)
    variance = np.einsum("ij,ij->i", weight, np.square(tau - mean[:, None]) + tau_var)
    return mean, np.sqrt(variance)


__all__ = ["KnnEstimator", "WEIGHTINGS", "default_feature_scale", "direction"]
