"""The search for effects: forward selection, one effect a round, then backward elimination.

:func:`forward_selection`
    Each round screens every candidate (screening.screen), then takes the best-ranked one whose
    full refit passes acceptance.accepts (held-out improvement, consistent over the blocks, lower
    BIC) and keeps the refitted parameters physical (acceptance.physical); no current effect is
    added once the current is within ``at_floor`` x its noise floor.  From an unphysical start (the
    corrections twisted around an effect) every significant candidate is tried and the choice
    looks one step ahead (:func:`_look_ahead`).  It stops when a round accepts nothing.
:func:`backward_elimination`
    Drops, one at a time, an accepted effect that no longer earns its keep in the final set (the
    rest refitted without it: not accepted by the same criteria, or the current within
    ``at_floor`` x its floor without it), unless the rest alone would be unphysical.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from worm_model.residuals.description.unexplained import noise_floor
from worm_model.residuals.effects import EFFECTS
from worm_model.residuals.fitting.acceptance import accepts, physical
from worm_model.residuals.fitting.fitting import Fit, Problem, fit
from worm_model.residuals.fitting.screening import Candidate, grid_interval, screen


@dataclass
class Round:
    """One round of the search: the ranking and what was added."""

    candidates: list[Candidate]
    accepted: str | None
    refit_rms_held_out: float | None = None
    baseline_rms_held_out: float = math.nan  # held-out RMS of the fit the round started from [A]
    baseline_te_rms_held_out: float = math.nan  # the same for the transmission error [rad] (NaN: none)


def forward_selection(problem: Problem, start: Fit, progress: Callable[[str, int, int], None] | None = None
                      ) -> tuple[Fit, list[Round]]:
    """Add significant effects to ``start`` one round at a time (module docstring): (final fit, rounds)."""
    current, rounds = start, []
    total = len(problem.settings.candidates)
    while len(current.effects) < problem.settings.max_effects:
        label = f"round {len(rounds) + 1}"
        ranking = screen(problem, current, (lambda k, label=label: progress(label, k, total)) if progress else None)
        chosen = _choose(problem, current, ranking)
        rounds.append(Round(ranking, chosen[0].name if chosen else None,
                            chosen[1].rms_held_out if chosen else None, current.rms_held_out,
                            current.te.rms_held_out if current.te is not None else math.nan))
        if chosen is None:
            break
        current = _keep_grid_intervals(current, _with_grid_interval(problem, *chosen))
    return current, rounds


def _choose(problem: Problem, current: Fit, ranking: Sequence[Candidate]) -> tuple[Candidate, Fit] | None:
    """The candidate a round adds, with its refit: the best-ranked acceptable one that keeps the fit physical;
    from an unphysical start, the best held-out one that makes it physical (looking one step ahead)."""
    settings = problem.settings
    at_floor = current.rms_held_out <= settings.at_floor * noise_floor(problem, current).rms
    sane = physical(problem, current)
    tried: list[tuple[Candidate, Fit]] = []  # significant, accepted by the test (unphysical start)
    fallback = None
    for cand in ranking:
        if not cand.significant or cand.improvement < settings.min_improvement:
            continue
        if at_floor and cand.signal == "current_drive":
            continue  # the current is already at its noise floor: nothing there left to name
        effect = EFFECTS[cand.name]
        specs = [(e.effect, e.grid) for e in current.effects] + [(effect, cand.grid)]
        trial = fit(problem, specs, current, {cand.name: cand.guess})
        if not accepts(current, trial, settings, effect.fitted_signal, problem):
            continue
        if sane:
            if physical(problem, trial):
                return cand, trial
            continue
        tried.append((cand, trial))
        # from an unphysical start (an effect the corrections twisted themselves around) every significant
        # candidate is tried: the best held-out one that makes the fit physical, failing one the best
        key = (not physical(problem, trial), trial.rms(effect.fitted_signal) / current.rms(effect.fitted_signal))
        if fallback is None or key < fallback[0]:
            fallback = (key, (cand, trial))
    if fallback is None:
        return None
    return _look_ahead(problem, tried, fallback)[1]


def _with_grid_interval(problem: Problem, cand: Candidate, trial: Fit) -> Fit:
    """``trial`` with the profile interval of the added effect's grid parameter (from the screening profile)."""
    n_eff = trial.te.n_eff if cand.signal == "transmission_error" else trial.n_eff
    if len(cand.profile) > 1:
        interval = grid_interval(cand, n_eff, trial.n_train, problem.settings.confidence)
        for g in EFFECTS[cand.name].grid_parameters:
            trial.effects[-1].grid_ci[g.name] = interval
    return trial


def _keep_grid_intervals(old: Fit, new: Fit) -> Fit:
    """``new`` with the grid intervals ``old`` found for the effects both have (a refit does not recompute them)."""
    known = {e.name: e.grid_ci for e in old.effects}
    for e in new.effects:
        e.grid_ci = e.grid_ci or known.get(e.name, {})
    return new


def backward_elimination(problem: Problem, current: Fit) -> tuple[Fit, list[str]]:
    """Drop the accepted effects the later ones made redundant (module docstring): (final fit, names dropped)."""
    settings = problem.settings
    pruned: list[str] = []
    changed = len(current.effects) > 1
    while changed and len(current.effects) > 1:
        changed = False
        for e in list(current.effects):
            rest = [(x.effect, x.grid) for x in current.effects if x is not e]
            without = fit(problem, rest, current)
            # dropped: no longer significant, or not needed to reach the current's noise floor; but never
            # when the rest alone is unphysical (the effect keeps the refitted parameters sane)
            needless = e.effect.fitted_signal == "current_drive" and \
                without.rms_held_out <= settings.at_floor * noise_floor(problem, current).rms
            if (needless or not accepts(without, current, settings, e.effect.fitted_signal, problem)) and (
                    physical(problem, without) or not physical(problem, current)):
                current = _keep_grid_intervals(current, without)
                pruned.append(e.name)
                changed = True
                break
    return current, pruned


#: from an unphysical start, the physical first steps judged by what they let in next (see _look_ahead)
LOOK_AHEAD = 3


def _look_ahead(problem: Problem, tried: Sequence[tuple[Candidate, Fit]], fallback):
    """From an unphysical start, pick the first step by the best physical fit two steps make.

    The corrections can twist around an effect (a x3 Stribeck rise at low speed lets the Coulomb and
    viscous drags grow ten-fold); then several effects each make the fit physical again, and the best
    of them alone (a viscous drag) need not be the one that lets the others in (the Stribeck law, after
    which the cogging the twisted start refused is accepted).  So each of the LOOK_AHEAD physical first
    steps with the lowest held-out RMS is paired with each significant candidate it has not taken, and
    the best physical pair that the acceptance test passes is taken, both effects at once (taking only
    its first step let the viscous drag in and kept a x3 Stribeck rise out); the backward pass then
    drops whichever of the two the rest makes needless.  Without such a pair the single best
    (``fallback``) stands.  Only runs from an unphysical start.
    """
    settings = problem.settings
    firsts = sorted(((c, t) for c, t in tried if physical(problem, t)),
                    key=lambda ct: ct[1].rms(EFFECTS[ct[0].name].fitted_signal))[:LOOK_AHEAD]
    if len(firsts) < 2:
        return fallback
    best = None
    for cand, trial in firsts:
        for other, _t in tried:
            if other.name == cand.name:
                continue
            effect = EFFECTS[other.name]
            specs = [(e.effect, e.grid) for e in trial.effects] + [(effect, other.grid)]
            pair = fit(problem, specs, trial, {other.name: other.guess})
            if not (physical(problem, pair) and accepts(trial, pair, settings, effect.fitted_signal, problem)):
                continue
            if best is None or pair.rms_held_out < best[0]:
                best = (pair.rms_held_out, (cand, pair))
    if best is None:
        return fallback
    return ((False, 0.0), best[1])


