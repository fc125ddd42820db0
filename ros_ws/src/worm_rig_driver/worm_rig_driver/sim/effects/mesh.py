"""The mesh and the shafts beyond the model: mu's speed, load and oil-temperature laws, backlash, inertia errors."""
from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from worm_model.effects import oil
from worm_model.physics.parameters import Rig

from worm_rig_driver.sim.effects.hooks import simulates, EffectBase, ShaftState


@simulates
class SpeedDependentMu(EffectBase):
    """Mesh friction rising at low sliding speed (Stribeck / EHL film build-up), on top of the rig's law.

    mu = mu_rig(V_s) * (1 + low_speed_gain * exp(-V_s / stribeck_speed)), V_s the
    sliding speed at the pitch point. Residual signature: mu falling with sliding
    speed, rising sharply at low speed.
    """

    name = "speed_dependent_mu"

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu * (1.0 + self.p["low_speed_gain"] * np.exp(-v_sliding / self.p["stribeck_speed"]))

    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        return mu * (1.0 + self.p["low_speed_gain"] * math.exp(-v_sliding / self.p["stribeck_speed"]))


@simulates
class LoadDependentMu(EffectBase):
    """Mesh friction that depends on the load the mesh carries.

    mu = mu_rig * max(0.1, 1 + sensitivity * mesh_load / reference_torque), mesh_load
    the gear-side torque the mesh carries [N m]. Residual signature: a slope change with tau_d.
    """

    name = "load_dependent_mu"

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        factor = 1.0 + self.p["sensitivity"] * s.mesh_load / self.p["reference_torque"]
        return mu * np.maximum(factor, 0.1)

    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        factor = 1.0 + self.p["sensitivity"] * mesh_load / self.p["reference_torque"]
        return mu * (0.1 if factor < 0.1 else factor)  # np.maximum(factor, 0.1), NaN kept


@simulates
class OilTemperature(EffectBase):
    """Oil temperature with a thermal time constant, and mu that follows it.

    The model's oil law (worm_model.effects.oil: C dT/dt = P - (T - T_amb)/R_th), stepped
    exactly every sample with P the heat made inside the gearbox that sample (mesh friction
    and the dissipative shaft effects) [W]: the truth. The mesh mu is scaled by
    max(0.1, 1 + mu_per_kelvin (T - ambient)): the model's mu is the one at ambient.
    Residual signature: a slow drift over minutes at a constant operating point.
    """

    name = "oil_temperature"

    def __init__(self, params: Mapping[str, float], n: int, rig: Rig) -> None:
        super().__init__(params, n, rig)
        self.temperature = np.full(n, self.p["initial"])

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu * np.maximum(1.0 + self.p["mu_per_kelvin"] * (self.temperature - self.p["ambient"]), 0.1)

    def advance(self, dt: float, heat: np.ndarray) -> None:
        steady = oil.steady_temperature(self.p["ambient"], heat, self.p["thermal_resistance"])
        self.temperature = oil.relax(self.temperature, steady, oil.decay(dt, self.p["time_constant"]))

    # (n = 1: the temperature stays a (1,) array, written in place, so that observe() is unchanged)
    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        factor = 1.0 + self.p["mu_per_kelvin"] * (float(self.temperature[0]) - self.p["ambient"])
        return mu * (0.1 if factor < 0.1 else factor)

    def advance_float(self, dt: float, heat: float) -> None:
        steady = oil.steady_temperature(self.p["ambient"], heat, self.p["thermal_resistance"])
        self.temperature[0] = oil.relax(float(self.temperature[0]), steady, oil.decay(dt, self.p["time_constant"]))

    def observe(self) -> dict[str, np.ndarray]:
        return {"oil_temperature": self.temperature.copy()}


@simulates
class Backlash(EffectBase):
    """Clearance between thread and teeth: the mesh becomes a dead zone of this width.

    When the mesh force changes sign (a flank change: resistive <-> assistive load,
    or a reversal with little load) the contact crosses the gap: worm and gear move
    apart, each under its own torques, until the other flank is hit (a perfectly
    inelastic impact). Residual signature: dead time and a current spike at each
    flank change. The plant implements the dead zone; this effect sets its width.
    """

    name = "backlash"

    def backlash(self) -> float:
        return self.p["angle"]


@simulates
class InertiaError(EffectBase):
    """The shafts' true inertias differ from the rig file's: J_true = (1 + error) J_file.

    Residual signature: proportional to the acceleration.
    """

    name = "inertia_error"

    def inertia(self, worm: float, gear: float) -> tuple[float, float]:
        return worm * (1.0 + self.p["worm"]), gear * (1.0 + self.p["gear"])
