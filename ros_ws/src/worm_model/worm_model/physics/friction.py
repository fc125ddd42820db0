"""Tooth-thread friction coefficient mu (paper: the mu of Eqs 19-23, 28).

Conventions: omega_worm [rad/s] signed; sliding velocity [m/s] is a magnitude.
Models are a registry (:data:`FRICTION_MODELS`): ``Friction.model`` names one.
"""

from __future__ import annotations

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


class Gearbox(Protocol):
    """The pitch geometry the sliding speed needs (``worm_model.physics.parameters.Gearbox`` is one)."""

    worm_pitch_radius: float  # [m]
    lead_angle: float  # [rad]

#: 1 ft/min in m/s
FT_PER_MIN = 0.3048 / 60.0


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
    low = 0.124 * np.exp(-0.074 * v**0.645)
    high = 0.103 * np.exp(-0.110 * v**0.450) + 0.012
    return np.where(v == 0.0, 0.15, np.where(v <= 10.0, low, high))


def _agma(friction: Friction, v_sliding: FloatArray) -> FloatArray:
    return friction.scale * agma_friction_coefficient(v_sliding)


def _constant(friction: Friction, v_sliding: FloatArray) -> FloatArray:
    return np.where(np.isnan(v_sliding), np.nan, friction.mu_constant)


#: model name -> mu(friction parameters, sliding velocity [m/s])
FRICTION_MODELS: dict[str, Callable[[Friction, FloatArray], FloatArray]] = {
    "agma": _agma,
    "constant": _constant,
}


def friction_coefficient(friction: Friction, gearbox: Gearbox, omega_worm: ArrayLike) -> FloatArray:
    """mu at worm speed omega_worm [rad/s] under the rig's friction model.

    "agma": scale * agma_friction_coefficient(sliding_velocity); "constant": mu_constant.

    Raises:
        KeyError: unknown model (load_rig rejects it earlier with a ParameterError).
    """
    return FRICTION_MODELS[friction.model](friction, sliding_velocity(gearbox, omega_worm))
