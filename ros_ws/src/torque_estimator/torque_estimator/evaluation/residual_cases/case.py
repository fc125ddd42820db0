"""A case of the residual case matrix and its result: what is simulated, what was found, and the pass rule.

A case passes when ``effects_found`` is exactly its true set (parameter corrections are not
effects), every refitted drag and mu is physical (not below 0) and the held-out RMS after is
within ``Settings.unexplained_factor`` (1.3) of the noise floor estimated from the data; with an
effect outside the vocabulary (simulation.OUT_OF_VOCABULARY) it passes when nothing is named (the
residual above 1.3x the floor is then reported as ``unexplained=``; what the corrections can take of
such an effect, as mu takes most of a load-proportional bearing drag, may leave it at the floor).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import worm_model.residuals.analysis as an
from worm_model.residuals.free import LOWER_BOUNDS, mu_parameter

from torque_estimator.evaluation.residual_cases.rig_files import plant_rig


@dataclass(frozen=True)
class Case:
    """One simulated data set and what the analysis should name.

    ``effects``: the simulator's ``effects:`` mapping; ``extra``: out-of-vocabulary effects
    (:data:`OUT_OF_VOCABULARY` keys) added to the simulator; ``truth``: the names a correct
    analysis gives (the vocabulary effects switched on).  ``rig``: a :data:`RIGS` key;
    ``plant``: perturbation groups where the simulated rig differs from its file (e.g.
    ``{"drags": 0.0}``: no drag at all); ``perturbation``: the rig file given to the analysis.
    """

    name: str
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    profile: str = "standard"
    perturbation: str = "nominal"
    extra: tuple[str, ...] = ()
    oil_start: tuple[float, ...] = ()
    runs: int = 10
    seconds: float = 4.0
    seed: int = 1
    rig: str = "nmrv030"
    plant: Mapping[str, float] = field(default_factory=dict)

    @property
    def truth(self) -> tuple[str, ...]:
        return tuple(sorted(self.effects))


@dataclass
class CaseResult:
    case: Case
    found: tuple[str, ...]
    rms_before: float  # [A] held-out, rig file as declared
    rms_after: float  # [A] held-out, corrections and effects
    floor: float  # [A] noise floor estimated from the data
    unexplained: float | None  # [A] or None
    corrections: dict[str, float]  # refitted parameter -> identified / declared
    seconds: float  # wall time of simulation + analysis
    identified: dict[str, float] = field(default_factory=dict)  # refitted parameter -> identified value [SI]
    true: dict[str, float] = field(default_factory=dict)  # refitted parameter -> the simulated rig's value [SI]

    @property
    def truth(self) -> tuple[str, ...]:
        return self.case.truth

    @property
    def false_names(self) -> tuple[str, ...]:
        return tuple(sorted(set(self.found) - set(self.truth)))

    @property
    def missed(self) -> tuple[str, ...]:
        return tuple(sorted(set(self.truth) - set(self.found)))

    @property
    def exact(self) -> bool:
        return not self.false_names and not self.missed

    @property
    def within_floor(self) -> bool:
        return self.rms_after <= an.Settings().unexplained_factor * self.floor

    @property
    def unphysical(self) -> tuple[str, ...]:
        """Refitted parameters identified below their physical bound (drags, mu, inertias: free.LOWER_BOUNDS)."""
        return tuple(p for p, low in LOWER_BOUNDS.items() if self.identified.get(p, low) < low)

    @property
    def mu_ratio(self) -> float:
        """Identified / true value of the friction model's mu parameter (NaN when it was not refitted)."""
        name = mu_parameter(plant_rig(self.case.rig).friction.model)
        true = self.true.get(name, math.nan)
        return self.identified.get(name, math.nan) / true if true else math.nan

    @property
    def passed(self) -> bool:
        """Exact names and physical corrections, and at the floor; with an effect outside the vocabulary, nothing
        named (``unexplained=`` is then reported whenever the corrections leave more than 1.3x the floor: what
        they can take of it, e.g. of a load-proportional bearing drag through mu, is theirs)."""
        if self.unphysical:
            return False
        if self.case.extra:
            return self.exact and (self.unexplained is not None or self.within_floor)
        return self.exact and self.within_floor and self.unexplained is None
