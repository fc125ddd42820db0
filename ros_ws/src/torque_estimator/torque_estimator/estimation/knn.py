"""k-nearest-neighbour τ_d estimator over a calibration database (paper §3.3, Eqs 33–34).

Units and signs as in :mod:`torque_estimator.estimation.database`: ω_w
[rad/s], i [A], τ_d [N·m] positive opposing positive worm rotation.

Method, per sample (ω, i):

1. Direction. σ = sign(ω), or sign(i) when ω = 0 (physics.md §2; ω = i = 0
   counts as positive). Stored points are split the same way and a query
   only sees points of its own direction, so a slow query never averages
   +τ and −τ across zero speed. A direction without stored points gives
   NaN, flagged OUT_OF_CALIBRATION.
2. Scaling. Features are x = (ω / s_ω, i / s_i). Default
   (``feature_scale=None``, :func:`default_feature_scale`): s_ω and s_i are
   the standard deviations of ``omega_worm`` and ``current_drive`` over the
   whole database (1 where a std is 0). A grid cell then has a similar
   extent along both axes, so neither unit dominates the distance.
3. Eq. 34: Euclidean distance d_j = |x − x_j| in scaled space; the k nearest
   stored points by :class:`scipy.spatial.cKDTree` (k and 2k are capped at
   the number of points of that direction).
4. Eq. 33: weights w_j = 1 / max(d_j, 1e-12) (``"inverse_distance"``) or
   w_j = 1 (``"uniform"``), normalised; τ̂ = Σ w_j τ_j.
5. Uncertainty (the std of the mixture of the neighbours' sample
   distributions): u² = Σ w_j (τ_j − τ̂)² + Σ w_j σ_j², σ_j = ``tau_std``
   (NaN counts as 0).
6. AMBIGUOUS (physics.md §8, self-locking V map). Sort the τ_j of the 2k
   nearest points (wider than the k averaged, so that a second branch is
   seen even when the k nearest all lie on one). If the largest gap between
   consecutive values exceeds ``ambiguity_ratio`` × Δτ_grid (Δτ_grid = the
   median step of the sorted distinct ``torque_setpoints``), the points form
   two branches split at the gap's midpoint. Only those of the k nearest on
   the nearest point's branch are averaged (4, 5), and
   u = max(u_branch, |τ̂_other − τ̂|), τ̂_other the weighted mean of the other
   branch's points among the 2k, so τ̂ ± u reaches the other branch
   (u ≥ gap / 2 always). The default ratio 2.5 lets one missing torque level
   (a gap of 2 Δτ_grid) pass. Limitation: a map so sheared that one speed
   step moves the current by more than about three torque steps splits the
   same way.
7. OUT_OF_CALIBRATION: the nearest stored point of the query's direction is
   farther than ``outside_margin`` × h, h the typical grid spacing in scaled
   units = the median distance from each stored point to its nearest other
   (distinct) point of the same direction. The estimate is still returned.
8. NaN/inf in ω or i: τ̂ = u = NaN, INVALID_INPUT; never raises. Finite inputs so large
   that a squared distance would overflow (|scaled feature| > 1e100) are clipped to
   that size first: still OUT_OF_CALIBRATION, never an error.

TRANSIENT is never set here: the map is quasi-static and this estimator
does not see acceleration; the caller sets it.
"""

from __future__ import annotations

import math
from typing import Callable, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.base import EstimateFlags, TorqueEstimates

_TINY_DISTANCE: Final = 1e-12
#: |scaled feature| beyond this is clipped to it before the tree query: its square must not overflow
#: (the query then stays OUT_OF_CALIBRATION, and the estimate is the map's edge, as for any far query)
_FAR: Final = 1e100

#: weighting name → (distances (m, k) → unnormalised weights (m, k)).
WEIGHTINGS: Final[dict[str, Callable[[NDArray[np.float64]], NDArray[np.float64]]]] = {
    "inverse_distance": lambda d: 1.0 / np.maximum(d, _TINY_DISTANCE),
    "uniform": np.ones_like,
}


def is_negative(omega_worm: NDArray[np.float64], current_drive: NDArray[np.float64]) -> NDArray[np.bool_]:
    """σ < 0: ω_w < 0, or ω_w = 0 and i < 0 (step 1 of the module docstring)."""
    return np.where(omega_worm != 0, omega_worm, current_drive) < 0


def default_feature_scale(database: CalibrationDatabase) -> tuple[float, float]:
    """(s_ω [rad/s], s_i [A]): std of each feature over the database, 1 where it is 0."""
    scale = (float(np.std(database.omega_worm)), float(np.std(database.current_drive)))
    return scale[0] or 1.0, scale[1] or 1.0


class _Side:
    """The stored points of one direction, in scaled features, with their tree."""

    def __init__(self, features: NDArray[np.float64], tau: NDArray[np.float64],
                 tau_var: NDArray[np.float64]) -> None:
        # imported at first use: scipy.spatial takes ~0.2 s to import, paid at start by every executable
        from scipy.spatial import cKDTree

        self.tree = cKDTree(features)
        self.tau = tau
        self.tau_var = tau_var

    def nearest_other_distance(self) -> NDArray[np.float64]:
        """Distance from each stored point to its nearest other stored point."""
        if len(self.tau) < 2:
            return np.empty(0)
        return self.tree.query(self.tree.data, k=[2])[0][:, 0]


class KnnEstimator:
    """k-NN τ_d estimator (paper Eqs 33–34); formulas in the module docstring.

    Args:
        database: the calibration map.
        k: number of neighbours (≥ 1).
        weighting: a key of :data:`WEIGHTINGS`, ``"inverse_distance"`` or ``"uniform"``.
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
        self._scale = np.array(self.feature_scale)

        negative = is_negative(database.omega_worm, database.current_drive)
        features = np.column_stack((database.omega_worm, database.current_drive)) / self._scale
        tau_var = np.nan_to_num(np.square(database.tau_std), nan=0.0)
        self._sides: dict[bool, _Side] = {
            side: _Side(features[negative == side], database.tau_load[negative == side],
                        tau_var[negative == side])
            for side in (False, True) if np.any(negative == side)
        }
        spacing = np.concatenate([s.nearest_other_distance() for s in self._sides.values()])
        spacing = spacing[spacing > 0]  # repeated points are not a grid step
        #: h, typical grid spacing in scaled units.
        self.grid_spacing = float(np.median(spacing)) if spacing.size else 1.0

    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """Estimate τ_d [N·m] from ω_w [rad/s] and i [A].

        Inputs broadcast; outputs have the broadcast shape (two scalars → 0-d
        arrays, served by a plain-Python path). Flags are
        :class:`EstimateFlags` bits in an int64 array. Never raises for
        NaN/inf samples.
        """
        if np.ndim(omega_worm) == 0 and np.ndim(current_drive) == 0:
            torque, spread, flag = self._estimate_one(float(omega_worm), float(current_drive))  # type: ignore[arg-type]
            return TorqueEstimates(np.array(torque), np.array(spread), np.array(flag, dtype=np.int64))
        omega, current = np.broadcast_arrays(np.asarray(omega_worm, dtype=np.float64),
                                             np.asarray(current_drive, dtype=np.float64))
        x = np.column_stack((omega.ravel(), current.ravel())) / self._scale
        valid = np.isfinite(x).all(axis=1)
        x = np.clip(x, -_FAR, _FAR)  # squared distances of larger ones overflow the tree query
        negative = is_negative(x[:, 0], x[:, 1])
        torque = np.full(len(x), np.nan)
        uncertainty = np.full(len(x), np.nan)
        flags = np.where(valid, 0, int(EstimateFlags.INVALID_INPUT))
        for side in (False, True):
            rows = valid & (negative == side)
            if not rows.any():
                continue
            if side not in self._sides:
                flags[rows] |= EstimateFlags.OUT_OF_CALIBRATION
                continue
            torque[rows], uncertainty[rows], flags[rows] = self._query(self._sides[side], x[rows])
        shape = omega.shape
        return TorqueEstimates(torque.reshape(shape), uncertainty.reshape(shape), flags.reshape(shape))

    def _estimate_one(self, omega: float, current: float) -> tuple[float, float, int]:
        """One sample, steps 1–8, in plain Python: a numpy call per step would
        cost more than the tree query. Kept equal to :meth:`_query` by test."""
        if not (math.isfinite(omega) and math.isfinite(current)):
            return math.nan, math.nan, EstimateFlags.INVALID_INPUT
        side = self._sides.get((omega if omega != 0 else current) < 0)
        if side is None:
            return math.nan, math.nan, EstimateFlags.OUT_OF_CALIBRATION
        k, wide = self._neighbour_counts(side)
        query = (min(max(omega / self.feature_scale[0], -_FAR), _FAR),
                 min(max(current / self.feature_scale[1], -_FAR), _FAR))
        dist, index = side.tree.query(query, k=list(range(1, wide + 1)))
        tau, tau_var = side.tau[index].tolist(), side.tau_var[index].tolist()
        weight = self._weights(dist).tolist()
        flags = EstimateFlags.OUT_OF_CALIBRATION if dist[0] > self.outside_margin * self.grid_spacing \
            else EstimateFlags.NONE
        ordered = sorted(tau)
        gap, low, high = max(((b - a, a, b) for a, b in zip(ordered, ordered[1:])), default=(0.0, 0.0, 0.0))
        if gap <= self.ambiguity_ratio * self.torque_step:
            return (*_weighted_mean_std_one(tau[:k], tau_var[:k], weight[:k]), flags)
        cut = 0.5 * (low + high)
        same_branch = [(t > cut) == (tau[0] > cut) for t in tau]
        estimate, spread = _weighted_mean_std_one(tau[:k], tau_var[:k],
                                                  [w * s for w, s in zip(weight[:k], same_branch)])
        other, _ = _weighted_mean_std_one(tau, tau_var, [w * (not s) for w, s in zip(weight, same_branch)])
        return estimate, max(spread, abs(other - estimate)), flags | EstimateFlags.AMBIGUOUS

    def _neighbour_counts(self, side: _Side) -> tuple[int, int]:
        """(k averaged, 2k examined for branches), both capped at the side's point count."""
        return min(self.k, len(side.tau)), min(2 * self.k, len(side.tau))

    def _query(self, side: _Side, x: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Steps 3–7 of the module docstring for scaled queries ``x`` (m, 2)."""
        k, wide = self._neighbour_counts(side)
        dist, index = side.tree.query(x, k=list(range(1, wide + 1)))
        tau, tau_var = side.tau[index], side.tau_var[index]
        weight = self._weights(dist)
        flags = (dist[:, 0] > self.outside_margin * self.grid_spacing) * int(EstimateFlags.OUT_OF_CALIBRATION)
        ordered = np.sort(tau, axis=1)
        gaps = ordered[:, 1:] - ordered[:, :-1]
        ambiguous = (gaps.max(axis=1, initial=0.0) > self.ambiguity_ratio * self.torque_step)
        if not ambiguous.any():
            estimate, spread = _weighted_mean_std(tau[:, :k], tau_var[:, :k], weight[:, :k])
            return estimate, spread, flags

        split = gaps.argmax(axis=1)[:, None]
        cut = 0.5 * (np.take_along_axis(ordered, split, axis=1) + np.take_along_axis(ordered, split + 1, axis=1))
        upper = tau > cut
        same_branch = (upper == upper[:, :1]) | ~ambiguous[:, None]
        estimate, spread = _weighted_mean_std(tau[:, :k], tau_var[:, :k], (weight * same_branch)[:, :k])
        other, _ = _weighted_mean_std(tau[ambiguous], tau_var[ambiguous], (weight * ~same_branch)[ambiguous])
        spread[ambiguous] = np.maximum(spread[ambiguous], np.abs(other - estimate[ambiguous]))
        flags[ambiguous] |= EstimateFlags.AMBIGUOUS
        return estimate, spread, flags


def _weighted_mean_std(tau: NDArray[np.float64], tau_var: NDArray[np.float64],
                       weight: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Row-wise weighted mean and mixture std: u² = Σ w (τ − τ̂)² + Σ w σ², Σ w = 1."""
    weight = weight / weight.sum(axis=1, keepdims=True)
    mean = (weight * tau).sum(axis=1)
    variance = (weight * (np.square(tau - mean[:, None]) + tau_var)).sum(axis=1)
    return mean, np.sqrt(variance)


def _weighted_mean_std_one(tau: list[float], tau_var: list[float], weight: list[float]) -> tuple[float, float]:
    """:func:`_weighted_mean_std` for one row of Python floats."""
    total = sum(weight)
    mean = sum(w * t for w, t in zip(weight, tau)) / total
    variance = sum(w * ((t - mean) ** 2 + v) for w, t, v in zip(weight, tau, tau_var)) / total
    return mean, math.sqrt(variance)


__all__ = ["KnnEstimator", "WEIGHTINGS", "default_feature_scale", "is_negative"]
