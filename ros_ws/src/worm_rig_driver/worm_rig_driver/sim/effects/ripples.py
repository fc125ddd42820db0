"""Torque ripples periodic in a shaft angle: worm and gear runout, the tooth pass, the motor's cogging."""
from __future__ import annotations

import math

import numpy as np

from worm_rig_driver.sim.effects.hooks import simulates, EffectBase, ShaftState, _ripple


@simulates
class WormRunout(EffectBase):
    """Worm eccentricity / coupling misalignment: a torque ripple once per worm turn.

    Worm torque -(amplitude + load_fraction * ratio * mesh_load) sin(theta_worm + phase):
    a constant part plus a part proportional to the mesh torque at the worm
    (eccentricity changes the lever arm of the mesh force).
    Residual signature: periodic in worm angle, once per worm turn.
    """

    name = "worm_runout"

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -_ripple(self.p["amplitude"], self.p["load_fraction"], self.rig.gearbox.ratio * s.mesh_load,
                        np.sin(s.theta_worm + self.p["phase"]))

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -_ripple(self.p["amplitude"], self.p["load_fraction"], self.rig.gearbox.ratio * mesh_load,
                        math.sin(theta_worm + self.p["phase"]))


@simulates
class ToothPass(EffectBase):
    """Mesh (tooth-pass) ripple: a gear-side torque ripple at the tooth-pass order.

    Gear torque (amplitude + load_fraction * mesh_load) sin(Z_g theta_gear + phase):
    Z_g per gear turn, i.e. n (worm starts) per worm turn.
    Residual signature: periodic in worm angle, n per worm turn.
    """

    name = "tooth_pass"

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], s.mesh_load,
                       np.sin(self.rig.gearbox.gear_teeth * s.theta_gear + self.p["phase"]))

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], mesh_load,
                       math.sin(self.rig.gearbox.gear_teeth * theta_gear + self.p["phase"]))


@simulates
class GearRunout(EffectBase):
    """Gear (wheel) eccentricity: a gear-side torque ripple once per gear turn.

    Gear torque (amplitude + load_fraction * mesh_load) sin(theta_gear + phase).
    Residual signature: periodic in gear angle, once per gear turn.
    """

    name = "gear_runout"

    def gear_torque(self, s: ShaftState) -> np.ndarray:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], s.mesh_load,
                       np.sin(s.theta_gear + self.p["phase"]))

    def gear_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return _ripple(self.p["amplitude"], self.p["load_fraction"], mesh_load, math.sin(theta_gear + self.p["phase"]))


@simulates
class MotorCogging(EffectBase):
    """Cogging of the drive motor: a torque periodic in the motor (= worm) angle.

    Worm torque -amplitude sin(order theta_worm + phase); order = LCM(poles, slots)
    cycles per turn. Conservative (zero work per turn), and a detent at rest.
    Residual signature: periodic in motor angle, `order` per turn.
    """

    name = "motor_cogging"

    def worm_torque(self, s: ShaftState) -> np.ndarray:
        return -self.p["amplitude"] * np.sin(self.p["order"] * s.theta_worm + self.p["phase"])

    def worm_torque_float(self, omega_worm, theta_worm, omega_gear, theta_gear, current, mesh_load) -> float:
        return -self.p["amplitude"] * math.sin(self.p["order"] * theta_worm + self.p["phase"])
