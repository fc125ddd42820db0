"""Drags on the worm and gear shafts: the bearings' and seals' Coulomb drag, viscous and oil-churning drag."""
from __future__ import annotations

import numpy as np

from worm_rig_driver.sim.effects.hooks import simulates, EffectBase, ShaftState, _sign


@simulates
class BearingCoulomb(EffectBase):
    """Coulomb drag of the bearings and lip seals of the worm and gear shafts.

    Worm: -worm_torque sign(omega_worm); gear: +gear_torque sign(omega_gear) (a drag).
    At rest it is static friction up to the same torque (the plant's breakaway test).
    Residual signature: a step with sign(omega), independent of the load.
    """

    name = "bearing_coulomb"
    dissipative = True

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -self.p["worm_torque"] * np.sign(s.omega_worm)

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return self.p["gear_torque"] * np.sign(s.omega_gear)

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -self.p["worm_torque"] * _sign(omega_worm)

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return self.p["gear_torque"] * _sign(omega_gear)


@simulates
class ViscousDrag(EffectBase):
    """Viscous and oil-churning drag: T(omega) = T_ref (|omega| / omega_ref)^exponent sign(omega).

    Both shafts are referred to the same worm speed: the gear term is evaluated at
    the worm speed that goes with the gear's speed (omega_gear / ratio).
    Residual signature: linear (exponent 1) or ~|omega|^0.5..1 (churning).
    """

    name = "viscous_drag"
    dissipative = True

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
