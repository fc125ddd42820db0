"""Steady state of the drive: the worm speed at which a held voltage and load settle.

Eq. 28 with a_w = 0 and Eq. 29 with di/dt = 0. In steady state the motor's shaft
torque (Eq. 30 without the rotor inertia) is exactly the input torque that keeps
the worm turning against the gear-side load:

    K_t (V - K_e w) / R - b w - c sign(w) = reflected_input_torque(mu(w), tau_load + drag(w), w)

The right-hand side includes the load motors' drag (gear_side.gear_side_load).
The expectation is computed by root finding, so it is independent of any time
integration. That makes it a reference for the simulators (plant, simulated and
virtual rig).

Conventions: those of dynamics.py. voltage [V] and omega_worm [rad/s] are signed
in the fixed frame. tau_load [N m] is + when it opposes + worm rotation.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

import math
from collections.abc import Callable

from worm_model.physics.dynamics import make_reflected_input_torque_float, reflected_input_torque
from worm_model.physics.friction import friction_coefficient, make_friction_coefficient_float
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.motor import shaft_torque, steady_state_current
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray


def torque_surplus(rig: Rig, voltage: float, tau_load: float, omega_worm: float) -> float:
    """Drive shaft torque at steady current minus the input torque the load needs [N m].

    The result is 0 at the steady speed and > 0 where the worm would speed up.
    """
    motor = rig.drive_motor
    current = steady_state_current(motor, voltage, omega_worm)
    mu = friction_coefficient(rig.friction, rig.gearbox, omega_worm)
    need = reflected_input_torque(rig.gearbox, mu, gear_side_load(rig, tau_load, omega_worm), omega_worm)
    return float(shaft_torque(motor, current, omega_worm) - need)


def steady_worm_speed(rig: Rig, voltage: float, tau_load: float) -> float:
    """Worm speed [rad/s] that ``voltage`` [V] settles at against ``tau_load`` [N m].

    The speed turns in the direction of the voltage. It is sought between 1 mrad/s
    and 1.5 times the no-load speed |V| / K_e.

    Raises:
        ValueError: voltage 0, or the motor cannot turn the load. A self-locking box
            stalls, and then the torque surplus has no sign change in that range.
    """
    if voltage == 0.0:
        raise ValueError("voltage 0: no steady speed to seek (the worm stands still)")
    top = 1.5 * abs(voltage) / rig.drive_motor.back_emf_constant
    lo, hi = (1e-3, top) if voltage > 0 else (-top, -1e-3)
    # here, not at the top: scipy.optimize costs 0.2-0.4 s to import, which every process that reads rig data
    # (the recorder among them) would pay at start-up without ever seeking a steady speed
    from scipy.optimize import brentq

    return float(brentq(lambda w: torque_surplus(rig, voltage, tau_load, w), lo, hi, xtol=1e-12, rtol=1e-13))



def balancing_torque(rig: Rig, tau_load: ArrayLike, omega_worm: ArrayLike) -> FloatArray:
    """Input torque at the worm [N m] that balances load tau_load [N m] at speed omega_worm [rad/s].

    Eq. 28 quasi-statically (a_w = 0) with the friction coefficient of the rig's
    friction model at that speed: what a speed controller feeds forward for a
    known load. The load motors' own drag is not added (the feedforward balances
    the load it is told). NaN loads give 0, never NaN.
    """
    tau_load = np.asarray(tau_load, dtype=float)
    mu = friction_coefficient(rig.friction, rig.gearbox, omega_worm)
    torque = reflected_input_torque(rig.gearbox, mu, np.nan_to_num(tau_load), omega_worm)
    return np.where(np.isfinite(tau_load), torque, 0.0)


def make_balancing_torque_float(rig: Rig) -> Callable[[float, float], float]:
    """:func:`balancing_torque` for one float load [N m] and speed [rad/s], in plain math: a controller
    computes it for every estimate. Agrees with it to round-off (the friction law's float twin does);
    a test checks. Speeds below 1e-9 rad/s count as positive (motion_sign with no torque)."""
    mu_of = make_friction_coefficient_float(rig.friction, rig.gearbox)
    reflected = make_reflected_input_torque_float(rig.gearbox)

    def torque(tau_load: float, omega_worm: float) -> float:
        if not (math.isfinite(tau_load) and math.isfinite(omega_worm)):
            return 0.0
        return reflected(mu_of(omega_worm), tau_load, omega_worm)[0]

    return torque
