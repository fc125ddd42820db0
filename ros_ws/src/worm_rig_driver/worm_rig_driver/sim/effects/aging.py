"""Aging: effects that evolve over a gearbox's life (wear) or step in at a given rig time (lubricant loss, seal drag).

At their defaults these leave the gearbox as new (every hook returns its input bit for bit), so a
configuration of "every effect at its default" is a new gearbox; their parameters say how it ages.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from worm_model.physics.parameters import Rig

from worm_rig_driver.sim.effects.hooks import simulates, EffectBase, ShaftState, _sign

#: hours per second
_HOUR = 1.0 / 3600.0


@simulates
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
    dissipative = True

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


@simulates
class LubricantLoss(_RigClock):
    """Loss of lubricant (a leak, a starved mesh): mu steps up by ``rise`` at rig time ``at``.

    mu -> mu (1 + rise x ramp(t)), ramp 0 before ``at`` [s], then 1 (or rising linearly over
    ``duration`` [s]). At rise 0 (the default) the gearbox is healthy.
    Residual signature: a step in the friction torque, proportional to the mesh load.
    """

    name = "lubricant_loss"

    def friction(self, mu: np.ndarray, v_sliding: np.ndarray, s: ShaftState) -> np.ndarray:
        return mu * (1.0 + self.p["rise"] * self._onset(self.p["at"], self.p["duration"]))

    def friction_float(self, mu, v_sliding, omega_worm, theta_worm, omega_gear, theta_gear, current,
                       mesh_load) -> float:
        return mu * (1.0 + self.p["rise"] * self._onset(self.p["at"], self.p["duration"]))


@simulates
class SealDrag(_RigClock):
    """A seal starting to drag: Coulomb drag on the worm and gear shafts from rig time ``onset``.

    Worm: -worm_torque x ramp(t) sign(omega_worm); gear: +gear_torque x ramp(t) sign(omega_gear),
    ramp 0 before ``onset`` [s], rising linearly to 1 over ``growth`` [s] (0: at once). At its
    defaults (no torque) the seals are healthy.
    Residual signature: a sign(omega) step growing in, independent of the load.
    """

    name = "seal_drag"
    dissipative = True

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -(self.p["worm_torque"] * self._onset(self.p["onset"], self.p["growth"])) * np.sign(s.omega_worm)

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return (self.p["gear_torque"] * self._onset(self.p["onset"], self.p["growth"])) * np.sign(s.omega_gear)

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -(self.p["worm_torque"] * self._onset(self.p["onset"], self.p["growth"])) * _sign(omega_worm)

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return (self.p["gear_torque"] * self._onset(self.p["onset"], self.p["growth"])) * _sign(omega_gear)
