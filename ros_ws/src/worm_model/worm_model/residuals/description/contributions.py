"""Unique contributions: what each named effect buys on held-out data, with every other effect and correction
refitted without it, and a block-bootstrap interval."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from worm_model.residuals.description.aliases import AliasFinding
from worm_model.residuals.effects import EFFECTS
from worm_model.residuals.fitting.acceptance import paired_interval
from worm_model.residuals.fitting.fitting import SIGNAL_UNITS, Fit, Problem, fit


@dataclass
class Contribution:
    """What one accepted effect buys on held-out data: RMS of its signal without it minus with it.

    ``interval``: block-bootstrap interval (held-out blocks resampled, paired) at Settings.confidence.
    """

    name: str
    signal: str
    rms_without: float
    rms_with: float
    interval: tuple[float, float]

    @property
    def delta(self) -> float:
        return self.rms_without - self.rms_with

    @property
    def unit(self) -> str:
        return SIGNAL_UNITS[self.signal]




def contributions(problem: Problem, final: Fit, aliases: Sequence[AliasFinding]) -> list[Contribution]:
    """Each accepted effect's unique contribution: the final fit against the final fit without it.

    "Without" refits everything else (a fitted effect dropped; an alias's parameters clamped
    at their band edge), so shared explanatory power is not counted twice.
    """
    s = problem.settings
    out = []
    pairs = []
    for e in final.effects:
        rest = [(x.effect, x.grid) for x in final.effects if x is not e]
        pairs.append((e.name, e.effect.fitted_signal, fit(problem, rest, final)))
    pairs += [(a.effect, EFFECTS[a.effect].fitted_signal, a.clamped) for a in aliases]
    for name, signal, without in pairs:
        if signal == "transmission_error" and final.te is not None and without.te is not None:
            r0, r1, mask = without.te.residual, final.te.residual, problem.te_held_out
        else:
            signal = "current_drive"
            r0, r1, mask = without.residual, final.residual, problem.split.held_out
        out.append(Contribution(name, signal, without.rms(signal), final.rms(signal),
                                paired_interval(r0, r1, mask, problem.split.block, s.bootstrap, s.confidence)))
    return out


