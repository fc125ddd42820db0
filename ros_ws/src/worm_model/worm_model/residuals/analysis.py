"""Close the loop on measured data: fit, residual, rank candidate effects, add the significant ones.

The fitted signal is the drive current [A]; with a gear encoder in the data, also the
transmission error ratio theta_worm - theta_gear [rad at the gear] (declared model: a
constant per run, the encoders' zeros; effects with ``fitted_signal = "transmission_error"``,
i.e. backlash, add to it).  The two are fitted separately (the transmission-error terms
are linear and do not enter the current; they see the current model through its mesh
force) and scored each in its own unit; the BIC of a fit is the sum of both signals'.
:func:`analyse` runs the procedure (physics.md section 9), one named step each:

1. Split the samples into interleaved time blocks: a fraction is *held out* and never
   enters a fit (split.make_split); a guard interval at every block edge belongs to
   neither set, so no filter reaches across from one set into the other.
2. Fit the declared model (its free parameters and the standard refit set) to the training
   samples (fitting.fit): the parameter corrections.
3. :func:`selection.forward_selection`: rank every candidate effect by the held-out RMS error left
   after adding it (screening.screen: a Gauss-Newton step from the current fit with the effect's
   regressors and the model's own Jacobian, its grid parameters chosen on training data); take the
   best one whose full refit lowers that signal's held-out RMS by at least ``min_improvement``
   (relative) consistently over the held-out blocks, does not raise the other signal's by as much,
   lowers the BIC on the training samples, *and* keeps every refitted parameter physical
   (acceptance); repeat while one is left and the current is above ``at_floor`` x its noise floor.
4. :func:`selection.backward_elimination`: drop any accepted effect that no longer earns its keep in
   the final set (the rest refitted without it).
5. :func:`outside_the_vocabulary`: when the current stays above ``unexplained_factor`` x its noise
   floor, each named effect must also earn its keep beside a generic description of what is left
   (descriptors.describe_residual: binned means over speed, load, time, ...; angle orders); an effect
   that only took a share of a residual no effect of the vocabulary describes is dropped, and the
   residual is reported as unexplained instead.
6. Name the effects that are aliases of refitted parameters beyond their tolerance
   (aliases.resolve_aliases, free.TOLERANCES), report every accepted effect's unique
   contribution with a block-bootstrap interval (contributions.contributions), estimate the noise
   floor from the data (unexplained.noise_floor) and, when the held-out RMS stays above
   ``unexplained_factor`` x that floor, describe the unexplained residual
   (unexplained.describe_unexplained).

Why this shape.  The parameters a rig file typically gets wrong (mu, K_t, drags, rotor
inertia: free.STANDARD_REFIT) are refitted always, whatever the friction model and whatever the
provenance of the declared number, so that a wrong declared value, or a wrong reference state of a
mu effect (oil temperature, load, speed: they all modulate mu, which is refitted), shows as a
*parameter correction* and not as a string of effects that each buy 2 %.  Forward selection then
only sees what no correction can produce; backward elimination and the floor rule remove what a
later effect made redundant; an effect that would need a nonphysical correction (a mu scale of
0.03 bought with a 78-fold Stribeck rise) is not taken.  What is left above the floor is
reported as unexplained rather than forced onto a name.

The names a caller needs are importable from here: :class:`Settings`, :class:`Problem`,
:func:`make_split`, :func:`fit`, :func:`analyse`, :class:`Analysis`, :func:`extended_effects`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

from worm_model.physics.parameters import Rig

from worm_model.residuals.description.aliases import AliasFinding, resolve_aliases, with_aliases_as_effects
from worm_model.residuals.description.contributions import Contribution, contributions
from worm_model.residuals.description.descriptors import describe_residual
from worm_model.residuals.description.unexplained import NoiseFloor, Unexplained, describe_unexplained, noise_floor
from worm_model.residuals.effects import Effect
from worm_model.residuals.fitting.acceptance import accepts
from worm_model.residuals.fitting.fitting import Fit, Problem, fit
from worm_model.residuals.fitting.split import Split, make_split
from worm_model.residuals.selection import Round, backward_elimination, forward_selection
from worm_model.residuals.settings import Settings

__all__ = ["Analysis", "Problem", "Settings", "analyse", "extended_effects", "fit", "make_split"]


@dataclass
class Analysis:
    declared: Fit  # the declared model, its free parameters fitted (the corrections)
    final: Fit  # with the effects found
    rounds: list[Round]
    split: Split
    pruned: list[str] = field(default_factory=list)
    aliases: list[AliasFinding] = field(default_factory=list)
    contributions: list[Contribution] = field(default_factory=list)
    noise: NoiseFloor | None = None
    unexplained: Unexplained | None = None
    nominal: Fit | None = None  # the rig file as declared, nothing fitted (encoder offsets aside)
    outside: list[str] = field(default_factory=list)  # dropped: they only took a share of the unexplained residual

    @property
    def rms_before(self) -> float:
        """Held-out RMS of the current [A] by the rig file as declared (nothing fitted)."""
        return (self.nominal or self.declared).rms_held_out

    @property
    def found(self) -> list[str]:
        """Effects named: those fitted, then those named through a parameter beyond its tolerance."""
        names = list(self.final.names)
        names += [a.effect for a in self.aliases if a.effect not in names]
        return names

    @property
    def aliased_parameters(self) -> set[str]:
        return {p for a in self.aliases for p in a.parameters}


def analyse(problem: Problem, progress: Callable[[str, int, int], None] | None = None) -> Analysis:
    """Fit the declared model, then add significant effects one at a time (module docstring: the steps)."""
    declared = fit(problem, [])
    selected, rounds = forward_selection(problem, declared, progress)
    kept, pruned = backward_elimination(problem, selected)
    final, outside = outside_the_vocabulary(problem, kept)
    aliases = resolve_aliases(problem, final)
    noise = noise_floor(problem, final)
    unexplained = None
    if final.rms_held_out > problem.settings.unexplained_factor * noise.rms:
        unexplained = describe_unexplained(problem, final, noise)
    return Analysis(declared=declared, final=final, rounds=rounds, split=problem.split, pruned=pruned,
                    aliases=aliases, contributions=contributions(problem, final, aliases), noise=noise,
                    unexplained=unexplained, nominal=nominal_fit(problem), outside=outside)


def nominal_fit(problem: Problem) -> Fit:
    """The rig file as declared: nothing refitted (only the transmission error's encoder offsets)."""
    return fit(Problem(problem.rig0, [], problem.signals, problem.current, problem.split,
                       replace(problem.settings, refit=())), [])


def outside_the_vocabulary(problem: Problem, current: Fit) -> tuple[Fit, list[str]]:
    """Step 5: the named current effects that do not earn their keep beside a description of what is left.

    Only when the current stays above ``unexplained_factor`` x its noise floor (and
    ``Settings.check_outside_vocabulary``).  The residual of
    ``current`` is described generically (descriptors.describe_residual: the columns that capture it
    best, over speed, load, time, direction, temperature, worm and gear angle orders); with that
    description in the model, each named effect of the current is refitted out and must still pass
    acceptance.accepts against the fit without it.  One that does not only took a share of a residual
    no effect of the vocabulary describes (a drift in time is not a sensor offset; a load-dependent
    bearing drag is not a load-dependent mu): it is dropped, one at a time (the weakest first), and
    the search is repeated on what is left.  Returns (the fit without them, their names).
    """
    settings = problem.settings
    dropped: list[str] = []
    while settings.check_outside_vocabulary:
        named = [e for e in current.effects if e.effect.fitted_signal == "current_drive"]
        if not named:
            return current, dropped
        floor = noise_floor(problem, current).rms
        if current.rms_held_out <= settings.unexplained_factor * floor:
            return current, dropped
        descriptor = describe_residual(problem, current, floor)
        if descriptor is None:
            return current, dropped
        specs = [(e.effect, e.grid) for e in current.effects]
        with_all = fit(problem, specs + [(descriptor, descriptor.grid_values)], current)
        weakest = None
        for e in named:
            rest = [(x.effect, x.grid) for x in current.effects if x is not e]
            without = fit(problem, rest + [(descriptor, descriptor.grid_values)], current)
            if not accepts(without, with_all, settings, "current_drive", problem):
                margin = without.rms_held_out - with_all.rms_held_out
                if weakest is None or margin < weakest[0]:
                    weakest = (margin, e)
        if weakest is None:
            return current, dropped
        e = weakest[1]
        current = fit(problem, [(x.effect, x.grid) for x in current.effects if x is not e], current)
        dropped.append(e.name)
    return current, dropped


def extended_effects(result: Analysis) -> tuple[Rig, list[tuple[Effect, dict, dict]]]:
    """The extended model of an analysis as (rig, [(effect, values, grid)]): alias effects written as effects
    (aliases.with_aliases_as_effects)."""
    return with_aliases_as_effects(result.final, result.aliases)
