"""What every regressor of the residual analysis is: the protocol, the shapes, the coefficients, the shared helpers.

An effect adds to the model's channels (:data:`worm_model.residuals.model.CHANNELS`: mu,
mu_relative, worm_torque, gear_torque, worm_inertia, gear_inertia, current_gain,
current) a sum of *shapes*, one column per linear coefficient:
``channel += shapes[channel] @ values``.  Its regressors (current per unit coefficient
[A/unit]) are those shapes times the model's sensitivity of the current to each channel
(:func:`regressors`), so one declaration gives both the exact extended model and the
linear screening.  Parameters an effect is not linear in (a time constant, a harmonic
order, a Stribeck speed, a drag exponent, a PWM sampling phase) are *grid parameters*: the analysis tries
every grid value with linear least squares inside.

Signs: fixed frame; the worm_torque and gear_torque channels are extra torques the drive
has to overcome (+ opposes + rotation, as tau_load).  Angles: theta_worm, and theta_gear
worm-referenced (+ with + worm rotation).

A regressor is the residual analysis's face of an effect the vocabulary declares (worm_model.effects):
its name is the declared one, a coefficient that *is* a declared parameter takes its unit and meaning
from there (:meth:`Coefficient.of`), and :meth:`Effect.simulator_entry` / :meth:`Effect.from_simulator_entry`
translate fitted values to and from the declared parameters (an entry of an ``effects:`` section; there, a
worm-shaft torque is a magnitude that *drives* when +: the sign is flipped in the translation).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, TypeVar, runtime_checkable

import numpy as np

from worm_model.effects import VOCABULARY, implement
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.model import CHANNELS, Channels, ModelState, Signals, sensitivities

#: the residual analysis's face in worm_model.effects' registry
FACE = "residuals"

#: Shapes: channel -> (n, number of parameters); a parameter's column is zero in the
#: channels it does not touch (channels an effect never touches are left out).
Shapes = dict[str, FloatArray]


@dataclass(frozen=True)
class Coefficient:
    """A coefficient the effect is linear in (a declared parameter, or a part of one: a sine part)."""

    name: str
    unit: str
    description: str = ""

    @classmethod
    def of(cls, effect: str, key: str) -> "Coefficient":
        """The declared parameter ``key`` of ``effect`` as a coefficient: its name, unit and meaning."""
        declared = VOCABULARY[effect].parameters[key]
        return cls(key, declared.unit, declared.doc)


@dataclass(frozen=True)
class GridParameter(Coefficient):
    """A parameter searched on a grid (the effect is nonlinear in it): name, unit, meaning as a coefficient's."""


@runtime_checkable
class Effect(Protocol):
    """What every candidate effect provides."""

    name: str  # the declared effect's name (worm_model.effects.VOCABULARY)
    family: str  # "periodic" (angle spectrum), "regression", "thermal" (first-order drift)
    fitted_signal: str  # "current_drive" (channels, shapes) or "transmission_error" (te_columns)
    description: str
    parameters: tuple[Coefficient, ...]
    grid_parameters: tuple[GridParameter, ...]

    def grid(self, rig: Rig, signals: Signals) -> list[dict[str, float]]:
        """Grid values to try ([{}] if the effect has no grid parameter)."""

    def unavailable(self, rig: Rig, signals: Signals) -> str | None:
        """Why the data cannot show this effect (None if it can)."""

    def shapes(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> Shapes:
        """channel -> (n, len(parameters)): channel contribution per unit of each parameter."""

    def te_columns(self, rig: Rig, signals: Signals, state: ModelState, grid: Mapping[str, float]) -> FloatArray:
        """(n, len(parameters)) transmission error [rad] per unit of each parameter (fitted_signal
        "transmission_error" only), at the model state ``state``."""

    def signature(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> tuple[str, FloatArray]:
        """(axis label, per-sample values) to plot the residual against."""

    def simulator_entry(self, values: Mapping[str, float], grid: Mapping[str, float]) -> dict[str, float]:
        """The effect's entry of an ``effects:`` section (simulator's names, units and signs)."""

    def from_simulator_entry(self, entry: Mapping[str, Any], rig: Rig) -> tuple[dict[str, float], dict[str, float]]:
        """Inverse of :meth:`simulator_entry`: (values, grid); ``rig`` gives geometry (Z_g)."""


def _column(n: int, p: int, j: int, x: FloatArray) -> FloatArray:
    out = np.zeros((n, p))
    out[:, j] = x
    return out


def _sigma(signals: Signals) -> FloatArray:
    return np.where(signals.omega < 0.0, -1.0, 1.0)


def mesh_load(rig: Rig, signals: Signals) -> FloatArray:
    """|tau_load + declared gear-side drag| [N m]: the torque the mesh carries on the gear side."""
    return np.abs(gear_side_load(rig, signals.tau_load, signals.omega))


class _Base:
    """Shared plumbing: no grid, always available."""

    name: ClassVar[str]
    family: ClassVar[str] = "regression"
    fitted_signal: ClassVar[str] = "current_drive"
    description: ClassVar[str] = ""
    parameters: ClassVar[tuple[Coefficient, ...]] = ()
    grid_parameters: ClassVar[tuple[GridParameter, ...]] = ()

    def grid(self, rig: Rig, signals: Signals) -> list[dict[str, float]]:
        return [{}]

    def unavailable(self, rig: Rig, signals: Signals) -> str | None:
        return None

    def te_columns(self, rig: Rig, signals: Signals, state: ModelState, grid: Mapping[str, float]) -> FloatArray:
        raise NotImplementedError(f"{self.name} acts on the current, not on the transmission error")

    def signature(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> tuple[str, FloatArray]:
        return "omega_worm [rad/s]", signals.omega

    def simulator_entry(self, values: Mapping[str, float], grid: Mapping[str, float]) -> dict[str, float]:
        return {p.name: float(values[p.name]) for p in self.parameters}

    def from_simulator_entry(self, entry: Mapping[str, Any], rig: Rig) -> tuple[dict[str, float], dict[str, float]]:
        return {p.name: float(entry.get(p.name, 0.0)) for p in self.parameters}, {}


Regressor = TypeVar("Regressor", bound=type)


def regresses(cls: Regressor) -> Regressor:
    """Class decorator: an instance of ``cls`` is the analysis's regressor of the declared effect ``cls.name``."""
    implement(FACE, cls.name, cls())
    return cls


# --------------------------------------------------------------------------- helpers used by the analysis
def channels_of(effects: Sequence[tuple[Effect, Mapping[str, float], Mapping[str, float]]],
                rig: Rig, signals: Signals, shapes: Sequence[Shapes] | None = None) -> Channels:
    """Channel contributions of fitted effects: [(effect, values, grid), ...]."""
    ch = Channels()
    for k, (effect, values, grid) in enumerate(effects):
        sh = shapes[k] if shapes is not None else effect.shapes(rig, signals, grid)
        v = np.array([values[p.name] for p in effect.parameters])
        for channel, cols in sh.items():
            ch.add(channel, cols @ v)
    return ch


def regressors(effect: Effect, rig: Rig, signals: Signals, state: ModelState, shapes: Shapes,
               sens: Mapping[str, FloatArray] | None = None) -> FloatArray:
    """(n, p) d current / d parameter [A per parameter unit] at the model state (sens: precomputed sensitivities)."""
    sens = sens if sens is not None else sensitivities(rig, signals, state)
    total = np.zeros((len(signals), len(effect.parameters)))
    for channel, cols in shapes.items():
        total += sens[channel][:, None] * cols
    return total


def mask_shapes(shapes: Shapes, mask: np.ndarray) -> Shapes:
    return {k: v[mask] for k, v in shapes.items()}


assert all(c in CHANNELS for c in ("mu_relative", "worm_torque", "gear_torque", "current_gain", "current"))
