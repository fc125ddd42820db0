"""Screening: every candidate effect scored by the held-out error it would leave, one Gauss-Newton step from the
current fit (the candidate's regressors with the model's own Jacobian), its grid parameters chosen on training data.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from worm_model.physics.parameters import Rig

from worm_model.residuals.effects import EFFECTS, Effect, regressors
from worm_model.residuals.fitting.fitting import (SIGNAL_UNITS, Fit, Problem, bic, by_signal, effective_samples,
                                                  rms_of, te_columns, te_solve)
from worm_model.residuals.free import PURE_ALIASES
from worm_model.residuals.model import ModelState, sensitivities




@dataclass
class Candidate:
    """One candidate effect's score in one round (linearised from the current fit)."""

    name: str
    grid: dict[str, float]
    rms_held_out: float  # held-out RMS of its signal left after adding it [unit of the signal]
    improvement: float  # relative held-out improvement of its signal over the current fit
    delta_bic: float  # BIC(with) - BIC(without) on training data; < 0 favours the effect
    guess: dict[str, float]  # linear parameter estimates
    note: str = ""
    profile: list[tuple[float, float]] = field(default_factory=list)  # (grid value, training RSS)
    signal: str = "current_drive"  # the signal it acts on

    @property
    def significant(self) -> bool:
        return self.delta_bic < 0.0 and self.improvement >= 0.0

    @property
    def unit(self) -> str:
        return SIGNAL_UNITS[self.signal]


def _screen_te(problem: Problem, current: Fit, effect: Effect, rig: Rig, state: ModelState) -> Candidate:
    """A transmission-error candidate: linear least squares with the TE terms already in, per grid value."""
    base = te_columns(problem, by_signal([(e.effect, e.grid) for e in current.effects], "transmission_error"),
                      rig, state)
    train, held = problem.te_train, problem.te_held_out
    best, profile = None, []
    for grid in effect.grid(rig, problem.signals):
        cols = effect.te_columns(rig, problem.signals, state, grid)
        sol = te_solve(problem, np.hstack([base, cols]))
        profile.append((grid, sol.rss))
        if best is None or sol.rss < best[1].rss:
            best = (grid, sol)
    grid, sol = best
    te0 = current.te
    n_eff = effective_samples(np.nan_to_num(sol.residual), train, problem.signals.run)
    k_new = len(effect.parameters) + (len(effect.grid_parameters) if len(profile) > 1 else 0)
    d_bic = bic(sol.rss, te0.n_train, n_eff, te0.n_params + k_new) - bic(te0.rss_train, te0.n_train, n_eff,
                                                                         te0.n_params)
    rms_ho = rms_of(sol.residual[held])
    coef = sol.coef[base.shape[1]:]
    return Candidate(effect.name, dict(grid), rms_ho, 1.0 - rms_ho / te0.rms_held_out, d_bic,
                     {p.name: float(c) for p, c in zip(effect.parameters, coef)},
                     profile=[(next(iter(g.values()), math.nan), r) for g, r in profile], signal="transmission_error")


def screen(problem: Problem, current: Fit, progress: Callable[[int], None] | None = None) -> list[Candidate]:
    """Score every candidate effect not yet in ``current``; largest relative improvement first.

    A current candidate's columns are fitted together with the model's own Jacobian (free
    parameters and effects already in), i.e. one Gauss-Newton step from the current fit,
    on the training samples.  By Frisch-Waugh-Lovell the candidate's coefficients come
    from its columns projected off the Jacobian (one QR per round), so a candidate costs
    a least-squares problem of its own few columns.  A transmission-error candidate is
    linear: fitted with the offsets and the TE terms already in.  Each is scored on its
    own signal (relative held-out improvement, BIC change).
    """
    train, held = problem.split.train, problem.split.held_out
    use = train | held
    specs = by_signal([(e.effect, e.grid) for e in current.effects], "current_drive")
    theta = problem.theta0(current, specs)
    state, rig, _, _ = problem.predict(theta, specs)
    sens = sensitivities(rig, problem.signals, state)
    base = problem.jacobian(theta, specs, use)  # model's own directions, re-adjusted with each candidate
    r = current.residual[use]
    tr = train[use]
    b_tr, r_tr = base[tr], r[tr]
    if base.shape[1]:
        q, _ = np.linalg.qr(b_tr / np.maximum(np.linalg.norm(b_tr, axis=0), 1e-300))
    else:
        q = np.zeros((len(r_tr), 0))
    r_perp = r_tr - q @ (q.T @ r_tr)
    out: list[Candidate] = []
    done = 0
    for name in problem.settings.candidates:
        effect = EFFECTS[name]
        if name in current.names:
            continue
        te_effect = effect.fitted_signal == "transmission_error"
        why = effect.unavailable(rig, problem.signals)
        aliased = PURE_ALIASES.get(name, ())
        if not why and aliased and all(p in problem.free for p in aliased):
            why = (f"the same function of the data as the refitted {', '.join(aliased)}: named only when that "
                   f"correction leaves its tolerance band (free.TOLERANCES)")
        if not why and te_effect and not problem.has_te:
            why = "too few transmission-error samples (theta_gear) in the training or held-out set"
        if why:
            rms0 = current.rms(effect.fitted_signal)
            out.append(Candidate(name, {}, rms0, 0.0, math.inf, {}, note=why, signal=effect.fitted_signal))
            continue
        if te_effect:
            out.append(_screen_te(problem, current, effect, rig, state))
            done += 1
            if progress:
                progress(done)
            continue
        best = None
        profile = []
        for grid in effect.grid(rig, problem.signals):
            X = regressors(effect, rig, problem.signals, state, problem.shapes(effect, rig, grid), sens)[use]
            x_tr = X[tr]
            x_perp = x_tr - q @ (q.T @ x_tr)
            norms = np.linalg.norm(x_perp, axis=0)
            norms[norms == 0] = 1.0
            coef, *_ = np.linalg.lstsq(x_perp / norms, r_perp, rcond=1e-10)
            coef = coef / norms
            rss = float(np.sum((r_perp - x_perp @ coef) ** 2))
            profile.append((grid, rss))
            if best is None or rss < best[1]:
                best = (grid, rss, X, coef)
        grid, rss, X, coef = best
        # the model's own parameters move with the candidate: their step from the training rows
        delta, *_ = np.linalg.lstsq(b_tr, r_tr - X[tr] @ coef, rcond=None) if base.shape[1] else (np.zeros(0),)
        left = r - base @ delta - X @ coef
        full = np.zeros(len(problem.current))
        full[use] = left
        n_eff = effective_samples(full, train, problem.signals.run)
        k_new = len(effect.parameters) + (len(effect.grid_parameters) if len(profile) > 1 else 0)
        d_bic = bic(rss, current.n_train, n_eff, current.n_params + k_new) - bic(
            current.rss_train, current.n_train, n_eff, current.n_params)
        rms_ho = rms_of(left[~tr])
        out.append(Candidate(name, dict(grid), rms_ho, 1.0 - rms_ho / current.rms_held_out, d_bic,
                             {p.name: float(c) for p, c in zip(effect.parameters, coef)},
                             profile=[(next(iter(g.values()), math.nan), s) for g, s in profile]))
        done += 1
        if progress:
            progress(done)
    return sorted(out, key=lambda c: -c.improvement)


def grid_interval(candidate: Candidate, n_eff: float, n: int, confidence: float) -> tuple[float, float]:
    """Profile-likelihood interval of a 1-D grid parameter: grid values within the chi2(1) bound."""
    if len(candidate.profile) < 2:
        return (math.nan, math.nan)
    rss = np.array([s for _g, s in candidate.profile])
    values = np.array([g for g, _s in candidate.profile])
    stat = n_eff * np.log(rss / rss.min())
    # imported at first use: scipy.stats takes ~0.4 s to import, paid at start by every executable
    from scipy.stats import chi2

    inside = values[stat <= chi2.ppf(confidence, 1)]
    return float(inside.min()), float(inside.max())


