"""Make a live sample fit a quasi-static map: take the inertia's share out of the current.

The calibration map (omega, i) -> tau_d holds at constant speed. While the worm
accelerates, part of the armature current only accelerates the inertia
(Eq. 28: K_t*i = ... + J_eff*alpha_w); left in, the map reads it as load
(physics.md section 8). Worse, a controller that feeds the estimate forward
then closes a loop of gain ~1 through the current (more feedforward -> more
current -> larger estimate). Removing J_eff*alpha/K_t breaks that loop: extra
current that accelerates the rig is not taken for load.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from worm_model.physics.dynamics import effective_worm_inertia, inertia_at_flank_factor
from worm_model.physics.efficiency import make_flank_factor_float
from worm_model.physics.friction import friction_coefficient, make_friction_coefficient_float
from worm_model.physics.parameters import Rig


def inertia_free_current(rig: Rig, current, omega_worm, alpha_worm) -> np.ndarray:
    """Drive current [A] the rig would draw at this speed and load without accelerating.

    Args:
        current: measured drive current [A]; omega_worm [rad/s]; alpha_worm [rad/s^2]
            (all fixed frame, positive = positive worm rotation).
    The effective inertia is taken on the driving flank; on the paper's rig the
    gear's reflected share is below 1 % of the worm-side inertia either way.
    """
    mu = friction_coefficient(rig.friction, rig.gearbox, omega_worm)
    inertia = effective_worm_inertia(rig.gearbox, mu, 1, rig.total_worm_inertia, rig.total_gear_inertia)
    return np.asarray(current, dtype=float) - inertia * np.asarray(alpha_worm, dtype=float) \
        / rig.drive_motor.torque_constant


def make_inertia_free_current_float(rig: Rig) -> Callable[[float, float, float], float]:
    """:func:`inertia_free_current` for one float sample (current [A], omega_worm [rad/s], alpha_worm
    [rad/s^2]), in plain math: the per-sample path of LiveEstimator. It agrees with the numpy function to
    round-off (worm_model's float twins of mu and K_s), at well under a microsecond instead of ~40."""
    mu = make_friction_coefficient_float(rig.friction, rig.gearbox)
    factor = make_flank_factor_float(rig.gearbox)
    gearbox, k_t = rig.gearbox, rig.drive_motor.torque_constant
    worm, gear = rig.total_worm_inertia, rig.total_gear_inertia

    def current(current: float, omega_worm: float, alpha_worm: float) -> float:
        inertia = inertia_at_flank_factor(gearbox, factor(mu(omega_worm), 1.0), worm, gear)
        return current - inertia * alpha_worm / k_t

    return current
