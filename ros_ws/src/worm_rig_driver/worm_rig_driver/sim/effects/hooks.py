"""The simulator's face of an effect: the shaft state and sensing context it sees, the protocol, the base class.

An effect implements only the hooks it changes (:data:`HOOKS`; the package's map lists them); each hook that
runs every step has a float twin for the scalar path (:data:`FLOAT_SHAFT`).  Its name, summary and parameters
are the vocabulary's (worm_model.effects): a hook class names a declared effect and is attached to it with
:func:`simulates`.  Signs: the package's docstring.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar, Protocol, TypeVar, runtime_checkable

import numpy as np

from worm_model.effects import VOCABULARY, implement
from worm_model.physics.parameters import Rig

#: the simulator's face in worm_model.effects' registry
FACE = "simulator"


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

    name: ClassVar[str]  # the vocabulary's name of the effect
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
        params: every parameter the vocabulary declares for ``name``, in its declared unit (an effect
            the vocabulary does not know takes none: a test's effect outside the vocabulary).
        n: number of rigs simulated side by side (size of any state the effect keeps).
        rig: the rig's parameters (geometry an effect needs: ratio, teeth, inductance).
    """

    name: ClassVar[str] = ""
    dissipative: ClassVar[bool] = False  # its shaft torques turn work into heat inside the gearbox

    def __init__(self, params: Mapping[str, float], n: int, rig: Rig) -> None:
        declared = VOCABULARY[self.name].parameters if self.name in VOCABULARY else {}
        self.p = {key: float(params[key]) for key in declared}
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


Hooks = TypeVar("Hooks", bound=type[EffectBase])


def simulates(cls: Hooks) -> Hooks:
    """Class decorator: ``cls`` is the simulator's hooks of the declared effect ``cls.name`` (registry.EFFECTS)."""
    implement(FACE, cls.name, cls)
    return cls


def _ripple(amplitude: float, load_fraction: float, load, sine):
    """(amplitude + load_fraction * load) * sine: a load-dependent ripple; floats or arrays (sine given)."""
    return (amplitude + load_fraction * load) * sine
