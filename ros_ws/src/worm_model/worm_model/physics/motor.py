"""PMDC motor (paper Eq. 29, reference section 7).

Conventions: voltage [V], current [A], omega [rad/s] of the motor shaft (= worm shaft for
the drive motor, rigid coupling), all signed in the same fixed frame; torques [N m],
+ along + rotation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
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


def coulomb_magnitude(motor: Motor, omega: ArrayLike) -> FloatArray:
    """|Coulomb drag| of the shaft at speed omega [rad/s]: c + c_s exp(-|omega| / omega_s) [N m] (c =
    ``coulomb_drag``, c_s = ``stribeck_rise``, omega_s = ``stribeck_speed`` of this shaft): a support's
    (bearings', seals', brushes') Stribeck friction, higher at breakaway than sliding; c where there is no rise."""
    w = np.asarray(omega, dtype=float)
    if motor.stribeck_rise == 0.0:
        return np.full(w.shape, motor.coulomb_drag)
    return motor.coulomb_drag + motor.stribeck_rise * np.exp(-np.abs(w) / motor.stribeck_speed)


def coulomb_friction(motor: Motor, omega: ArrayLike) -> FloatArray:
    """The shaft's Coulomb drag with its low-speed rise [N m], opposing the motion (+ along + rotation):
    :func:`coulomb_magnitude` x sign(omega) (0 at omega = 0)."""
    w = np.asarray(omega, dtype=float)
    if motor.stribeck_rise == 0.0:
        return motor.coulomb_drag * np.sign(w)
    return coulomb_magnitude(motor, w) * np.sign(w)


def make_coulomb_friction_float(motor: Motor) -> Callable[[float], float]:
    """:func:`coulomb_friction` at one float speed [rad/s], in plain math (per-sample loops)."""
    c, rise, speed = motor.coulomb_drag, motor.stribeck_rise, motor.stribeck_speed

    def friction(omega: float) -> float:
        sign = (omega > 0) - (omega < 0)
        if rise == 0.0:
            return c * sign
        return (c + rise * math.exp(-abs(omega) / speed)) * sign

    return friction


def shaft_torque(motor: Motor, current: ArrayLike, omega: ArrayLike) -> FloatArray:
    """Torque reaching the coupling: K_t i - b omega - c(omega) sign(omega) [N m] (Eq. 30 without rotor inertia;
    c(omega) with its low-speed rise, :func:`coulomb_friction`).

    The rotor inertia J_m belongs to the shaft's total inertia, not to this torque.
    At omega = 0 the Coulomb term is 0 (static drag is the simulator's business).
    """
    w = np.asarray(omega, dtype=float)
    return electromagnetic_torque(motor, current) - motor.viscous_drag * w - coulomb_friction(motor, w)


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
