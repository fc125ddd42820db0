"""What a record can tell: which of the rig's uncertain parameters it identifies, and why not the others.

A parameter is fitted only where the record pins it better than the rig file already does:

* **a priori**, from what the record is: no inertia from held speeds (a steady record shows no
  acceleration); no K_t from a torque channel (a drive that reports K_t x current as its torque
  reports the product, :attr:`worm_model.rig_data.schema.MeasuredData.current_from_torque`);
* **by its band**: at the fit, the parameter's 95 % confidence half-width (least squares, the
  residual's own variance) must be narrower than the half-width of its *tolerance band*, the
  spread of a declared value a user should expect (:func:`tolerance_half_width`:
  worm_model.residuals.free.TOLERANCES; mu: a catalogue value is a guess within x2 either way,
  x0.4..x2.5 as the drags; the output's inertia, which a datasheet does not give: x0.2..x5). A band
  wider than that says the record cannot tell the parameter apart from others (it is named with
  the one it correlates with most, and what record would separate them);
* **by its bound**: a fit that takes a parameter to its physical bound (a drag or mu at 0) has traded
  it against another; the bound is not a value for it.

:func:`assess` takes a fit's Jacobian and residual and returns the confidence half-widths, the
correlations and the parameter to hold first (the worst ratio of half-width to band); the roads
(identification.fit) hold it at its declared value, refit, and ask again until every parameter left
passes. Each held parameter is written as a :class:`Held` line::

    not identifiable from this run: friction.mu_constant with load_motor.coulomb_drag (one load); to separate
    them, record a second load

No ROS; numpy + scipy.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from worm_model.physics.parameters import Rig
from worm_model.residuals.free import TOLERANCES, get_value

#: the rig's sections (a parameter of another name is an effect's)
_RIG_SECTIONS = frozenset(f.name for f in dataclasses.fields(Rig))
#: the confidence of the bands compared
CONFIDENCE = 0.95
#: a parameter held for its band is named with the parameter it correlates with most when |r| is above this
PARTNER_CORRELATION = 0.8
#: relative tolerance half-widths of what free.TOLERANCES leaves open: mu x0.4..x2.5, the output inertia x0.2..x5
OWN_BANDS = {"friction.mu_constant": (0.4, 2.5), "friction.scale": (0.4, 2.5), "gearbox.gear_inertia": (0.2, 5.0),
             "gearbox.worm_inertia": (0.2, 5.0)}


@dataclass(frozen=True)
class RecordFacts:
    """What a record holds, for the reasons and hints: distinct loads and speeds, whether it accelerates, and
    whether its current is a torque the drive divided by K_t."""

    loads: int
    speeds: int
    accelerates: bool
    current_from_torque: bool
    directions: int = 2

    def hint(self) -> str:
        """What a second record should add to separate what this one cannot."""
        if self.loads < 2:
            return "record a second load"
        if not self.accelerates:
            return "record speed steps (the acceleration shows the inertias)"
        if self.directions < 2:
            return "record both directions of rotation"
        if self.speeds < 4:
            return "record more speeds"
        return "record longer, or more loads and speeds"

    def describe(self) -> str:
        what = [f"{self.loads} load" + ("s" if self.loads != 1 else "")]
        if not self.accelerates:
            what.append("held speeds")
        return ", ".join(what)


@dataclass(frozen=True)
class Held:
    """A parameter held at its declared value, and why (one line: :meth:`line`)."""

    parameter: str
    reason: str  # "band", "bound", "held speeds", "torque channel"
    detail: str  # what the line says after the name

    def line(self) -> str:
        return f"not identifiable from this run: {self.parameter} {self.detail}"


def tolerance_half_width(name: str, declared: float, rig: Rig) -> float:
    """Half-width [SI] of the tolerance band around ``declared`` (module docstring); inf where none is known."""
    if name in OWN_BANDS:
        low, high = OWN_BANDS[name]
        return 0.5 * (high - low) * abs(declared) if declared else math.inf
    tol = TOLERANCES.get(name)
    if tol is None:
        return math.inf
    low, high = tol.band(declared, rig)
    if low is None or high is None:
        return math.inf
    return 0.5 * (high - low)


@dataclass
class Assessment:
    """The confidence half-widths [SI], correlations and bands of a fit's parameters, and which to hold first."""

    names: list[str]
    half_width: dict[str, float]
    band: dict[str, float]
    correlation: np.ndarray
    at_bound: list[str]

    @classmethod
    def of(cls, names: Sequence[str], half_width: dict[str, float], correlation: np.ndarray, declared: Rig,
           at_bound: Sequence[str] = (), values: Mapping[str, float] | None = None) -> "Assessment":
        """From a fit's 95 % half-widths [SI] and correlation matrix (order ``names``); the bands around
        ``declared``'s values (``values``: declared values to use instead, e.g. mu under another law)."""
        names = list(names)
        values = values or {}
        band = {n: tolerance_half_width(n, values[n], declared) if n in values
                else tolerance_half_width(n, get_value(declared, n), declared) if n.split(".")[0] in _RIG_SECTIONS
                else math.inf for n in names}  # an effect's parameter has no declared value: no band
        return cls(names, dict(half_width), band, np.asarray(correlation, dtype=float),
                   [n for n in at_bound if n in names])

    def partner(self, name: str) -> str | None:
        """The parameter ``name`` correlates with most, when above PARTNER_CORRELATION."""
        k = self.names.index(name)
        r = np.abs(np.nan_to_num(self.correlation[k]))
        r[k] = 0.0
        j = int(np.argmax(r)) if len(r) > 1 else k
        return self.names[j] if j != k and r[j] > PARTNER_CORRELATION else None

    def worst(self, candidates: Sequence[str] | None = None) -> str | None:
        """The parameter to hold first among ``candidates`` (default all): one at its bound, else the one whose
        half-width exceeds its band by the largest factor; None when every one passes."""
        names = [n for n in self.names if candidates is None or n in candidates]
        bound = [n for n in names if n in self.at_bound]
        if bound:
            return max(bound, key=lambda n: self.half_width[n] / self.band[n] if self.band[n] > 0 else math.inf)
        ratio = {n: self.half_width[n] / self.band[n] for n in names if self.band[n] > 0}
        over = {n: r for n, r in ratio.items() if not r <= 1.0}
        return max(over, key=over.get) if over else None

    def held(self, name: str, facts: RecordFacts) -> Held:
        """The :class:`Held` line of holding ``name`` (module docstring)."""
        partner = self.partner(name)
        if name in self.at_bound:
            detail = ("(the fit traded it to its physical bound" + (f" against {partner}" if partner else "") +
                      f"; {facts.describe()}); to separate them, {facts.hint()}")
            return Held(name, "bound", detail)
        ci, band = self.half_width[name], self.band[name]
        with_ = f"with {partner} " if partner else ""
        detail = (f"{with_}(95 % band +-{ci:.3g} wider than its tolerance +-{band:.3g}; {facts.describe()}); to "
                  f"{'separate them' if partner else 'pin it'}, {facts.hint()}")
        return Held(name, "band", detail)


#: the normal matrix (columns scaled to unit norm) is singular along an eigenvector whose eigenvalue is below this
#: share of the largest; a parameter takes part in that direction where its component exceeds NULL_COMPONENT
NULL_RCOND, NULL_COMPONENT = 1e-12, 1e-6


def assess(names: Sequence[str], jacobian: np.ndarray, residual: np.ndarray, declared: Rig,
           at_bound: Sequence[str] = (), inflation: float = 1.0, values: Mapping[str, float] | None = None
           ) -> Assessment:
    """The confidence half-widths and correlations of parameters ``names`` at a least-squares fit.

    Args:
        jacobian: d residual / d parameter [signal unit per SI unit], shape (n, len(names)).
        residual: the fit's residual (signal unit), shape (n,): its variance scales the covariance.
        declared: the rig file as declared (the bands are around its values).
        at_bound: parameters the fit left on a physical bound.
        inflation: variance factor for correlated residuals (n / n_eff).
        values: declared values to use instead of ``declared``'s (Assessment.of).
    """
    names = list(names)
    J = np.asarray(jacobian, dtype=float).reshape(len(residual), len(names))
    dof = max(len(residual) - len(names), 1)
    variance = float(np.sum(np.asarray(residual) ** 2)) / dof * inflation
    scale = np.linalg.norm(J, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    Js = J / scale
    normal = Js.T @ Js
    cov = np.linalg.pinv(normal) * variance / np.outer(scale, scale)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov / np.outer(sd, sd)
    # a direction the data do not see at all (the normal matrix singular along it): the pseudo-inverse gives it no
    # variance, the truth is an unbounded one; its parameters trade one for another along it, fully correlated
    if len(names):
        eigen, vectors = np.linalg.eigh(normal)
        for k in np.flatnonzero(eigen <= NULL_RCOND * max(float(eigen.max()), 1e-300)):
            v = vectors[:, k]
            involved = np.flatnonzero(np.abs(v) > NULL_COMPONENT)
            sd[involved] = np.inf
            for i in involved:
                for j in involved:
                    corr[i, j] = 1.0 if i == j else float(np.sign(v[i] * v[j]))
    # a parameter the data do not move at all (a zero column): unbounded
    sd = np.where(np.linalg.norm(J, axis=0) > 0, sd, np.inf)
    # imported at first use: scipy.stats takes ~0.4 s to import, paid at start by every executable
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + CONFIDENCE / 2.0))
    return Assessment.of(names, {n: float(z * s) for n, s in zip(names, sd)}, corr, declared, at_bound, values)


__all__ = ["CONFIDENCE", "Assessment", "Held", "NULL_COMPONENT", "NULL_RCOND", "OWN_BANDS", "RecordFacts", "assess",
           "tolerance_half_width"]
