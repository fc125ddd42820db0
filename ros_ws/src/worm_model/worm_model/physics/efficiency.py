"""Flank factor, efficiencies and self-locking (physics reference section 6, paper Eqs 27-28).

mu is the tooth-thread friction coefficient, flank s = +1 (driving) or -1 (coast).
"""

from __future__ import annotations

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
