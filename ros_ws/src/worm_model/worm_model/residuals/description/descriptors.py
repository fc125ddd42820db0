"""Generic descriptions of a residual: what it goes with, in no effect's terms.

The quantities a residual the vocabulary leaves may go with (:func:`quantities`): the worm
speed, the load, the time within the run, the direction of rotation, the oil temperature
(binned means over quantile bins), and the worm and gear angles (a sinusoid of one order per
turn, each direction of rotation its own phase; whole and half orders, :data:`WORM_ORDERS`,
:data:`GEAR_ORDERS`).  Two users:

* unexplained.describe_unexplained reports the share of the unexplained residual each one takes;
* :func:`describe_residual` turns the best of them into a pseudo-effect (:class:`Descriptor`: linear
  columns on the current) that the analysis fits beside the named effects (analysis step 5): an
  effect that only earns its keep without it took a share of a residual outside the vocabulary.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import count
from typing import ClassVar

import numpy as np

from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects import Coefficient, GridParameter, Shapes
from worm_model.residuals.fitting.fitting import Fit, Problem
from worm_model.residuals.model import ModelState, Signals

#: orders per turn tried for the worm and gear angles: whole orders and the half orders between the first ones
#: (a 3:2 coupling stage turns at 1.5 per worm turn)
WORM_ORDERS: tuple[float, ...] = tuple(float(k) for k in range(1, 61)) + tuple(k + 0.5 for k in range(10))
GEAR_ORDERS: tuple[float, ...] = tuple(float(k) for k in range(1, 31)) + tuple(k + 0.5 for k in range(5))
#: quantile bins of a binned quantity
BINS = 20
#: a second description is added to the first when it takes at least this share of what the first leaves
SECOND_SHARE = 0.25


def time_in_run(signals: Signals) -> FloatArray:
    """Time since the start of each sample's run [s]."""
    runs, first = np.unique(signals.run, return_index=True)
    return signals.t - signals.t[first][np.searchsorted(runs, signals.run)]


def direction(signals: Signals) -> FloatArray:
    """Sign of the worm speed, +1 at 0."""
    return np.where(signals.omega < 0.0, -1.0, 1.0)


def quantities(signals: Signals, mask: np.ndarray) -> list[tuple[str, FloatArray, int, str]]:
    """(name, values on every sample, bins, axis label) of the binned quantities; temperature only when measured
    on every sample of ``mask``."""
    out = [("speed", signals.omega, BINS, "omega_worm [rad/s]"), ("load", signals.tau_load, BINS, "tau_load [N m]"),
           ("time", time_in_run(signals), BINS, "time within the run [s]"),
           ("direction", direction(signals), 2, "sign of omega")]
    if signals.temperature is not None and np.all(np.isfinite(signals.temperature[mask])):
        out.append(("temperature", signals.temperature, BINS, "temperature [degC]"))
    return out


def bin_edges(x: FloatArray, bins: int) -> FloatArray:
    """Quantile bin edges of ``x`` (duplicates merged)."""
    return np.unique(np.quantile(x, np.linspace(0.0, 1.0, bins + 1)))


def bin_index(x: FloatArray, edges: FloatArray) -> np.ndarray:
    """Which bin of ``edges`` each value falls in (values beyond the outer edges in the outer bins)."""
    return np.clip(np.digitize(x, edges) - 1, 0, max(len(edges) - 2, 0))


def explained_by_bins(x: FloatArray, r: FloatArray, bins: int, floor: float) -> tuple[float, FloatArray, FloatArray]:
    """Variance of r explained by its binned means over x (quantile bins), less the noise's share [A^2];
    with the bin centres and means."""
    edges = bin_edges(x, bins)
    if len(edges) < 2:
        return 0.0, np.zeros(0), np.zeros(0)
    which = bin_index(x, edges)
    number = np.bincount(which, minlength=len(edges) - 1).astype(float)
    mean = np.bincount(which, weights=r, minlength=len(edges) - 1) / np.maximum(number, 1.0)
    explained = float(np.sum(number * mean**2) / len(r)) - (len(edges) - 1) * floor**2 / len(r)
    return max(explained, 0.0), 0.5 * (edges[1:] + edges[:-1]), mean


def order_columns(angle: FloatArray, sigma: FloatArray, order: float) -> FloatArray:
    """(n, 4): sin and cos of order x angle, and the same times the direction (each direction its own phase)."""
    s, c = np.sin(order * angle), np.cos(order * angle)
    return np.column_stack([s, c, sigma * s, sigma * c])


def explained_by_orders(angle: FloatArray, sigma: FloatArray, r: FloatArray, orders: Sequence[float],
                        floor: float) -> tuple[float, float, float]:
    """(best order, explained variance [A^2], amplitude [A]): sin/cos of order*angle, per direction."""
    best = (math.nan, 0.0, 0.0)
    for k in orders:
        X = order_columns(angle, sigma, k)
        coef, *_ = np.linalg.lstsq(X, r, rcond=None)
        fitted = X @ coef
        explained = float(np.mean(fitted**2)) - 4 * floor**2 / len(r)
        if explained > best[1]:
            best = (float(k), explained, float(math.sqrt(2.0 * np.mean(fitted**2))))
    return best


def angles(signals: Signals) -> list[tuple[str, FloatArray, Sequence[float]]]:
    """(name, angle [rad], orders tried) of the worm and the gear."""
    return [("worm angle orders", signals.theta_worm, WORM_ORDERS), ("gear angle orders", signals.theta_gear,
                                                                     GEAR_ORDERS)]


# --------------------------------------------------------------------------- the pseudo-effect
_ids = count()


@dataclass(eq=False)
class Descriptor:
    """A pseudo-effect: fixed columns [A per unit] added to the measured current, one linear parameter each.

    Not in the vocabulary (effects.EFFECTS) and never named: the analysis fits it only to ask whether
    the named effects still earn their keep beside it (analysis.outside_the_vocabulary).
    """

    columns: FloatArray  # (n, p) on every sample
    what: str  # the quantities it describes
    name: ClassVar[str] = "unexplained"
    family: ClassVar[str] = "descriptor"
    fitted_signal: ClassVar[str] = "current_drive"
    grid_parameters: ClassVar[tuple[GridParameter, ...]] = ()

    def __post_init__(self) -> None:
        self.parameters = tuple(Coefficient(f"c{k}", "A") for k in range(self.columns.shape[1]))
        self.description = f"generic description of the residual: {self.what}"
        self.grid_values = {"descriptor": float(next(_ids))}  # its own key in Problem's shape cache

    def grid(self, rig: Rig, signals: Signals) -> list[dict[str, float]]:
        return [self.grid_values]

    def unavailable(self, rig: Rig, signals: Signals) -> str | None:
        return None

    def shapes(self, rig: Rig, signals: Signals, grid) -> Shapes:
        return {"current": self.columns}

    def te_columns(self, rig: Rig, signals: Signals, state: ModelState, grid) -> FloatArray:
        raise NotImplementedError("a descriptor acts on the current")

    def signature(self, rig: Rig, signals: Signals, grid) -> tuple[str, FloatArray]:
        return "t [s]", signals.t

    def simulator_entry(self, values, grid) -> dict[str, float]:
        raise NotImplementedError("a descriptor is not an effect of the simulator")

    def from_simulator_entry(self, entry, rig):
        raise NotImplementedError("a descriptor is not an effect of the simulator")


def _candidates(signals: Signals, train: np.ndarray, r: FloatArray) -> list[tuple[str, FloatArray]]:
    """Every generic description as (label, columns on every sample): bins from the training samples' quantiles,
    for the angles the order that fits the training residual ``r`` (on ``train``) best."""
    out = []
    for name, x, bins, _label in quantities(signals, train):
        edges = bin_edges(x[train], bins)
        if len(edges) < 3:
            continue
        which = bin_index(x, edges)
        out.append((f"binned over {name}", (which[:, None] == np.arange(len(edges) - 1)[None, :]).astype(float)))
    sigma = direction(signals)
    for name, angle, orders in angles(signals):
        k, _explained, _amp = explained_by_orders(angle[train], sigma[train], r, orders, 0.0)
        if math.isfinite(k):
            out.append((f"{name}: order {k:g}", order_columns(angle, sigma, k)))
    return out


def _explained(columns: FloatArray, r: FloatArray, floor: float) -> tuple[float, FloatArray]:
    """(variance of r the columns explain less the noise's share [A^2], what is left of r)."""
    coef, *_ = np.linalg.lstsq(columns, r, rcond=None)
    fitted = columns @ coef
    return float(np.mean(fitted**2)) - columns.shape[1] * floor**2 / len(r), r - fitted


def describe_residual(problem: Problem, current: Fit, floor: float) -> Descriptor | None:
    """The generic description that takes most of the training residual of ``current`` (less what noise of the
    ``floor`` [A] would give), and a second one when it takes at least SECOND_SHARE of what the first leaves;
    None when none takes anything."""
    train = problem.split.train
    r = current.residual[train]
    chosen: list[tuple[str, FloatArray]] = []
    for _ in range(2):
        scored = [(c, *_explained(c[1][train], r, floor)) for c in _candidates(problem.signals, train, r)]
        scored = [s for s in scored if s[1] > 0.0 and s[0][0] not in (x[0] for x in chosen)]
        if not scored:
            break
        best = max(scored, key=lambda s: s[1])
        excess = float(np.mean(r**2)) - floor**2
        if chosen and best[1] < SECOND_SHARE * excess:
            break
        chosen.append(best[0])
        r = best[2]
    if not chosen:
        return None
    return Descriptor(np.hstack([c for _l, c in chosen]), "; ".join(label for label, _c in chosen))
