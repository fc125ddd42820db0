"""What wears, in the model: the friction torque a drive needs at steady speed, and its temperature law.

At a constant worm speed omega [rad/s] against a known load tau_load [N m] (physics.md sections 6-7,
Eq. 28 with a_w = 0), the drive motor's torque K_t i [N m] balances

    K_t i = c_w sign(w) + b_w w + tau_0 + (r_w/r_g) K_s(mu) D_mesh                 (fixed frame)
    D_mesh = tau_load + c_g sign(w) + b_g i w                                      (gear shaft, worm-referenced)
    mu     = s mu_file(V_s) (V_s / V_ref)^e max(0.1, 1 + l (|D_mesh| - D_ref)) f_T(T)

with K_s the flank factor (efficiency.flank_factor; the flank s = sign(sigma D_mesh)), mu_file the
rig file's friction law (physics/friction.py) and V_s the sliding speed. The speed and load laws are
centred (V_ref = 1 m/s, D_ref = 0.8 x the load motors' torque, :func:`reference_load`) so that s is
mu's scale where a check's loads decide it best (the friction torque grows with the load: the high
loads weigh most), and is decided apart from e and l (on the reference run their correlation with s
falls from -0.9 at D_ref = 0 to -0.6).
The parameters
(:class:`HealthParameters`) are what wears and what hides it:

=====================  =============  ======================================================
``mu_scale``           1              s: the mesh friction relative to the rig file's law (at V_ref, D_ref)
``mu_speed_exponent``  1              e: how mu's speed law departs from the file's
``mu_load_slope``      1/(N m)        l: mu's change with the mesh load (paper Fig. 9: < 0)
``drive_coulomb``      N m            c_w: Coulomb drag on the worm shaft (motor, bearings, seal)
``drive_viscous``      N m s/rad      b_w: viscous drag on the worm shaft
``gear_coulomb``       N m            c_g: Coulomb drag on the gear shaft (load motors, seals)
``gear_viscous``       N m s/rad      b_g: viscous drag on the gear shaft, per rad/s of the gear
``torque_offset``      N m            tau_0: the current sensor's zero offset times K_t (not wear)
=====================  =============  ======================================================

The oil temperature T [degC] enters through mu only (:class:`TemperatureLaw`, f_T(T) = max(0.1,
1 + k (T - T_ref))): a warm gearbox is not a worn one. The drags' own temperature dependence
(churning falls as the oil thins) is not modelled.

Signs: those of physics.md section 2; the gear turns at i w (worm-referenced), so sign(w_g) =
sign(w).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np
from numpy.typing import ArrayLike

from worm_model.effects import VOCABULARY
from worm_model.effects.heat import mesh_heat
from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient, sliding_velocity
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

#: reference sliding speed of the speed law [m/s]
V_REF = 1.0
#: mu is kept below this fraction of the engagement bound (Remark 4) while a fit explores
MU_CEILING = 0.9
#: the parameter vector's names and units, in order
NAMES = ("mu_scale", "mu_speed_exponent", "mu_load_slope", "drive_coulomb", "drive_viscous", "gear_coulomb",
         "gear_viscous", "torque_offset")
UNITS = {"mu_scale": "1", "mu_speed_exponent": "1", "mu_load_slope": "1/(N m)", "drive_coulomb": "N m",
         "drive_viscous": "N m s/rad", "gear_coulomb": "N m", "gear_viscous": "N m s/rad", "torque_offset": "N m"}


@dataclass(frozen=True)
class HealthParameters:
    """What wears, at the reference oil temperature (module docstring; SI)."""

    mu_scale: float = 1.0
    mu_speed_exponent: float = 0.0
    mu_load_slope: float = 0.0
    drive_coulomb: float = 0.0
    drive_viscous: float = 0.0
    gear_coulomb: float = 0.0
    gear_viscous: float = 0.0
    torque_offset: float = 0.0

    @classmethod
    def from_rig(cls, rig: Rig) -> "HealthParameters":
        """The rig file's values: its mu law (scale 1), the drive motor's drags on the worm shaft, the
        load motors' drags (all of them) on the gear shaft, no offset."""
        load = rig.load_motor
        return cls(drive_coulomb=rig.drive_motor.coulomb_drag, drive_viscous=rig.drive_motor.viscous_drag,
                   gear_coulomb=rig.load_motor_count * load.coulomb_drag,
                   gear_viscous=rig.load_motor_count * load.viscous_drag)

    def vector(self) -> FloatArray:
        return np.array([getattr(self, name) for name in NAMES], dtype=float)

    @classmethod
    def from_vector(cls, values: ArrayLike) -> "HealthParameters":
        return cls(**{name: float(v) for name, v in zip(NAMES, np.asarray(values, dtype=float))})

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict, origin: str) -> "HealthParameters":
        """From :meth:`to_dict`'s form; every name present and finite, else ValueError naming it."""
        out = {}
        for f in fields(cls):
            raw = values.get(f.name) if isinstance(values, dict) else None
            if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
                raise ValueError(f"{origin}: parameters.{f.name}: expected a finite number, got {raw!r}")
            out[f.name] = float(raw)
        return cls(**out)


@dataclass(frozen=True)
class TemperatureLaw:
    """mu's oil-temperature law f_T(T) = max(0.1, 1 + k (T - reference)): 1 at the reference temperature.

    The monitor's own law (fitted to checks), kept apart from the simulator's oil effect, whose mu follows the
    same form: the health study judges the monitor on simulated gearboxes.

    Attributes:
        reference: T_ref [degC], where the health parameters hold.
        mu_per_kelvin: k [1/K] (< 0: hotter, thinner oil, lower mu).
        sigma: standard uncertainty of k [1/K].
        source: where k comes from ("prior" or "learned from N checks").
    """

    reference: float = 25.0
    mu_per_kelvin: float = VOCABULARY["oil_temperature"].default("mu_per_kelvin")  # the oil effect's assumption
    sigma: float = 0.003
    source: str = "prior"

    def factor(self, temperature: ArrayLike) -> FloatArray:
        """f_T at temperature [degC]; 1 where the temperature is NaN (unknown: the reference is assumed)."""
        t = np.asarray(temperature, dtype=float)
        f = np.maximum(1.0 + self.mu_per_kelvin * (t - self.reference), 0.1)
        return np.where(np.isfinite(t), f, 1.0)

    def with_coefficient(self, mu_per_kelvin: float, sigma: float, source: str) -> "TemperatureLaw":
        return replace(self, mu_per_kelvin=mu_per_kelvin, sigma=sigma, source=source)


def reference_load(rig: Rig) -> float:
    """D_ref [N m]: the mesh load at which mu_scale holds, 0.8 x what the load motors can make (module docstring)."""
    return 0.8 * rig.max_load_torque


def gear_drag(rig: Rig, p: HealthParameters, omega_worm: ArrayLike) -> FloatArray:
    """Drag on the gear shaft [N m], + opposing + rotation: c_g sign(w) + b_g i w."""
    w = np.asarray(omega_worm, dtype=float)
    return p.gear_coulomb * np.sign(w) + p.gear_viscous * rig.gearbox.ratio * w


def mesh_mu(rig: Rig, p: HealthParameters, omega_worm: ArrayLike, mesh_load: ArrayLike,
            temperature_factor: ArrayLike = 1.0) -> FloatArray:
    """mu of the module docstring's law at worm speed [rad/s] and gear-side mesh load [N m] (either sign)."""
    w = np.asarray(omega_worm, dtype=float)
    v = np.maximum(sliding_velocity(rig.gearbox, w), 1e-6)
    law = p.mu_scale * friction_coefficient(rig.friction, rig.gearbox, w) * (v / V_REF) ** p.mu_speed_exponent
    load = np.maximum(1.0 + p.mu_load_slope * (np.abs(np.asarray(mesh_load, dtype=float)) - reference_load(rig)),
                      0.1)
    mu = law * load * np.asarray(temperature_factor, dtype=float)
    return np.clip(mu, 0.0, MU_CEILING * rig.gearbox.mu_engagement_max)


def mesh_torque(rig: Rig, p: HealthParameters, omega_worm: ArrayLike, tau_load: ArrayLike,
                temperature_factor: ArrayLike = 1.0) -> tuple[FloatArray, FloatArray]:
    """(torque into the mesh at the worm [N m], gear-side mesh load D_mesh [N m]), fixed frame, a_w = 0."""
    d_mesh = np.asarray(tau_load, dtype=float) + gear_drag(rig, p, omega_worm)
    mu = mesh_mu(rig, p, omega_worm, d_mesh, temperature_factor)
    return reflected_input_torque(rig.gearbox, mu, d_mesh, omega_worm), d_mesh


def input_torque(rig: Rig, p: HealthParameters, omega_worm: ArrayLike, tau_load: ArrayLike,
                 temperature_factor: ArrayLike = 1.0) -> FloatArray:
    """K_t i [N m] the drive motor makes at steady speed omega_worm [rad/s] against tau_load [N m] (module doc)."""
    w = np.asarray(omega_worm, dtype=float)
    mesh, _ = mesh_torque(rig, p, w, tau_load, temperature_factor)
    return mesh + p.drive_coulomb * np.sign(w) + p.drive_viscous * w + p.torque_offset


def mesh_loss(rig: Rig, p: HealthParameters, omega_worm: ArrayLike, tau_load: ArrayLike,
              temperature_factor: ArrayLike = 1.0) -> FloatArray:
    """Power the mesh turns into heat [W] (>= 0): what goes in at the worm less what comes out at the gear
    (worm_model.effects.heat), at a steady point (no acceleration)."""
    w = np.asarray(omega_worm, dtype=float)
    mesh, d_mesh = mesh_torque(rig, p, w, tau_load, temperature_factor)
    return mesh_heat(mesh, w, d_mesh, rig.gearbox.ratio * w)


def drag_power(rig: Rig, p: HealthParameters, omega_worm: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """(worm-shaft drag power, gear-shaft drag power) [W], both >= 0."""
    w = np.asarray(omega_worm, dtype=float)
    worm = np.abs((p.drive_coulomb * np.sign(w) + p.drive_viscous * w) * w)
    gear = np.abs(gear_drag(rig, p, w) * rig.gearbox.ratio * w)
    return worm, gear


__all__ = ["HealthParameters", "MU_CEILING", "NAMES", "TemperatureLaw", "UNITS", "V_REF", "drag_power", "gear_drag",
           "input_torque", "mesh_loss", "mesh_mu", "mesh_torque", "reference_load"]
