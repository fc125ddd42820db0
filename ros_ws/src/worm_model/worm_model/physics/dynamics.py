"""Coupled worm-gear dynamics (paper Eqs 26-28, reference section 6).

Sign conventions (fixed frame): tau_in [N m] on the worm shaft, + drives + worm rotation;
tau_d [N m] on the gear shaft, + opposes the gear rotation that goes with + worm rotation
(worm-referenced); omega_worm [rad/s], alpha_worm [rad/s^2].  Handedness h only maps the
gear's physical sign: omega_gear = h i omega_worm (Eqs 26-27).  Internally everything is
solved in the frame of motion (modes.motion_sign), where Eq. 28 reads

    (J_w + J_g i (r_w/r_g) K_s) a_w = T - (r_w/r_g) K_s D,   K_s = efficiency.flank_factor.

The engaged flank s is the one for which the contact force it implies,
N = (J_g i a_w + D) / (r_g (s cos(phi_n) cos(lambda) - mu sin(lambda))), is >= 0.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.efficiency import flank_factor, make_flank_factor_float
from worm_model.physics.modes import motion_sign
from worm_model.physics.units import FloatArray, IntArray

if TYPE_CHECKING:
    from worm_model.physics.parameters import Gearbox


def gear_velocity(gearbox: Gearbox, omega_worm: ArrayLike) -> FloatArray:
    """Physical gear speed about the gear's own axis, omega_g = h i omega_w [rad/s] (Eqs 26-27).

    Also maps accelerations (alpha_g = h i alpha_w) and angles (theta_g = h i theta_w).
    """
    return gearbox.hand * gearbox.ratio * np.asarray(omega_worm, dtype=float)


def disturbance_from_gear_axis(gearbox: Gearbox, tau_gear_axis: ArrayLike) -> FloatArray:
    """Worm-referenced load torque tau_d = -h tau from a torque applied to the gear about its own axis [N m].

    A torque tau (+ along the gear axis, e.g. the load motors' shaft torque) opposes the
    worm-referenced + rotation (which is h along the gear axis) when h tau < 0.  The map is
    its own inverse.
    """
    return -gearbox.hand * np.asarray(tau_gear_axis, dtype=float)


def _normal_force_sign_ok(gearbox: Gearbox, mu: FloatArray, flank: float, gear_side: FloatArray) -> FloatArray:
    """Whether N = gear_side / (r_g (s cos(phi_n) cos(lambda) - mu sin(lambda))) >= 0 (Eq. 20)."""
    den = flank * np.cos(gearbox.normal_pressure_angle) * np.cos(gearbox.lead_angle) - mu * np.sin(gearbox.lead_angle)
    return gear_side * den >= 0.0


def effective_worm_inertia(gearbox: Gearbox, mu: ArrayLike, flank: ArrayLike, worm_inertia: ArrayLike,
                           gear_inertia: ArrayLike) -> FloatArray:
    """Inertia the worm's torque accelerates, the bracket of Eq. 28 [kg m^2].

    J_w + J_g * i * (r_w / r_g) * K_s(mu), with worm_inertia / gear_inertia the total
    inertias on each shaft [kg m^2] and flank s = +1 driving / -1 coast.
    """
    K = flank_factor(gearbox, mu, flank)
    return inertia_at_flank_factor(gearbox, K, np.asarray(worm_inertia, dtype=float),
                                   np.asarray(gear_inertia, dtype=float))


def inertia_at_flank_factor(gearbox: Gearbox, factor, worm_inertia, gear_inertia):
    """:func:`effective_worm_inertia` for a flank factor K_s already known [kg m^2]: J_w + J_g i (r_w/r_g) K_s.

    Plain arithmetic in the same order: floats give a float (a per-sample loop that has K_s pays no
    numpy call), arrays broadcast.
    """
    return worm_inertia + gear_inertia * gearbox.ratio * gearbox.radius_ratio * factor


def _frame_acceleration(
    gearbox: Gearbox, mu: ArrayLike, T: ArrayLike, D: ArrayLike, jw: ArrayLike, jg: ArrayLike
) -> tuple[FloatArray, IntArray]:
    """Eq. 28 in the frame of motion with the self-consistent flank: (a_w, s).

    Try s = +1 and keep it where the implied N >= 0, else s = -1 where consistent.
    With positive effective inertias exactly one flank is consistent (N has the sign of
    J_g i T + J_w D for both).  Where neither is (only possible for a very large gear
    inertia with a self-locking mu, or mu beyond mu_engagement_max) s = sign(D), +1 at D = 0.
    """
    m, t, d, j_w, j_g = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (mu, T, D, jw, jg)))
    k, i = gearbox.radius_ratio, gearbox.ratio
    result = []
    for s in (1.0, -1.0):
        K = flank_factor(gearbox, m, s)
        a = (t - k * K * d) / effective_worm_inertia(gearbox, m, s, j_w, j_g)
        result.append((a, _normal_force_sign_ok(gearbox, m, s, j_g * i * a + d)))
    (a_p, ok_p), (a_m, ok_m) = result
    fallback = np.where(d >= 0.0, 1, -1)
    s_arr = np.where(ok_p, 1, np.where(ok_m, -1, fallback)).astype(np.int8)
    return np.where(s_arr == 1, a_p, a_m), s_arr


def reflected_input_torque(gearbox: Gearbox, mu: ArrayLike, tau_d: ArrayLike, omega_worm: ArrayLike) -> FloatArray:
    """Quasi-static input torque to keep the worm moving against tau_d (Eq. 28, a_w = 0) [N m, fixed frame].

    T = (r_w/r_g) K_s(mu) D with s = +1 if D >= 0 else -1 (D = sigma tau_d), tau_in = sigma T,
    sigma = sign(omega_worm) (+1 at omega = 0: pass the intended direction's sign as
    omega for feedforward from rest).  For s = +1 this is i D / eta (forward efficiency).
    An aiding load (D < 0) on a self-locking box still needs a driving torque (T > 0).
    Requires mu < gearbox.mu_engagement_max.
    """
    sigma = motion_sign(omega_worm)
    D = sigma * np.asarray(tau_d, dtype=float)
    s = np.where(D >= 0.0, 1.0, -1.0)
    return sigma * gearbox.radius_ratio * flank_factor(gearbox, mu, s) * D


def make_reflected_input_torque_float(gearbox: Gearbox) -> Callable[[float, float, float], tuple[float, float, int]]:
    """:func:`reflected_input_torque` for one float mu, tau_d [N m] and omega_worm [rad/s], in plain math: for
    per-sample loops. Returns (tau_in [N m, fixed frame], K_s, flank s: +1 driving / -1 coast).

    The same operations in the same order (the flank factor's float twin agrees with flank_factor bit for
    bit), with motion_sign's rule: speeds within 1e-9 rad/s of 0 count as positive.
    """
    factor = make_flank_factor_float(gearbox)
    ratio = gearbox.radius_ratio

    def torque(mu: float, tau_d: float, omega_worm: float) -> tuple[float, float, int]:
        sigma = -1.0 if omega_worm <= -1e-9 else 1.0
        d = sigma * tau_d
        flank = 1 if d >= 0.0 else -1
        k = factor(mu, float(flank))
        return sigma * ratio * k * d, k, flank

    return torque


def load_per_flank(gearbox: Gearbox, mu: ArrayLike, tau_in: ArrayLike, omega_worm: ArrayLike
                   ) -> tuple[FloatArray, FloatArray]:
    """Eq. 28 quasi-statically, inverted: the gear-side load [N m, fixed frame] that needs the input torque
    tau_in [N m] at this speed, per flank: (driving, coast), NaN where that flank cannot carry it.

    The inverse of :func:`reflected_input_torque`: sigma tau_in = (r_w/r_g) K_s D, so D = sigma tau_in /
    ((r_w/r_g) K_s) on the driving flank where that gives D >= 0 and on the coast flank where it gives
    D < 0. In a self-locking box (K_- < 0) both hold for a driving torque: two loads need the same input
    torque (the V of physics.md section 8); an input torque below the V's vertex (D = 0) has neither.
    """
    w = np.asarray(omega_worm, dtype=float)
    sigma = motion_sign(w)
    x = sigma * np.asarray(tau_in, dtype=float) / gearbox.radius_ratio  # = K_s D
    with np.errstate(divide="ignore", invalid="ignore"):
        d_plus = x / flank_factor(gearbox, mu, 1.0)
        d_minus = x / flank_factor(gearbox, mu, -1.0)
    driving = np.where(d_plus >= 0, sigma * d_plus, np.nan)
    coast = np.where((d_minus < 0) & np.isfinite(d_minus), sigma * d_minus, np.nan)
    return driving, coast


def worm_acceleration(
    gearbox: Gearbox,
    mu: ArrayLike,
    tau_in: ArrayLike,
    tau_d: ArrayLike,
    omega_worm: ArrayLike,
    worm_inertia: ArrayLike,
    gear_inertia: ArrayLike,
) -> tuple[FloatArray, IntArray]:
    """Worm acceleration of a moving worm, Eq. 28 in the fixed frame.

    Args:
        mu: kinetic friction coefficient (e.g. friction.friction_coefficient).
        tau_in, tau_d, omega_worm: see module docstring.
        worm_inertia, gear_inertia: TOTAL inertia on each shaft [kg m^2]
            (a simulator passes rig.total_worm_inertia and rig.total_gear_inertia).
    Returns:
        (alpha_worm [rad/s^2, fixed frame], flank s: +1 driving / -1 coast), chosen
        self-consistently (see module docstring; fallback s = sign(D)).  For a worm at
        rest use :func:`breakaway` first: here sigma would come from tau_in.
    """
    sigma = motion_sign(omega_worm, tau_in)
    T = sigma * np.asarray(tau_in, dtype=float)
    D = sigma * np.asarray(tau_d, dtype=float)
    a, s = _frame_acceleration(gearbox, mu, T, D, worm_inertia, gear_inertia)
    return sigma * a, s


def breakaway(
    gearbox: Gearbox,
    mu_static: ArrayLike,
    tau_in: ArrayLike,
    tau_d: ArrayLike,
    worm_inertia: ArrayLike,
    gear_inertia: ArrayLike,
) -> IntArray:
    """Whether a worm at rest starts to move under tau_in, tau_d, and which way.

    Both frames are tested: motion in direction sigma is possible when Eq. 28 with
    friction mu_static opposing that motion gives a_w > 0 in that frame.  With positive
    effective inertias friction makes at most one direction possible (if a degenerate
    case allows both, the larger acceleration wins).

    Returns:
        int8 array: +1, -1, or 0 (stays stuck; also for NaN input).
    """
    t = np.asarray(tau_in, dtype=float)
    d = np.asarray(tau_d, dtype=float)
    a_p, _ = _frame_acceleration(gearbox, mu_static, t, d, worm_inertia, gear_inertia)
    a_m, _ = _frame_acceleration(gearbox, mu_static, -t, -d, worm_inertia, gear_inertia)
    return np.where((a_p > 0.0) & (a_p >= a_m), 1, np.where(a_m > 0.0, -1, 0)).astype(np.int8)
