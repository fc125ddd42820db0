"""The options of a residual analysis (:class:`Settings`; the ``residuals`` CLI exposes each one)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from worm_model.physics.parameters import Rig
from worm_model.physics.resolution import kinetic_speed

from worm_model.residuals.effects import EFFECTS
from worm_model.residuals.free import STANDARD_REFIT
from worm_model.residuals.model import ALPHA_TIME_CONSTANT, REFERENCE_TEMPERATURE


@dataclass(frozen=True)
class Settings:
    """Options of the analysis (the CLI exposes each one)."""

    holdout_fraction: float = 1.0 / 3.0  # share of the blocks held out
    block_seconds: float = 2.0  # length of a split block [s]
    guard_seconds: float = 0.05  # excluded at both ends of every block [s]
    # samples slower than this [rad/s] are not used (no kinetic model at rest); None: the rig's own
    # (worm_model.physics.resolution.kinetic_speed: 5 x its speed noise), :meth:`for_rig`
    min_speed: float | None = None
    min_improvement: float = 0.02  # relative held-out RMS improvement an effect must bring
    # relative held-out RMS rise of the *other* signal (current vs transmission error) an effect may cause;
    # None: min_improvement (a tiny min_improvement would otherwise refuse an effect for a 1e-4 wobble there)
    other_signal_tolerance: float | None = None
    max_effects: int = 6
    alpha_time_constant: float = ALPHA_TIME_CONSTANT  # [s]
    reference_temperature: float = REFERENCE_TEMPERATURE  # [degC] oil temperature at which the declared mu holds
    confidence: float = 0.95
    # every effect the analysis has a regressor for when the settings are made (an effect registered since counts)
    candidates: tuple[str, ...] = field(default_factory=lambda: tuple(EFFECTS))
    # refitted always, on top of the caller's free list (free.STANDARD_REFIT: why these)
    refit: tuple[str, ...] = STANDARD_REFIT
    # held-out RMS above this multiple of the noise floor: an unexplained residual is reported
    unexplained_factor: float = 1.3
    # held-out RMS of the current within this multiple of its noise floor: no further current effect is
    # added, and one whose removal stays within it is dropped (its share is below ~half the noise)
    at_floor: float = 1.1
    bootstrap: int = 400  # block-bootstrap resamples for the intervals of unique contributions
    # analysis step 5: above unexplained_factor x the floor, a named current effect must also earn its keep beside a
    # generic description of the residual (off: every accepted effect stays, e.g. for a model an estimator inverts)
    check_outside_vocabulary: bool = True

    def for_rig(self, rig: Rig) -> "Settings":
        """These settings with what they leave to the rig (``min_speed``) taken from ``rig``."""
        return self if self.min_speed is not None else replace(self, min_speed=kinetic_speed(rig))

    @property
    def other_tolerance(self) -> float:
        """The other signal's allowed relative rise: other_signal_tolerance, or min_improvement when None."""
        return self.min_improvement if self.other_signal_tolerance is None else self.other_signal_tolerance


