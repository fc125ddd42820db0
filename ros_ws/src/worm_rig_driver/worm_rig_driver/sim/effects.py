"""Effects the paper's model lacks (physics.md section 9), and the gearbox's aging, as plug-ins of the simulator.

Each effect is a small class behind one protocol (:class:`Effect`) and is found by
its name in the registry :data:`EFFECTS` (the way rosbags finds storage plug-ins in
``STORAGE_PLUGINS``). An effect declares its parameters (unit, default, meaning)
and implements only the hooks it needs:

  worm_torque   extra torque on the worm shaft, a function of the shaft state
  gear_torque   extra torque on the gear shaft
  friction      a modified mesh friction coefficient mu
  inertia       the true shaft inertias (they differ from the rig file's)
  backlash      the gear-side clearance of the mesh (the plant's dead zone)
  drive_voltage what the H-bridge really applies for a requested voltage
  advance       its own state (oil temperature) over one step
  sense         what the sensors read (gain, offset, PWM ripple), before the ADC
  observe       its own state, for the ground truth

Float twins (the scalar fast path for one rig, sim/scalar_plant.py): the hooks
that run every step have a twin ``<hook>_float`` taking and returning plain floats
(shaft state as six positional floats, see :data:`FLOAT_SHAFT`), computed with the
same floating-point operations as the array hook, so that both paths agree to
round-off. An effect without the twin of a hook it changes still works: the
simulator then steps that rig with the vectorised plant (scalar_plant.float_hooks_missing).

Aging (``wear``, ``lubricant_loss``, ``seal_drag``): effects that evolve over the gearbox's life
(hours run) or step at a given rig time, so that a health monitor is measured on runs whose truth
is known. At their defaults they leave the gearbox as new.

The simulator switches effects on from a YAML file (:func:`load_effects`); the
model (worm_model) is not told: the effects are *undeclared*, the test bed for
closing the loop between model and measurements.

Conventions (those of plant.py; SI units, angles in rad):
  * worm quantities in the fixed frame, + along + worm rotation;
  * gear quantities about the gear's own axis but worm-referenced: + is the gear
    rotation that goes with + worm rotation, so omega_gear = ratio * omega_worm
    in contact; theta_gear is the gear's own angle;
  * worm_torque: + drives + worm rotation (a drag is -c sign(omega_worm));
  * gear_torque: + OPPOSES + gear rotation, like the load torque tau_load (a drag
    is +c sign(omega_gear)).

File format ``worm_rig_effects``
--------------------------------
version 1 (current)::

    format: worm_rig_effects
    version: 1
    effects:
      tooth_pass: {load_fraction: 0.05}          # plain number: the parameter's own unit
      backlash: {angle: {value: 15, unit: arcmin}}
      oil_temperature: {}                        # every parameter at its default
      sensor_gain: {enabled: false}              # listed but off

The same ``effects`` section may also sit in a ``worm_rig_parameters`` file
(worm_model's rig file, which skips it); :func:`load_effects` reads it from either.
Every failure raises :class:`EffectsError`, whose message names the file and the key.
"""
from __future__ import annotations

import math
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from worm_model.cli.errors import run_tool
from worm_model.errors import InputError
from worm_model.cli.options import Parser, existing_file, output_path
from worm_model.files.reading import load_yaml
from worm_model.files.writing import Output, atomic_file, check_output
from worm_model.physics.parameters import Rig, finite_number

import worm_rig_driver.protocol.table as protocol_table
from worm_rig_driver.errors import EffectsError

FORMAT_NAME = "worm_rig_effects"
FORMAT_VERSION = 1
#: a rig parameter file (worm_model.physics.parameters) may carry an ``effects`` section too
RIG_FORMAT_NAME = "worm_rig_parameters"


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


# --- the effects -----------------------------------------------------------------------------------

class BearingCoulomb(EffectBase):
    """Coulomb drag of the bearings and lip seals of the worm and gear shafts.

    Worm: -worm_torque sign(omega_worm); gear: +gear_torque sign(omega_gear) (a drag).
    At rest it is static friction up to the same torque (the plant's breakaway test).
    Residual signature: a step with sign(omega), independent of the load.
    """

    name = "bearing_coulomb"
    summary = "bearing and seal Coulomb drag on the worm and gear shafts"
    dissipative = True
    parameters = {
        "worm_torque": Parameter(3e-3, "N m", "Coulomb drag on the worm shaft (assumption: two ball bearings "
                                 "and a 15 mm lip seal, a few mN m)", "nonnegative"),
        "gear_torque": Parameter(15e-3, "N m", "Coulomb drag on the gear shaft (assumption: two 14 mm lip "
                                 "seals and the output bearings)", "nonnegative"),
    }

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -self.p["worm_torque"] * np.sign(s.omega_worm)

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return self.p["gear_torque"] * np.sign(s.omega_gear)

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -self.p["worm_torque"] * _sign(omega_worm)

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return self.p["gear_torque"] * _sign(omega_gear)


class ViscousDrag(EffectBase):
    """Viscous and oil-churning drag: T(omega) = T_ref (|omega| / omega_ref)^exponent sign(omega).

    Both shafts are referred to the same worm speed: the gear term is evaluated at
    the worm speed that goes with the gear's speed (omega_gear / ratio).
    Residual signature: linear (exponent 1) or ~|omega|^0.5..1 (churning).
    """

    name = "viscous_drag"
    summary = "viscous and oil-churning drag on the worm and gear shafts"
    dissipative = True
    parameters = {
        "worm_torque": Parameter(3e-3, "N m", "drag on the worm shaft at the reference speed (assumption: "
                                 "splash-lubricated worm, ~1 W at 300 rad/s)", "nonnegative"),
        "gear_torque": Parameter(10e-3, "N m", "drag on the gear shaft at the reference worm speed "
                                 "(assumption: wheel churning in the oil bath)", "nonnegative"),
        "reference_speed": Parameter(300.0, "rad/s", "worm speed at which the torques above are reached",
                                     "positive"),
        "exponent": Parameter(1.0, "1", "speed exponent: 1 viscous, 0.5..1 churning", "nonnegative"),
    }

    def _law(self, torque: float, worm_speed: np.ndarray) -> np.ndarray:
        x = np.abs(worm_speed) / self.p["reference_speed"]
        return torque * np.sign(worm_speed) * (x if self.p["exponent"] == 1.0 else x ** self.p["exponent"])

    def _law_float(self, torque: float, worm_speed: float) -> float:
        x = abs(worm_speed) / self.p["reference_speed"]
        return torque * _sign(worm_speed) * (x if self.p["exponent"] == 1.0 else x ** self.p["exponent"])

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -self._law(self.p["worm_torque"], s.omega_worm)

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return self._law(self.p["gear_torque"], s.omega_gear / self.rig.gearbox.ratio)

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -self._law_float(self.p["worm_torque"], omega_worm)

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return self._law_float(self.p["gear_torque"], omega_gear / self.rig.gearbox.ratio)


class SpeedDependentMu(EffectBase):
    """Mesh friction rising at low sliding speed (Stribeck / EHL film build-up), on top of the rig's law.

    mu = mu_rig(V_s) * (1 + low_speed_gain * exp(-V_s / stribeck_speed)), V_s the
    sliding speed at the pitch point. Residual signature: mu falling with sliding
    speed, rising sharply at low speed.
    """

    name = "speed_dependent_mu"
    summary = "mesh mu rising at low sliding speed (Stribeck), beyond the model's mu law"
    parameters = {
        "low_speed_gain": Parameter(0.5, "1", "relative increase of mu as the sliding speed goes to 0 "
                                    "(assumption: boundary vs. EHL friction of bronze on steel)", "relative"),
        "stribeck_speed": Parameter(0.3, "m/s", "sliding speed over which the increase decays "
                                    "(assumption: 0.3 m/s ~ 40 rad/s worm speed on the bundled rig)", "positive"),
    }

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu * (1.0 + self.p["low_speed_gain"] * np.exp(-v_sliding / self.p["stribeck_speed"]))

    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        return mu * (1.0 + self.p["low_speed_gain"] * math.exp(-v_sliding / self.p["stribeck_speed"]))


class LoadDependentMu(EffectBase):
    """Mesh friction that depends on the load the mesh carries.

    mu = mu_rig * max(0.1, 1 + sensitivity * mesh_load / reference_torque), mesh_load
    the gear-side torque the mesh carries [N m]. Residual signature: a slope change with tau_d.
    """

    name = "load_dependent_mu"
    summary = "mesh mu changing with the transmitted load"
    parameters = {
        "sensitivity": Parameter(-0.15, "1", "relative change of mu at the reference torque (assumption: mu "
                                 "falls as the load grows, as the paper's Fig. 9 shows)"),
        "reference_torque": Parameter(0.25, "N m", "gear-side torque at which the change is `sensitivity`",
                                      "positive"),
    }

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        factor = 1.0 + self.p["sensitivity"] * s.mesh_load / self.p["reference_torque"]
        return mu * np.maximum(factor, 0.1)

    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        factor = 1.0 + self.p["sensitivity"] * mesh_load / self.p["reference_torque"]
        return mu * (0.1 if factor < 0.1 else factor)  # np.maximum(factor, 0.1), NaN kept


class OilTemperature(EffectBase):
    """Oil temperature with a thermal time constant, and mu that follows it.

    First-order thermal model of the housing: C dT/dt = P - (T - T_amb)/R_th with
    C = time_constant / thermal_resistance, P the heat made inside the gearbox (mesh
    friction and the dissipative shaft effects) [W]. The mesh mu is scaled by
    max(0.1, 1 + mu_per_kelvin (T - ambient)): the model's mu is the one at ambient.
    Residual signature: a slow drift over minutes at a constant operating point.
    """

    name = "oil_temperature"
    summary = "oil temperature (first order, thermal time constant) scaling the mesh mu"
    parameters = {
        "ambient": Parameter(25.0, "degC", "ambient temperature; the model's mu holds there (assumption: lab)"),
        "initial": Parameter(25.0, "degC", "oil temperature at the start of the run"),
        "thermal_resistance": Parameter(5.0, "K/W", "housing to ambient (assumption: ~0.2 W/K for a small "
                                        "aluminium housing in still air)", "positive"),
        "time_constant": Parameter(900.0, "s", "thermal time constant R_th C (assumption: ~15 min)", "positive"),
        "mu_per_kelvin": Parameter(-0.003, "1/K", "relative change of mu per kelvin (assumption: thinner, "
                                   "hotter oil lowers the viscous part of the mesh friction)"),
    }

    def __init__(self, params: Mapping[str, float], n: int, rig: Rig) -> None:
        super().__init__(params, n, rig)
        self.temperature = np.full(n, self.p["initial"])

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu * np.maximum(1.0 + self.p["mu_per_kelvin"] * (self.temperature - self.p["ambient"]), 0.1)

    def advance(self, dt: float, heat: np.ndarray) -> None:
        # exact for P held over dt: T -> T_ss + (T - T_ss) exp(-dt / tau)
        steady = self.p["ambient"] + self.p["thermal_resistance"] * heat
        self.temperature = steady + (self.temperature - steady) * math.exp(-dt / self.p["time_constant"])

    # (n = 1: the temperature stays a (1,) array, written in place, so that observe() is unchanged)
    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        factor = 1.0 + self.p["mu_per_kelvin"] * (float(self.temperature[0]) - self.p["ambient"])
        return mu * (0.1 if factor < 0.1 else factor)

    def advance_float(self, dt: float, heat: float) -> None:
        steady = self.p["ambient"] + self.p["thermal_resistance"] * heat
        self.temperature[0] = steady + (float(self.temperature[0]) - steady) * math.exp(-dt / self.p["time_constant"])

    def observe(self) -> dict[str, np.ndarray]:
        return {"oil_temperature": self.temperature.copy()}


class WormRunout(EffectBase):
    """Worm eccentricity / coupling misalignment: a torque ripple once per worm turn.

    Worm torque -(amplitude + load_fraction * ratio * mesh_load) sin(theta_worm + phase):
    a constant part plus a part proportional to the mesh torque at the worm
    (eccentricity changes the lever arm of the mesh force).
    Residual signature: periodic in worm angle, once per worm turn.
    """

    name = "worm_runout"
    summary = "torque ripple once per worm turn (eccentricity, misalignment)"
    parameters = {
        "amplitude": Parameter(1e-3, "N m", "load-independent ripple amplitude on the worm shaft (assumption)",
                               "nonnegative"),
        "load_fraction": Parameter(0.02, "1", "ripple amplitude per unit of mesh torque at the worm "
                                   "(assumption: ~2 %, eccentricity + misalignment)", "nonnegative"),
        "phase": Parameter(0.0, "rad", "angle of the ripple's zero crossing on the worm"),
    }

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -_ripple(self.p["amplitude"], self.p["load_fraction"], self.rig.gearbox.ratio * s.mesh_load,
                        np.sin(s.theta_worm + self.p["phase"]))

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -_ripple(self.p["amplitude"], self.p["load_fraction"], self.rig.gearbox.ratio * mesh_load,
                        math.sin(theta_worm + self.p["phase"]))


class ToothPass(EffectBase):
    """Mesh (tooth-pass) ripple: a gear-side torque ripple at the tooth-pass order.

    Gear torque (amplitude + load_fraction * mesh_load) sin(Z_g theta_gear + phase):
    Z_g per gear turn, i.e. n (worm starts) per worm turn.
    Residual signature: periodic in worm angle, n per worm turn.
    """

    name = "tooth_pass"
    summary = "mesh ripple at the tooth-pass order (Z_g per gear turn = n per worm turn)"
    parameters = {
        "amplitude": Parameter(5e-3, "N m", "load-independent ripple amplitude on the gear shaft (assumption)",
                               "nonnegative"),
        "load_fraction": Parameter(0.03, "1", "ripple amplitude per unit of mesh load (assumption: mesh "
                                   "stiffness variation of a few %)", "nonnegative"),
        "phase": Parameter(0.0, "rad", "phase of the ripple at theta_gear = 0"),
    }

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], s.mesh_load,
                       np.sin(self.rig.gearbox.gear_teeth * s.theta_gear + self.p["phase"]))

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], mesh_load,
                       math.sin(self.rig.gearbox.gear_teeth * theta_gear + self.p["phase"]))


class GearRunout(EffectBase):
    """Gear (wheel) eccentricity: a gear-side torque ripple once per gear turn.

    Gear torque (amplitude + load_fraction * mesh_load) sin(theta_gear + phase).
    Residual signature: periodic in gear angle, once per gear turn.
    """

    name = "gear_runout"
    summary = "torque ripple once per gear turn (wheel eccentricity)"
    parameters = {
        "amplitude": Parameter(10e-3, "N m", "load-independent ripple amplitude on the gear shaft (assumption)",
                               "nonnegative"),
        "load_fraction": Parameter(0.03, "1", "ripple amplitude per unit of mesh load (assumption)",
                                   "nonnegative"),
        "phase": Parameter(0.0, "rad", "phase of the ripple at theta_gear = 0"),
    }

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], s.mesh_load,
                       np.sin(s.theta_gear + self.p["phase"]))

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], mesh_load, math.sin(theta_gear + self.p["phase"]))


class MotorCogging(EffectBase):
    """Cogging of the drive motor: a torque periodic in the motor (= worm) angle.

    Worm torque -amplitude sin(order theta_worm + phase); order = LCM(poles, slots)
    cycles per turn. Conservative (zero work per turn), and a detent at rest.
    Residual signature: periodic in motor angle, `order` per turn.
    """

    name = "motor_cogging"
    summary = "drive-motor cogging torque, `order` cycles per motor turn"
    parameters = {
        "amplitude": Parameter(2e-3, "N m", "cogging torque amplitude (assumption: ~1.5 % of the rated "
                               "0.14 N m of a brushed servo)", "nonnegative"),
        "order": Parameter(14, "1", "cogging cycles per turn (assumption: 2 poles, 7 slots -> LCM 14)", "count"),
        "phase": Parameter(0.0, "rad", "phase at theta_worm = 0"),
    }

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -self.p["amplitude"] * np.sin(self.p["order"] * s.theta_worm + self.p["phase"])

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -self.p["amplitude"] * math.sin(self.p["order"] * theta_worm + self.p["phase"])


class Backlash(EffectBase):
    """Clearance between thread and teeth: the mesh becomes a dead zone of this width.

    When the mesh force changes sign (a flank change: resistive <-> assistive load,
    or a reversal with little load) the contact crosses the gap: worm and gear move
    apart, each under its own torques, until the other flank is hit (a perfectly
    inelastic impact). Residual signature: dead time and a current spike at each
    flank change. The plant implements the dead zone; this effect sets its width.
    """

    name = "backlash"
    summary = "mesh clearance: a dead zone crossed at each flank change"
    parameters = {
        "angle": Parameter(math.radians(15.0 / 60.0), "rad", "circumferential clearance at the gear (output) "
                           "shaft (assumption: 15 arcmin, the order catalogues give for small worm gearboxes)",
                           "nonnegative"),
    }

    def backlash(self) -> float:
        return self.p["angle"]


class SensorGain(EffectBase):
    """Gain errors of the Hall current sensors and tachogenerators: reading = (1 + gain) x true.

    Changes only the readings, never the plant. Residual signature: proportional to i (or omega).
    """

    name = "sensor_gain"
    summary = "gain error of the current sensors and tachos (readings only)"
    parameters = {
        "drive_current": Parameter(0.03, "1", "relative gain error of the drive current sensor (assumption: "
                                   "ACS712 sensitivity tolerance is a few %)", "relative"),
        "load_current": Parameter(0.02, "1", "relative gain error of both load current sensors", "relative"),
        "drive_tacho": Parameter(0.01, "1", "relative gain error of the drive tacho", "relative"),
        "load_tacho": Parameter(0.01, "1", "relative gain error of both load tachos", "relative"),
    }

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        for key, gain in (("current_drive", "drive_current"), ("current_load_1", "load_current"),
                          ("current_load_2", "load_current"), ("tacho_drive", "drive_tacho"),
                          ("tacho_load_1", "load_tacho"), ("tacho_load_2", "load_tacho")):
            signals[key] = signals[key] * (1.0 + self.p[gain])

    sense_float = sense  # plain arithmetic: the same code serves floats


class SensorOffset(EffectBase):
    """Zero offsets of the Hall current sensors and tachos: reading = true + offset.

    Changes only the readings, never the plant. Residual signature: a constant.
    """

    name = "sensor_offset"
    summary = "zero offset of the current sensors and tachos (readings only)"
    parameters = {
        "drive_current": Parameter(0.05, "A", "offset of the drive current sensor (assumption: ACS712 zero "
                                   "drift of ~10 mV / 185 mV/A)"),
        "load_current": Parameter(0.03, "A", "offset of both load current sensors"),
        "drive_tacho": Parameter(0.0, "rad/s", "offset of the drive tacho channel"),
        "load_tacho": Parameter(0.0, "rad/s", "offset of both load tacho channels"),
    }

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        for key, offset in (("current_drive", "drive_current"), ("current_load_1", "load_current"),
                            ("current_load_2", "load_current"), ("tacho_drive", "drive_tacho"),
                            ("tacho_load_1", "load_tacho"), ("tacho_load_2", "load_tacho")):
            signals[key] = signals[key] + self.p[offset]

    sense_float = sense  # plain arithmetic: the same code serves floats


class InertiaError(EffectBase):
    """The shafts' true inertias differ from the rig file's: J_true = (1 + error) J_file.

    Residual signature: proportional to the acceleration.
    """

    name = "inertia_error"
    summary = "true shaft inertias differ from the rig file's"
    parameters = {
        "worm": Parameter(0.2, "1", "relative error of the worm-shaft inertia (worm + motor rotor)", "relative"),
        "gear": Parameter(0.2, "1", "relative error of the gear-shaft inertia (gear + load rotors)", "relative"),
    }

    def inertia(self, worm: float, gear: float) -> tuple[float, float]:
        return worm * (1.0 + self.p["worm"]), gear * (1.0 + self.p["gear"])


class Pwm(EffectBase):
    """The H-bridge's PWM: duty quantised to the timer's levels, and the armature current ripple.

    The plant integrates the average-duty voltage: the PWM period (50 us) is 16x
    shorter than L/R (0.8 ms), so the mean current obeys Eq. 29 with V = duty x
    supply. What the average hides is (1) the duty resolution of the timer and
    (2) the triangular current ripple, peak to peak V_s d (1 - d) / (L f_pwm) for
    sign-magnitude PWM, which the ADC sees at whatever phase it samples (the ADC
    and PWM timers are not synchronised), reduced by the Hall sensor's output filter.
    """

    name = "pwm"
    summary = "H-bridge PWM: duty resolution and the current ripple the ADC samples"
    parameters = {
        "frequency": Parameter(protocol_table.F_CPU_HZ / (protocol_table.PWM_TOP + 1), "Hz",
                               "PWM frequency (the firmware's: 16 MHz / (PWM_TOP + 1) = 20 kHz)", "positive"),
        "duty_levels": Parameter(protocol_table.PWM_TOP + 1, "1", "duty steps from 0 to 100 % (the firmware's "
                                 "PWM_TOP + 1 = 800); 0 = continuous", "count0"),
        "filter_cutoff": Parameter(2000.0, "Hz", "first-order cut-off of the Hall sensor's output filter "
                                   "(assumption: ACS712 with C_F = 47 nF)", "positive"),
    }

    def drive_voltage(self, voltage: np.ndarray, supply: float) -> np.ndarray:
        levels = self.p["duty_levels"]
        if levels == 0:
            return voltage
        return np.round(voltage / supply * levels) / levels * supply

    def drive_voltage_float(self, voltage: float, supply: float) -> float:
        levels = self.p["duty_levels"]
        if levels == 0 or voltage != voltage:
            return voltage
        return round(voltage / supply * levels) / levels * supply  # (round: ties to even, as np.round)

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        f = self.p["frequency"]
        duty = np.clip(np.abs(context.voltage_drive) / context.supply_voltage, 0.0, 1.0)
        ripple_pp = context.supply_voltage * duty * (1.0 - duty) / (self.rig.drive_motor.inductance * f)
        attenuation = 1.0 / math.sqrt(1.0 + (f / self.p["filter_cutoff"]) ** 2)
        phase = (context.channel_time["current_drive"] * f) % 1.0
        rising = phase < duty  # switch on: the current rises for d/f, then falls
        with np.errstate(divide="ignore", invalid="ignore"):
            shape = np.where(rising, -0.5 + phase / duty, 0.5 - (phase - duty) / (1.0 - duty))
        shape = np.where((duty <= 0.0) | (duty >= 1.0), 0.0, shape)
        signals["current_drive"] = signals["current_drive"] + np.sign(context.voltage_drive) * attenuation \
            * ripple_pp * shape

    def sense_float(self, signals: dict[str, float], context: SenseContext) -> None:
        f = self.p["frequency"]
        duty = abs(context.voltage_drive) / context.supply_voltage
        duty = 0.0 if duty < 0.0 else (1.0 if duty > 1.0 else duty)
        if duty <= 0.0 or duty >= 1.0:
            return  # no ripple at 0 % or 100 % duty (signal + 0.0, as the array hook)
        ripple_pp = context.supply_voltage * duty * (1.0 - duty) / (self.rig.drive_motor.inductance * f)
        attenuation = 1.0 / math.sqrt(1.0 + (f / self.p["filter_cutoff"]) ** 2)
        phase = (context.channel_time["current_drive"] * f) % 1.0
        shape = -0.5 + phase / duty if phase < duty else 0.5 - (phase - duty) / (1.0 - duty)
        signals["current_drive"] = signals["current_drive"] + _sign(context.voltage_drive) * attenuation \
            * ripple_pp * shape


# --- aging: effects that evolve over a gearbox's life -----------------------------------------------------
# At their defaults these leave the gearbox as new (every hook returns its input bit for bit), so a
# configuration of "every effect at its default" is a new gearbox; their parameters say how it ages.

#: hours per second
_HOUR = 1.0 / 3600.0


class Wear(EffectBase):
    """Wear over the gearbox's life: the mesh mu, the shaft drags and the backlash grow with the hours run.

    Age h [h] = ``hours`` at the start of the run + ``time_factor`` x the rig time run since [h]
    (time_factor 0: the age is fixed over the run; 3600: an hour of wear per second).
    mu -> mu (1 + mu_rate h / 1000); the worm shaft gets an extra Coulomb drag
    -worm_drag_rate (h / 1000) sign(omega_worm), the gear shaft +gear_drag_rate (h / 1000) sign(omega_gear)
    (worn seal lips and bearings); the mesh clearance grows by backlash_rate h / 1000, added to the
    ``backlash`` effect's (the plant's dead zone is set when the simulator is built, so the clearance
    is the one at the start of the run, and the same for every rig of a vectorised simulator).

    ``hours`` is also the effect's state, an array over the rigs: a harness may set it per rig
    (``effect.hours[:] = ...``) to simulate rigs of different ages side by side.
    Residual signature: mu and drag rising slowly over checks weeks apart.
    """

    name = "wear"
    summary = "wear: mu, shaft drags and backlash rising with the hours run"
    dissipative = True
    parameters = {
        "hours": Parameter(0.0, "h", "age at the start of the run (0: new)", "nonnegative"),
        "time_factor": Parameter(0.0, "1", "hours of wear per hour of rig time (0: the age is fixed over the "
                                 "run; 3600: an hour per second)", "nonnegative"),
        "mu_rate": Parameter(0.05, "1", "relative rise of mu per 1000 h (assumption: a bronze wheel running in "
                             "and wearing, ~5 % per 1000 h)"),
        "worm_drag_rate": Parameter(1e-3, "N m", "rise of the worm shaft's Coulomb drag per 1000 h (assumption: "
                                    "a hardening input seal lip)", "nonnegative"),
        "gear_drag_rate": Parameter(2e-3, "N m", "rise of the gear shaft's Coulomb drag per 1000 h (assumption: "
                                    "output seals and bearings)", "nonnegative"),
        "backlash_rate": Parameter(math.radians(3.0 / 60.0), "rad", "growth of the clearance at the gear per "
                                   "1000 h (assumption: 3 arcmin per 1000 h of tooth wear)", "nonnegative"),
    }

    def __init__(self, params: Mapping[str, float], n: int, rig: Rig) -> None:
        super().__init__(params, n, rig)
        self.hours = np.full(n, self.p["hours"])

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu * (1.0 + self.p["mu_rate"] * (self.hours / 1000.0))

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -(self.p["worm_drag_rate"] * (self.hours / 1000.0)) * np.sign(s.omega_worm)

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return (self.p["gear_drag_rate"] * (self.hours / 1000.0)) * np.sign(s.omega_gear)

    def backlash(self) -> float:
        return self.p["backlash_rate"] * (self.p["hours"] / 1000.0)

    def advance(self, dt: float, heat: np.ndarray) -> None:
        if self.p["time_factor"]:
            self.hours = self.hours + self.p["time_factor"] * (dt * _HOUR)

    # (n = 1: the age stays a (1,) array, written in place)
    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        return mu * (1.0 + self.p["mu_rate"] * (float(self.hours[0]) / 1000.0))

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -(self.p["worm_drag_rate"] * (float(self.hours[0]) / 1000.0)) * _sign(omega_worm)

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return (self.p["gear_drag_rate"] * (float(self.hours[0]) / 1000.0)) * _sign(omega_gear)

    def advance_float(self, dt: float, heat: float) -> None:
        if self.p["time_factor"]:
            self.hours[0] = float(self.hours[0]) + self.p["time_factor"] * (dt * _HOUR)

    def observe(self) -> dict[str, np.ndarray]:
        return {"wear_hours": self.hours.copy()}


class _RigClock(EffectBase):
    """An effect that keeps the rig time since the start of the run [s] (the same for every rig)."""

    def __init__(self, params: Mapping[str, float], n: int, rig: Rig) -> None:
        super().__init__(params, n, rig)
        self.time = 0.0

    def advance(self, dt: float, heat: np.ndarray) -> None:
        self.time += dt

    def advance_float(self, dt: float, heat: float) -> None:
        self.time += dt

    def _onset(self, start: float, duration: float) -> float:
        """0 before ``start`` [s], then rising linearly to 1 over ``duration`` [s] (0: a step)."""
        if self.time < start:
            return 0.0
        return 1.0 if duration <= 0.0 or self.time >= start + duration else (self.time - start) / duration


class LubricantLoss(_RigClock):
    """Loss of lubricant (a leak, a starved mesh): mu steps up by ``rise`` at rig time ``at``.

    mu -> mu (1 + rise x ramp(t)), ramp 0 before ``at`` [s], then 1 (or rising linearly over
    ``duration`` [s]). At rise 0 (the default) the gearbox is healthy.
    Residual signature: a step in the friction torque, proportional to the mesh load.
    """

    name = "lubricant_loss"
    summary = "lubricant loss: mu stepping up at a given rig time"
    parameters = {
        "rise": Parameter(0.0, "1", "relative rise of mu after the loss (0: healthy; a starved mesh: 0.3)",
                          "relative"),
        "at": Parameter(0.0, "s", "rig time of the loss since the start of the run", "nonnegative"),
        "duration": Parameter(0.0, "s", "time over which mu rises to its new value (0: a step)", "nonnegative"),
    }

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu * (1.0 + self.p["rise"] * self._onset(self.p["at"], self.p["duration"]))

    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        return mu * (1.0 + self.p["rise"] * self._onset(self.p["at"], self.p["duration"]))


class SealDrag(_RigClock):
    """A seal starting to drag: Coulomb drag on the worm and gear shafts from rig time ``onset``.

    Worm: -worm_torque x ramp(t) sign(omega_worm); gear: +gear_torque x ramp(t) sign(omega_gear),
    ramp 0 before ``onset`` [s], rising linearly to 1 over ``growth`` [s] (0: at once). At its
    defaults (no torque) the seals are healthy.
    Residual signature: a sign(omega) step growing in, independent of the load.
    """

    name = "seal_drag"
    summary = "a seal starting to drag: Coulomb drag on the worm and gear shafts from a given rig time"
    dissipative = True
    parameters = {
        "worm_torque": Parameter(0.0, "N m", "extra Coulomb drag on the worm shaft (0: healthy; a dragging "
                                 "15 mm lip seal: a few mN m)", "nonnegative"),
        "gear_torque": Parameter(0.0, "N m", "extra Coulomb drag on the gear shaft (0: healthy)", "nonnegative"),
        "onset": Parameter(0.0, "s", "rig time at which the drag starts", "nonnegative"),
        "growth": Parameter(0.0, "s", "time over which the drag grows to its full value (0: at once)",
                            "nonnegative"),
    }

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -(self.p["worm_torque"] * self._onset(self.p["onset"], self.p["growth"])) * np.sign(s.omega_worm)

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return (self.p["gear_torque"] * self._onset(self.p["onset"], self.p["growth"])) * np.sign(s.omega_gear)

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -(self.p["worm_torque"] * self._onset(self.p["onset"], self.p["growth"])) * _sign(omega_worm)

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return (self.p["gear_torque"] * self._onset(self.p["onset"], self.p["growth"])) * _sign(omega_gear)


#: effect name -> class; the names are those of physics.md section 9 (plus the PWM), then the aging effects
EFFECTS: dict[str, type[EffectBase]] = {cls.name: cls for cls in (
    BearingCoulomb, ViscousDrag, SpeedDependentMu, LoadDependentMu, OilTemperature, WormRunout, ToothPass,
    GearRunout, MotorCogging, Backlash, SensorGain, SensorOffset, InertiaError, Pwm, Wear, LubricantLoss, SealDrag)}


# --- configuration ---------------------------------------------------------------------------------

def _parameter_value(raw: Any, declared: Parameter, origin: str, where: str) -> float:
    """A plain number (in the declared unit) or {value, unit[, note|source|assumption]}, checked."""
    if isinstance(raw, Mapping):
        unknown = set(raw) - {"value", "unit", "note", "source", "assumption"}
        if unknown or "value" not in raw:
            raise EffectsError(origin, where, "expected a number or a mapping {value, unit}"
                               + (f"; unknown keys {sorted(unknown)}" if unknown else ""))
        number = finite_number(raw["value"], origin, where, EffectsError)
        unit = str(raw.get("unit", declared.unit))
        if unit not in UNITS:
            raise EffectsError(origin, where, f"unknown unit {unit!r} (known: {', '.join(UNITS)})")
        factor, base = UNITS[unit]
        if base != declared.unit:
            raise EffectsError(origin, where, f"unit {unit!r} is not a {declared.unit!r}")
        number *= factor
    else:
        number = finite_number(raw, origin, where, EffectsError)
    predicate, message = CHECKS[declared.check]
    if not predicate(number):
        raise EffectsError(origin, where, f"value {number:g} {declared.unit}: {message}")
    limit = PLAUSIBLE[declared.unit]
    if abs(number) > limit:
        raise EffectsError(origin, where, f"value {number:g} {declared.unit} is far beyond any bench rig "
                                          f"(|value| <= {limit:g} {declared.unit})")
    return number


@dataclass(frozen=True)
class EffectsConfig:
    """Which effects are on, with every parameter in its declared unit (defaults filled in).

    Build one with :func:`load_effects`, :meth:`from_mapping` or :meth:`defaults`;
    :meth:`build` makes the live effects for a simulator of n rigs.
    """

    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    source: str = ""

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.effects)

    @classmethod
    def from_mapping(cls, effects: Mapping[str, Any] | None, origin: str = "<dict>") -> "EffectsConfig":
        """The ``effects`` section: effect name -> {parameter: value, ..., enabled: bool} (or null).

        Raises:
            EffectsError: unknown effect or parameter, bad value, unit or range.
        """
        if effects is None:
            return cls({}, origin)
        if not isinstance(effects, Mapping):
            raise EffectsError(origin, "effects", "expected a mapping effect name -> parameters")
        chosen: dict[str, dict[str, float]] = {}
        for name, section in effects.items():
            where = f"effects.{name}"
            if name not in EFFECTS:
                raise EffectsError(origin, where, f"unknown effect (known: {', '.join(EFFECTS)})")
            section = {} if section is None else section
            if not isinstance(section, Mapping):
                raise EffectsError(origin, where, "expected a mapping of parameters (or {} for the defaults)")
            enabled = section.get("enabled", True)
            if not isinstance(enabled, bool):
                raise EffectsError(origin, where + ".enabled", f"expected true or false, got {enabled!r}")
            declared = EFFECTS[name].parameters
            unknown = set(section) - set(declared) - {"enabled"}
            if unknown:
                raise EffectsError(origin, f"{where}.{sorted(unknown)[0]}",
                                   f"unknown parameter (known: {', '.join(declared)})")
            values = {key: float(p.default) for key, p in declared.items()}
            for key, raw in section.items():
                if key != "enabled":
                    values[key] = _parameter_value(raw, declared[key], origin, f"{where}.{key}")
            if enabled:
                chosen[name] = values
        return cls(chosen, origin)

    @classmethod
    def defaults(cls, *names: str, **overrides: Mapping[str, Any]) -> "EffectsConfig":
        """The named effects at their defaults, plus ``overrides`` (effect -> {parameter: value})."""
        section: dict[str, Any] = {name: {} for name in names}
        section.update({name: dict(values) for name, values in overrides.items()})
        return cls.from_mapping(section, "<defaults>")

    def build(self, n: int, rig: Rig) -> "EffectStack":
        """Live effects (with their own state) for a simulator of n rigs."""
        return EffectStack([EFFECTS[name](params, n, rig) for name, params in self.effects.items()])

    def to_dict(self) -> dict[str, Any]:
        """The file's document: format, version and the effects (values in declared units)."""
        return {"format": FORMAT_NAME, "version": FORMAT_VERSION,
                "effects": {name: dict(params) for name, params in self.effects.items()}}


def load_effects(path: str | os.PathLike[str]) -> EffectsConfig:
    """Read the effects of a ``worm_rig_effects`` v1 file, or the ``effects`` section of a rig file.

    A ``worm_rig_parameters`` file (worm_model) may carry an optional top-level
    ``effects`` section in the same form; only that section is read here.

    Raises:
        EffectsError: unreadable file, wrong format or version, unknown effect or
            parameter, bad value, unit or range; the message names the file and the key.
    """
    origin = str(path)
    try:
        document = load_yaml(path, "effects file")
    except InputError as err:
        raise EffectsError(err.where, "", err.what) from None
    if not isinstance(document, Mapping):
        raise EffectsError(origin, "", "not a YAML mapping")
    if document.get("format") == RIG_FORMAT_NAME:
        return EffectsConfig.from_mapping(document.get("effects"), origin)
    if document.get("format") != FORMAT_NAME:
        raise EffectsError(origin, "format", f"expected {FORMAT_NAME!r} (or a {RIG_FORMAT_NAME!r} file with an "
                           f"'effects' section), got {document.get('format')!r}")
    if document.get("version") != FORMAT_VERSION:
        raise EffectsError(origin, "version", f"unsupported version {document.get('version')!r}")
    extra = set(document) - {"format", "version", "effects"}
    if extra:
        raise EffectsError(origin, sorted(extra)[0], "unknown key (expected format, version, effects)")
    return EffectsConfig.from_mapping(document.get("effects"), origin)


def as_config(effects: "EffectsConfig | Mapping[str, Any] | str | os.PathLike[str] | None") -> EffectsConfig:
    """Accept a config, an ``effects`` mapping, a file path, or None (no effects)."""
    if effects is None:
        return EffectsConfig()
    if isinstance(effects, EffectsConfig):
        return effects
    if isinstance(effects, Mapping):
        return EffectsConfig.from_mapping(effects)
    return load_effects(effects)


# --- composition -----------------------------------------------------------------------------------

class EffectStack:
    """The live effects of one simulator, composed hook by hook (sums of torques, chained mu, ...).

    With no effect on a hook, the plant skips it entirely (``has_*`` flags), so the
    pure model costs nothing extra.
    """

    def __init__(self, effects: list[EffectBase]) -> None:
        self.effects = effects
        by_hook = {hook: [e for e in effects if hook in type(e).hooks()] for hook in HOOKS}
        self._worm = by_hook["worm_torque"]
        self._gear = by_hook["gear_torque"]
        self._friction = by_hook["friction"]
        self._voltage = by_hook["drive_voltage"]
        self._advance = by_hook["advance"]
        self._sense = by_hook["sense"]
        self._observe = by_hook["observe"]
        self._inertia = by_hook["inertia"]
        self._dissipative = [e for e in effects if e.dissipative]
        self.has_worm_torque = bool(self._worm)
        self.has_gear_torque = bool(self._gear)
        self.has_friction = bool(self._friction)
        self.has_voltage = bool(self._voltage)
        self.has_sense = bool(self._sense)
        self.needs_heat = bool(self._advance)
        self.backlash = float(sum(e.backlash() for e in by_hook["backlash"]))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.effects)

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        """Sum of the worm-shaft torques [N m], + along + worm rotation."""
        total = self._worm[0].worm_torque(s)
        for e in self._worm[1:]:
            total = total + e.worm_torque(s)
        return total

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        """Sum of the gear-shaft torques [N m], + opposing + gear rotation."""
        total = self._gear[0].gear_torque(s)
        for e in self._gear[1:]:
            total = total + e.gear_torque(s)
        return total

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        for e in self._friction:
            mu = e.friction(mu, v_sliding, s)
        return mu

    def inertia(self, worm: float, gear: float) -> tuple[float, float]:
        for e in self._inertia:
            worm, gear = e.inertia(worm, gear)
        return worm, gear

    def drive_voltage(self, voltage: np.ndarray, supply: float) -> np.ndarray:
        for e in self._voltage:
            voltage = e.drive_voltage(voltage, supply)
        return voltage

    def heat(self, s: ShaftState) -> np.ndarray:
        """Power [W] the dissipative shaft effects turn into heat inside the gearbox (>= 0)."""
        power = np.zeros_like(s.omega_worm)
        for e in self._dissipative:
            power = power - e.worm_torque(s) * s.omega_worm + e.gear_torque(s) * s.omega_gear
        return power

    def advance(self, dt: float, heat: np.ndarray) -> None:
        for e in self._advance:
            e.advance(dt, heat)

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        for e in self._sense:
            e.sense(signals, context)

    def observe(self) -> dict[str, np.ndarray]:
        found: dict[str, np.ndarray] = {}
        for e in self._observe:
            found.update(e.observe())
        return found


# --- command line ----------------------------------------------------------------------------------

def describe() -> str:
    """Every registered effect with its hooks and parameters (unit, default, meaning)."""
    lines = []
    for name, cls in EFFECTS.items():
        lines.append(f"{name}: {cls.summary}  [changes: {', '.join(sorted(cls.hooks()))}]")
        for key, p in cls.parameters.items():
            unit = "" if p.unit == "1" else f" {p.unit}"
            lines.append(f"    {key} = {p.default:g}{unit}: {p.doc}")
    return "\n".join(lines)


def template(names: tuple[str, ...] | None = None) -> str:
    """A documented worm_rig_effects file with the named effects (default: all) at their defaults."""
    lines = [f"# {FORMAT_NAME} v{FORMAT_VERSION}: effects the model lacks, switched on in the simulator only.",
             "# Every parameter is {value, unit} (or a plain number in the unit shown); remove an effect,",
             f"# or give it 'enabled: false', to switch it off. {TEMPLATE_MARK}",
             f"format: {FORMAT_NAME}", f"version: {FORMAT_VERSION}", "effects:"]
    for name in names or tuple(EFFECTS):
        cls = EFFECTS[name]
        lines.append(f"  {name}:  # {cls.summary}")
        for key, p in cls.parameters.items():
            lines.append(f'    {key}: {{value: {p.default!r}, unit: "{p.unit}"}}  # {p.doc}')
    return "\n".join(lines) + "\n"


#: the line every template carries: what lets --template --force recognise one it wrote
TEMPLATE_MARK = "Generated by python -m worm_rig_driver.sim.effects."
#: what --template writes; --force replaces only a template it wrote (worm_model.files.writing)
TEMPLATE_OUTPUT = Output("worm_effects", recognise=lambda path: TEMPLATE_MARK in path.read_text(encoding="utf-8",
                                                                                                 errors="replace"))


def main(argv: list[str] | None = None) -> int:
    return run_tool("worm_effects", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    parser = Parser(
        prog="worm_effects",
        description="The simulator's effect plug-ins (physics.md section 9): list them, write a template "
                    "effects file with every effect at its defaults, or check an effects file.")
    parser.add_argument("--list", action="store_true", help="print every effect, what it changes and its "
                        "parameters with unit, default and meaning")
    parser.add_argument("--template", metavar="FILE", type=output_path,
                        help="write a worm_rig_effects file with every effect at its defaults ('-' for stdout); "
                             "an existing file is replaced only with --force, and only a template worm_effects wrote")
    parser.add_argument("--force", action="store_true", help="let --template replace a template it wrote before")
    parser.add_argument("--check", metavar="FILE", type=existing_file,
                        help="read an effects file and print what it switches on")
    args = parser.parse_args(argv)
    if not (args.list or args.template is not None or args.check):
        parser.print_help()
        return 0
    to_file = args.template is not None and str(args.template) != "-"
    if to_file:
        check_output(args.template, args.force, option="--template", inputs=[args.check], output=TEMPLATE_OUTPUT)
    config = load_effects(args.check) if args.check else None
    if args.list:
        print(describe())
    if args.template is not None:
        text = template()
        if not to_file:
            sys.stdout.write(text)
        else:
            with atomic_file(args.template, args.force, option="--template", inputs=[args.check],
                             output=TEMPLATE_OUTPUT) as tmp:
                tmp.write_text(text, encoding="utf-8")
    if config is not None:
        for name, params in config.effects.items():
            units = {k: ("" if p.unit == "1" else " " + p.unit) for k, p in EFFECTS[name].parameters.items()}
            shown = ", ".join(f"{k}={v:g}{units[k]}" for k, v in params.items())
            print(f"{name}: {shown}")
        if not config.effects:
            print("no effect switched on")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
