"""The simulator's effect hooks: how an effect declares its parameters (units, checks), the shaft state and
sensing context it sees, the protocol, the base class.

An effect implements only the hooks it changes (:data:`HOOKS`; the package's map lists them); each hook that
runs every step has a float twin for the scalar path (:data:`FLOAT_SHAFT`).  Signs: the package's docstring.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from worm_model.physics.parameters import Rig

# --- parameters and their units ------------------------------------------------------------------

#: unit accepted in an effects file -> (factor to the parameter's unit, that unit)
UNITS: dict[str, tuple[float, str]] = {
    "N m": (1.0, "N m"), "mN m": (1e-3, "N m"),
    "rad": (1.0, "rad"), "deg": (math.pi / 180.0, "rad"), "arcmin": (math.pi / 10800.0, "rad"),
    "rad/s": (1.0, "rad/s"), "rpm": (math.pi / 30.0, "rad/s"),
    "m/s": (1.0, "m/s"),
    "A": (1.0, "A"), "mA": (1e-3, "A"),
    "s": (1.0, "s"), "min": (60.0, "s"),
    "h": (1.0, "h"),  # a gearbox's age (hours run): the aging effects
    "Hz": (1.0, "Hz"), "kHz": (1e3, "Hz"),
    "degC": (1.0, "degC"),
    "K/W": (1.0, "K/W"),
    "1/K": (1.0, "1/K"),
    "1": (1.0, "1"), "%": (0.01, "1"),
}

#: largest magnitude an effect parameter of each unit may have: far beyond what a bench rig like this one
#: shows (its motors make ~1 N m, turn at ~400 rad/s, draw ~10 A), so only typos and overflows are refused
PLAUSIBLE: dict[str, float] = {
    "N m": 100.0, "rad": 2 * math.pi, "rad/s": 1e4, "m/s": 100.0, "A": 100.0, "s": 1e6, "Hz": 1e5,
    "degC": 300.0, "K/W": 1e3, "1/K": 1.0, "h": 1e6, "1": 1e6,  # "1" holds counts too (PWM levels, orders)
}

#: range check name -> (predicate, message)
CHECKS: dict[str, tuple[Any, str]] = {
    "any": (lambda x: True, ""),
    "nonnegative": (lambda x: x >= 0.0, "must be >= 0"),
    "positive": (lambda x: x > 0.0, "must be > 0"),
    # a relative change or error: above +1000 % is a slip (a percentage written as a fraction, a unit), not a gearbox
    "relative": (lambda x: -1.0 < x <= 10.0, "must be > -1 and <= 10 (a relative change, -100 % .. +1000 %)"),
    "count": (lambda x: x >= 1 and float(x).is_integer(), "must be an integer >= 1"),
    "count0": (lambda x: x >= 0 and float(x).is_integer(), "must be an integer >= 0"),
}


@dataclass(frozen=True)
class Parameter:
    """Declaration of one effect parameter: default (in ``unit``), unit, meaning, range check."""

    default: float
    unit: str
    doc: str
    check: str = "any"


@dataclass
class ShaftState:
    """What an effect's torque or friction may depend on; arrays of shape (n,), SI.

    See the module docstring for the signs. mesh_load is the magnitude of the torque
    the mesh carries on the gear side (load + load-motor drag) [N m], 0 while the
    teeth are apart in the backlash.
    """

    omega_worm: np.ndarray  # [rad/s]
    theta_worm: np.ndarray  # [rad]
    omega_gear: np.ndarray  # [rad/s]
    theta_gear: np.ndarray  # [rad]
    current_drive: np.ndarray  # [A]
    mesh_load: np.ndarray  # [N m] >= 0


@dataclass
class SenseContext:
    """When and under what drive the sensors read: for effects on the analogue signals."""

    channel_time: Mapping[str, float]  # [s] sim time at which each channel is sampled
    voltage_drive: np.ndarray  # [V] average voltage the H-bridge applied
    supply_voltage: float  # [V]


#: analogue channels an effect may change in sense(); values before the ADC, in SI
SIGNALS = ("current_drive", "current_load_1", "current_load_2", "tacho_drive", "tacho_load_1", "tacho_load_2")


@runtime_checkable
class Effect(Protocol):
    """One effect the model lacks. Implement only the hooks that the effect changes."""

    name: ClassVar[str]
    summary: ClassVar[str]
    parameters: ClassVar[Mapping[str, Parameter]]
    dissipative: ClassVar[bool]  # its shaft torques turn work into heat inside the gearbox

    def worm_torque(self, s: ShaftState) -> np.ndarray: ...
    def gear_torque(self, s: ShaftState) -> np.ndarray: ...
    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray: ...
    def inertia(self, worm: float, gear: float) -> tuple[float, float]: ...
    def backlash(self) -> float: ...
    def drive_voltage(self, voltage: np.ndarray, supply: float) -> np.ndarray: ...
    def advance(self, dt: float, heat: np.ndarray) -> None: ...
    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None: ...
    def observe(self) -> dict[str, np.ndarray]: ...


HOOKS = ("worm_torque", "gear_torque", "friction", "inertia", "backlash", "drive_voltage", "advance", "sense",
         "observe")

#: the float twins' shaft state, ShaftState's fields as positional floats in this order:
#: worm_torque_float(omega_worm, theta_worm, omega_gear, theta_gear, current_drive, mesh_load) -> float,
#: gear_torque_float(same) -> float, friction_float(mu, v_sliding, same) -> float,
#: drive_voltage_float(voltage, supply) -> float, advance_float(dt, heat) -> None, and
#: sense_float(signals: dict of floats, context with a float voltage_drive) -> None.
FLOAT_SHAFT = ("omega_worm", "theta_worm", "omega_gear", "theta_gear", "current_drive", "mesh_load")


def _sign(x: float) -> float:
    """np.sign of one float (NaN -> 0.0 rather than NaN: a diverged plant is reported elsewhere)."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


class EffectBase:
    """Identity implementation of every hook; an effect overrides the ones it changes.

    Args:
        params: every declared parameter, in its declared unit (see :data:`UNITS`).
        n: number of rigs simulated side by side (size of any state the effect keeps).
        rig: the rig's parameters (geometry an effect needs: ratio, teeth, inductance).
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    parameters: ClassVar[Mapping[str, Parameter]] = {}
    dissipative: ClassVar[bool] = False

    def __init__(self, params: Mapping[str, float], n: int, rig: Rig) -> None:
        self.p = {key: float(params[key]) for key in self.parameters}
        self.n = n
        self.rig = rig

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return np.zeros(self.n)

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return np.zeros(self.n)

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu

    def inertia(self, worm: float, gear: float) -> tuple[float, float]:
        return worm, gear

    def backlash(self) -> float:
        return 0.0

    def drive_voltage(self, voltage: np.ndarray, supply: float) -> np.ndarray:
        return voltage

    def advance(self, dt: float, heat: np.ndarray) -> None:
        return None

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        return None

    def observe(self) -> dict[str, np.ndarray]:
        return {}

    # float twins (module docstring): None = not provided; an effect defines those of the hooks it changes
    worm_torque_float = gear_torque_float = friction_float = drive_voltage_float = None
    advance_float = sense_float = None

    @classmethod
    def hooks(cls) -> frozenset[str]:
        """The hooks this effect overrides: what it changes in the simulator."""
        return frozenset(h for h in HOOKS if getattr(cls, h) is not getattr(EffectBase, h))


def _ripple(amplitude: float, load_fraction: float, load, sine):
    """(amplitude + load_fraction * load) * sine: a load-dependent ripple; floats or arrays (sine given)."""
    return (amplitude + load_fraction * load) * sine
