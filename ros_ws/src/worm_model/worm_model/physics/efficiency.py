"""Flank factor, efficiencies and self-locking (physics reference section 6, paper Eqs 27-28).

mu is the tooth-thread friction coefficient, flank s = +1 (driving) or -1 (coast).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.units import BoolArray, FloatArray

if TYPE_CHECKING:
    from worm_model.physics.parameters import Gearbox


def flank_factor(gearbox: Gearbox, mu: ArrayLike, flank: ArrayLike) -> FloatArray:
    """K_s(mu) = (s cos(phi_n) sin(lambda) + mu cos(lambda)) / (s cos(phi_n) cos(lambda) - mu sin(lambda)).

    The factor of Eq. 28: the worm-side tangential force per unit gear-side tangential
    force.  K_+1 = tan(lambda + rho'), K_-1 = tan(lambda - rho') (see :func:`friction_angle`).
    Only meaningful for flank in {+1, -1} and, on the driving flank, mu < mu_engagement_max.
    """
    m = np.asarray(mu, dtype=float)
    s = np.asarray(flank, dtype=float)
    cphi = np.cos(gearbox.normal_pressure_angle)
    sl, cl = np.sin(gearbox.lead_angle), np.cos(gearbox.lead_angle)
    return (s * cphi * sl + m * cl) / (s * cphi * cl - m * sl)


def make_flank_factor_float(gearbox: Gearbox) -> Callable[[float, float], float]:
    """:func:`flank_factor` for one float mu and flank (+1.0 / -1.0), in plain math: for per-sample loops.

    Returns K(mu, flank) -> float. The gearbox's trigonometry is evaluated once, by numpy
    as flank_factor does, and the expression is flank_factor's with the same order of
    operations, so the two agree bit for bit (test_efficiency checks it).
    """
    cphi = float(np.cos(gearbox.normal_pressure_angle))
    sl, cl = float(np.sin(gearbox.lead_angle)), float(np.cos(gearbox.lead_angle))

    def factor(mu: float, flank: float) -> float:
        return (flank * cphi * sl + mu * cl) / (flank * cphi * cl - mu * sl)

    return factor


def friction_angle(gearbox: Gearbox, mu: ArrayLike) -> FloatArray:
    """Virtual friction angle rho' = atan(mu / cos(phi_n)) [rad] (section 6)."""
    return np.arctan(np.asarray(mu, dtype=float) / np.cos(gearbox.normal_pressure_angle))


def forward_efficiency(gearbox: Gearbox, mu: ArrayLike) -> FloatArray:
    """Worm driving the gear: eta = tan(lambda) / tan(lambda + rho') = tan(lambda) / K_+ (Eq. 28, a_w = 0)."""
    return np.tan(gearbox.lead_angle) / flank_factor(gearbox, mu, 1.0)


def backward_efficiency(gearbox: Gearbox, mu: ArrayLike) -> FloatArray:
    """Gear back-driving the worm: eta' = tan(lambda - rho') / tan(lambda) = K_- / tan(lambda).

    <= 0 means the gearbox self-locks (the load cannot back-drive the worm).
    """
    return flank_factor(gearbox, mu, -1.0) / np.tan(gearbox.lead_angle)


def is_self_locking(gearbox: Gearbox, mu: ArrayLike) -> BoolArray:
    """True where mu > cos(phi_n) tan(lambda), i.e. rho' > lambda (section 6)."""
    return np.asarray(np.asarray(mu, dtype=float) > gearbox.self_locking_mu)
