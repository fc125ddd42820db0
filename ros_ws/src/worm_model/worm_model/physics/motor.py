"""PMDC motor (paper Eq. 29, reference section 7).

Conventions: voltage [V], current [A], omega [rad/s] of the motor shaft (= worm shaft for
the drive motor, rigid coupling), all signed in the same fixed frame; torques [N m],
+ along + rotation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.units import FloatArray

if TYPE_CHECKING:
    from worm_model.physics.parameters import Motor


def current_derivative(motor: Motor, voltage: ArrayLike, current: ArrayLike, omega: ArrayLike) -> FloatArray:
    """di/dt = (V - R i - K_e omega) / L [A/s] (Eq. 29)."""
    v, i, w = (np.asarray(x, dtype=float) for x in (voltage, current, omega))
    return (v - motor.resistance * i - motor.back_emf_constant * w) / motor.inductance


def electromagnetic_torque(motor: Motor, current: ArrayLike) -> FloatArray:
    """tau_m = K_t i [N m] (Eq. 29)."""
    return motor.torque_constant * np.asarray(current, dtype=float)


def shaft_torque(motor: Motor, current: ArrayLike, omega: ArrayLike) -> FloatArray:
    """Torque reaching the coupling: K_t i - b omega - c sign(omega) [N m] (Eq. 30 without rotor inertia).

    The rotor inertia J_m belongs to the shaft's total inertia, not to this torque.
    At omega = 0 the Coulomb term is 0 (static drag is the simulator's business).
    """
    w = np.asarray(omega, dtype=float)
    return electromagnetic_torque(motor, current) - motor.viscous_drag * w - motor.coulomb_drag * np.sign(w)


def steady_state_current(motor: Motor, voltage: ArrayLike, omega: ArrayLike) -> FloatArray:
    """i_ss = (V - K_e omega) / R [A]: Eq. 29 with di/dt = 0."""
    return ((np.asarray(voltage, dtype=float) - motor.back_emf_constant * np.asarray(omega, dtype=float))
            / motor.resistance)


def exact_current_step(
    motor: Motor, voltage: ArrayLike, current: ArrayLike, omega: ArrayLike, dt: ArrayLike
) -> FloatArray:
    """Current after dt [s] with V and omega held: exact solution of Eq. 29.

    i(t + dt) = i_ss + (i - i_ss) exp(-R dt / L); stable for any dt >= 0 (tends to i_ss).
    """
    i_ss = steady_state_current(motor, voltage, omega)
    decay = np.exp(-motor.resistance * np.asarray(dt, dtype=float) / motor.inductance)
    return i_ss + (np.asarray(current, dtype=float) - i_ss) * decay
