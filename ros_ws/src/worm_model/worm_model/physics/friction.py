"""Tooth-thread friction coefficient mu (paper: the mu of Eqs 19-23, 28).

Conventions: omega_worm [rad/s] signed; sliding velocity [m/s] is a magnitude.
Models are a registry (:data:`FRICTION_MODELS`): ``Friction.model`` names one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.units import FloatArray


class Friction(Protocol):
    """What a friction model reads (``worm_model.physics.parameters.Friction`` is one)."""

    model: str
    mu_constant: float  # [-]
    scale: float  # [-]
    stribeck_rise: float  # [-]
    stribeck_speed: float  # [m/s]


class Gearbox(Protocol):
    """The pitch geometry the sliding speed needs (``worm_model.physics.parameters.Gearbox`` is one)."""

    worm_pitch_radius: float  # [m]
    lead_angle: float  # [rad]

#: 1 ft/min in m/s
FT_PER_MIN = 0.3048 / 60.0

# AGMA fit (see agma_friction_coefficient), V_s in ft/min: f at rest; up to the break
# A exp(-B V^E); above it A exp(-B V^E) + C. Shared by the array and the float form.
_AGMA_REST = 0.15
_AGMA_BREAK = 10.0
_AGMA_LOW_A, _AGMA_LOW_B, _AGMA_LOW_E = 0.124, 0.074, 0.645
_AGMA_HIGH_A, _AGMA_HIGH_B, _AGMA_HIGH_E, _AGMA_HIGH_C = 0.103, 0.110, 0.450, 0.012


def sliding_velocity(gearbox: Gearbox, omega_worm: ArrayLike) -> FloatArray:
    """Sliding speed at the pitch point, V_s = |omega_w| r_w / cos(lambda) [m/s] (>= 0).

    Args:
        omega_worm: worm speed [rad/s], either sign.
    """
    return np.abs(np.asarray(omega_worm, dtype=float)) * gearbox.worm_pitch_radius / np.cos(gearbox.lead_angle)


def agma_friction_coefficient(v_sliding: ArrayLike) -> FloatArray:
    """AGMA worm-gear friction coefficient f(V_s), hardened steel worm on bronze gear.

    As published in Shigley's Mechanical Engineering Design (9th/10th ed., Eq. 15-38),
    with V_s in ft/min (converted here from m/s)::

        f = 0.15                                      V_s = 0
        f = 0.124 exp(-0.074 V_s^0.645)               0 < V_s <= 10 ft/min
        f = 0.103 exp(-0.110 V_s^0.450) + 0.012       V_s > 10 ft/min

    Note: the middle branch carries no additive constant in the published form (the two
    branches then meet within 0.002 at 10 ft/min; with a "+0.013" they would jump by 0.015).

    Args:
        v_sliding: sliding velocity [m/s]; the magnitude is used.  NaN gives NaN.
    Returns:
        mu [-].
    """
    v = np.abs(np.asarray(v_sliding, dtype=float)) / FT_PER_MIN
    low = _AGMA_LOW_A * np.exp(-_AGMA_LOW_B * v**_AGMA_LOW_E)
    high = _AGMA_HIGH_A * np.exp(-_AGMA_HIGH_B * v**_AGMA_HIGH_E) + _AGMA_HIGH_C
    return np.where(v == 0.0, _AGMA_REST, np.where(v <= _AGMA_BREAK, low, high))


def agma_friction_coefficient_float(v_sliding: float) -> float:
    """:func:`agma_friction_coefficient` for one float, in plain math (no numpy): for per-sample loops.

    Same coefficients and branches; only the one branch needed is evaluated. numpy's
    vectorised exp and pow may differ from libm's in the last bit, so the two agree to
    round-off (about 1e-16 relative), not always bit for bit.
    """
    v = abs(v_sliding) / FT_PER_MIN
    if v == 0.0:
        return _AGMA_REST
    if v <= _AGMA_BREAK:
        return _AGMA_LOW_A * math.exp(-_AGMA_LOW_B * v**_AGMA_LOW_E)
    return _AGMA_HIGH_A * math.exp(-_AGMA_HIGH_B * v**_AGMA_HIGH_E) + _AGMA_HIGH_C


def _agma(friction: Friction, v_sliding: FloatArray) -> FloatArray:
    return friction.scale * agma_friction_coefficient(v_sliding)


def _constant(friction: Friction, v_sliding: FloatArray) -> FloatArray:
    return np.where(np.isnan(v_sliding), np.nan, friction.mu_constant)


def stribeck_friction_coefficient(v_sliding: ArrayLike, mu_kinetic: float, rise: float, speed: float) -> FloatArray:
    """mu = mu_k + mu_s exp(-|V_s| / V_st)^2: the Stribeck law of Mablekos-Alexiou, da Cruz and Bergeles
    (IEEE T-RO 37(4), 2021), as their public scripts evaluate it (``Transmission.getFrictionCoeff`` and
    ``id_1dof_static.m``: ``kinFriction + strbFriction*exp(-abs(v)/strbVelocity)^2``, the square applied to
    the exponential). They write it in the worm's angular speed; here in the sliding speed V_s [m/s], so
    V_st = their velocity x r_w / cos(lambda).

    Args:
        v_sliding: sliding speed [m/s] (magnitude used); mu_kinetic, rise [-]; speed V_st [m/s] > 0.
    """
    v = np.abs(np.asarray(v_sliding, dtype=float))
    return mu_kinetic + rise * np.exp(-v / speed) ** 2


def _stribeck(friction: Friction, v_sliding: FloatArray) -> FloatArray:
    return friction.scale * stribeck_friction_coefficient(v_sliding, friction.mu_constant, friction.stribeck_rise,
                                                          friction.stribeck_speed)


#: model name -> mu(friction parameters, sliding velocity [m/s])
FRICTION_MODELS: dict[str, Callable[[Friction, FloatArray], FloatArray]] = {
    "agma": _agma,
    "constant": _constant,
    "stribeck": _stribeck,
}


def _agma_float(friction: Friction, v_sliding: float) -> float:
    return friction.scale * agma_friction_coefficient_float(v_sliding)


def _constant_float(friction: Friction, v_sliding: float) -> float:
    return math.nan if v_sliding != v_sliding else friction.mu_constant


def _stribeck_float(friction: Friction, v_sliding: float) -> float:
    decay = math.exp(-abs(v_sliding) / friction.stribeck_speed)
    return friction.scale * (friction.mu_constant + friction.stribeck_rise * decay**2)


#: the same models for one float (plain math; the simulator's scalar fast path):
#: model name -> mu(friction parameters, sliding velocity [m/s] as a float) as a float
FLOAT_FRICTION_MODELS: dict[str, Callable[[Friction, float], float]] = {
    "agma": _agma_float,
    "constant": _constant_float,
    "stribeck": _stribeck_float,
}


def friction_coefficient(friction: Friction, gearbox: Gearbox, omega_worm: ArrayLike) -> FloatArray:
    """mu at worm speed omega_worm [rad/s] under the rig's friction model.

    "agma": scale * agma_friction_coefficient(sliding_velocity); "constant": mu_constant;
    "stribeck": scale * stribeck_friction_coefficient(sliding_velocity, mu_constant, stribeck_rise, stribeck_speed).

    Raises:
        KeyError: unknown model (load_rig rejects it earlier with a ParameterError).
    """
    return FRICTION_MODELS[friction.model](friction, sliding_velocity(gearbox, omega_worm))


def make_friction_coefficient_float(friction: Friction, gearbox: Gearbox) -> Callable[[float], float]:
    """:func:`friction_coefficient` for one float omega_worm [rad/s], in plain math: for per-sample loops.

    Returns mu(omega_worm) -> float with the model and the pitch geometry bound once
    (cos(lambda) taken from numpy, as :func:`sliding_velocity` has it, so the sliding
    speed is the same to the bit). The law is FLOAT_FRICTION_MODELS', which agrees with
    FRICTION_MODELS' to round-off (libm's exp and pow against numpy's), not always bit
    for bit. A numpy call on one value costs ~5 us, the arithmetic well under 1 us.
    """
    law = FLOAT_FRICTION_MODELS[friction.model]
    r_w, cos_lead = gearbox.worm_pitch_radius, float(np.cos(gearbox.lead_angle))

    def mu(omega_worm: float) -> float:
        return law(friction, abs(omega_worm) * r_w / cos_lead)  # sliding_velocity's |w| r_w / cos(lambda)

    return mu
