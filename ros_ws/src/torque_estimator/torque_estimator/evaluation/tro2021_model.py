"""The published model of the T-RO 2021 worm drive, with its authors' parameters: the reference we compare to.

This implements the steady-state (constant speed) motor torque of the model of
A. Mablekos-Alexiou, L. da Cruz, C. Bergeles, "Friction-Inclusive Modeling of Sliding
Contact Transmission Systems in Robotics", IEEE T-RO 37(4), 1252-1267, 2021, for their
worm drive (drive No. 3), as their public MATLAB code evaluates it
(https://github.com/RViMLab/TRO2021-Dynamic-Modelling, commit c3b758b, MIT): the
equations of ``Transmission.m`` (``getDvar``, ``getFrictionCoeff``, ``getPsiStar``,
``getSupportTorque``, ``getTorque`` at zero acceleration and no preload) and of the
``stribeck`` fit function of ``id_1dof_static.m``, with the parameters of ``sd_1dof.m``.
Written here from those equations, independently of this project's model
(worm_model.physics), so that the two can be checked against each other.

Their frame and ours. Their reader (``getEposData.m``) negates the EPOS's velocity and
torque; their payload P > 0 *aids* positive motion. In their frame, at speed v [rad/s of
the worm] (no acceleration):

    mu      = kinFriction + strbInf exp(-|v| / strbVelocity)^2                (getFrictionCoeff)
    rho     = atan(mu / cos(pressureAngle))
    Dvar    = (P - outSupBreak sign(v) - outSupVisc gamma0 psi0 v) sign(v)     (getDvar)
    psi*    = tan(lambda - rho) if Dvar > 0 else tan(lambda + rho)            (getPsiStar: downhill/uphill)
    support = inSupBreak sign(v) + inSupVisc v
              + gamma psi* (outSupBreak sign(v) + outSupVisc gamma0 psi0 v)   (getSupportTorque)
    torque  = -gamma psi* P + support                                         (getTorque)

with gamma0 = gamma = d_worm / d_gear (Transmission.getGamma with the effective diameters
equal to the diameters), psi0 = tan(lambda), d_gear = tan(lambda) d_worm ratio
(setWDgeometry), pressureAngle = atan(tan(threadAngle / 2) cos(lambda)). This project
keeps the EPOS's signs: ``omega_worm = -v``, the motor torque ``= -torque``, and the
hanging load is tau_load = +P (it opposes + rotation, which lifts it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.units import FloatArray

#: their local gravity [m/s^2] (id_1dof_static.m, extLoad)
TRO_GRAVITY = 9.812
#: the hanging mass [kg] and pulley radius [m] of the steady-state files (id_1dof_static.m)
TRO_MASS, TRO_PULLEY_RADIUS = 0.096, 0.02
#: the motor's nominal torque [N m]: 100 % of the EPOS's torque (sd_1dof.m nominalTorque)
TRO_NOMINAL_TORQUE = 9.84e-3


@dataclass(frozen=True)
class TroDrive:
    """Drive No. 3 as ``sd_1dof.m`` declares it (SI; angles in rad; velocities in rad/s of the worm)."""

    lead_angle: float = 2.8625 * math.pi / 180.0
    thread_angle: float = 40.0 * math.pi / 180.0
    worm_diameter: float = 0.010
    reduction_ratio: float = 60.0
    in_sup_break: float = 5.5e-4  # [N m]
    in_sup_visc: float = 1.15e-5  # [N m s/rad]
    out_sup_break: float = 4e-3  # [N m]
    out_sup_visc: float = 2.2e-12  # [N m s/rad] at the gear
    kin_friction: float = 0.12
    strb_inf: float = 0.06
    strb_velocity: float = 0.688  # [rad/s of the worm]

    @property
    def gear_diameter(self) -> float:
        """Transmission.setWDgeometry: tan(lambda) d_worm ratio [m]."""
        return math.tan(self.lead_angle) * self.worm_diameter * self.reduction_ratio

    @property
    def gamma(self) -> float:
        """Transmission.getGamma: d_worm / d_gear (gamma0 and gamma alike here)."""
        return self.worm_diameter / self.gear_diameter

    @property
    def pressure_angle(self) -> float:
        """Transmission set.geometry: atan(tan(threadAngle / 2) cos(leadAngle)) [rad]."""
        return math.atan(math.tan(self.thread_angle / 2.0) * math.cos(self.lead_angle))


def payload(mass: float = TRO_MASS, pulley_radius: float = TRO_PULLEY_RADIUS, gravity: float = TRO_GRAVITY) -> float:
    """id_1dof_static.m extLoad for the worm drive: gravity x mass x pulley radius [N m]."""
    return gravity * mass * pulley_radius


def friction_coefficient(drive: TroDrive, v: ArrayLike) -> FloatArray:
    """getFrictionCoeff (moving): kinFriction + strbInf exp(-|v|/strbVelocity)^2, v [rad/s of the worm]."""
    return drive.kin_friction + drive.strb_inf * np.exp(-np.abs(np.asarray(v, dtype=float)) / drive.strb_velocity) ** 2


def their_torque(drive: TroDrive, v: ArrayLike, load: float) -> FloatArray:
    """The motor torque [N m] at constant speed v [rad/s], in their frame (module docstring)."""
    v = np.asarray(v, dtype=float)
    sign = np.sign(v)
    gamma0 = gamma = drive.gamma
    psi0 = math.tan(drive.lead_angle)
    rho = np.arctan(friction_coefficient(drive, v) / math.cos(drive.pressure_angle))
    downhill, uphill = np.tan(drive.lead_angle - rho), np.tan(drive.lead_angle + rho)
    dvar = (load - drive.out_sup_break * sign - drive.out_sup_visc * gamma0 * psi0 * v) * sign
    psi = np.where(dvar > 0, downhill, uphill)
    support = (drive.in_sup_break * sign + drive.in_sup_visc * v
               + gamma * psi * drive.out_sup_break * np.sign(gamma0 * psi0 * v)
               + gamma * psi * drive.out_sup_visc * gamma0 * psi0 * v)
    return -gamma * psi * load + support


def motor_torque(drive: TroDrive, omega_worm: ArrayLike, tau_load: float) -> FloatArray:
    """The same in this project's frame: motor torque [N m] at worm speed omega_worm [rad/s] (the EPOS's sign)
    against tau_load [N m] (+ opposes + rotation; the hanging mass: +P)."""
    return -their_torque(drive, -np.asarray(omega_worm, dtype=float), tau_load)


__all__ = ["TRO_GRAVITY", "TRO_MASS", "TRO_NOMINAL_TORQUE", "TRO_PULLEY_RADIUS", "TroDrive", "friction_coefficient",
           "motor_torque", "payload", "their_torque"]
