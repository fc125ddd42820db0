"""Contact forces from measured torques and accelerations (paper Eqs 19-23, reference section 5).

Sign conventions (fixed frame, used by every argument):
  tau_in     torque delivered to the worm shaft [N m], + drives + worm rotation
             (motor torque minus rotor inertia and motor drag: see motor.shaft_torque).
  tau_d      load torque on the gear shaft [N m], + opposes the gear rotation that goes
             with + worm rotation (worm-referenced; use dynamics.disturbance_from_gear_axis
             for a torque about the gear's own axis).
  omega_worm, alpha_worm  worm speed [rad/s] and acceleration [rad/s^2].
  alpha_gear gear acceleration [rad/s^2], worm-referenced (+ with + worm rotation).
The equations are solved in the frame of motion (modes.motion_sign); results are
frame-free: N >= 0, F_f > 0 opposes the sliding, s = +1 driving flank / -1 coast flank.

Textbook check: test/test_textbook_example.py reproduces the worked force and efficiency
analysis of Mott, Machine Elements in Mechanical Design, 4th ed., Example Problem 10-7, with
these functions; the textbook's W_x, W_r, W_t are :func:`mesh_force_components`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.modes import Flank, Mode, classify_mode, motion_sign
from worm_model.physics.units import BoolArray, FloatArray, IntArray

if TYPE_CHECKING:
    from worm_model.physics.parameters import Gearbox


@dataclass
class InternalForces:
    """Result of :func:`internal_forces`; all arrays of the broadcast input shape."""

    normal_force: FloatArray  # N >= 0 [N] (Eq. 21)
    friction_force: FloatArray  # F_f [N], > 0 opposes sliding (Eq. 22)
    mu: FloatArray  # F_f / N (Eq. 23); +-inf/NaN where N == 0
    flank: IntArray  # Flank: +1 driving, -1 coast, 0 none (N == 0 or invalid)
    mode: IntArray  # Mode from D and switching_torque; STANDSTILL if not valid
    switching_torque: FloatArray  # tau_sw used for the classification [N m]
    mu_valid: BoolArray  # valid and 0 <= mu <= mu_engagement_max (Remark 4)
    valid: BoolArray  # finite inputs and a moving worm


@dataclass
class MeshForceComponents:
    """Contact force resolved along the shafts (Shigley's W_x, W_y, W_z; Mott's W_tW, W_r, W_tG) [N].

    Magnitudes in the frame of motion (signs as in Eqs 19-20): the worm and gear shafts
    are perpendicular, so each tangential force on one member is the axial force on the other.
    """

    worm_tangential: FloatArray  # = gear axial: s N cos(phi_n) sin(lambda) + F_f cos(lambda); resists the worm [N]
    gear_tangential: FloatArray  # = worm axial: s N cos(phi_n) cos(lambda) - F_f sin(lambda); drives the gear [N]
    radial: FloatArray  # separating force N sin(phi_n), pushes the shafts apart [N]


def mesh_force_components(
    gearbox: Gearbox, normal_force: ArrayLike, friction_force: ArrayLike, flank: ArrayLike
) -> MeshForceComponents:
    """Tangential, axial and radial components of the contact force (the brackets of Eqs 19-20).

    Args:
        normal_force: N >= 0 [N]; friction_force: F_f [N], > 0 opposing the sliding;
        flank: s, +1 driving / -1 coast.
    Returns:
        :class:`MeshForceComponents`.  worm_tangential * r_w is the torque the mesh takes
        from the worm (T - J_w a_w), gear_tangential * r_g the torque it gives the gear
        (D + J_g a_g), both in the frame of motion.  The radial force is the same on
        either flank.
    """
    n, f, s = (np.asarray(x, dtype=float) for x in (normal_force, friction_force, flank))
    cphi = np.cos(gearbox.normal_pressure_angle)
    sl, cl = np.sin(gearbox.lead_angle), np.cos(gearbox.lead_angle)
    return MeshForceComponents(
        worm_tangential=s * n * cphi * sl + f * cl,
        gear_tangential=s * n * cphi * cl - f * sl,
        radial=n * np.sin(gearbox.normal_pressure_angle),
    )


def switching_torque(gearbox: Gearbox, no_load_input_torque: ArrayLike) -> FloatArray:
    """Quasi-static switching torque tau_sw = T_0 (r_g / r_w) tan(lambda) [N m] (section 5).

    The D (frame of motion) at which Eq. 21 gives N = 0 is -tau_sw.  T_0 is the input
    torque at that speed with no load, in the frame of motion (the drag the worm shaft
    needs to turn, >= 0).  In the pure model T_0 = 0 and tau_sw = 0; in data it comes
    from bearing/seal/churning drag read into F_f.
    """
    return np.asarray(no_load_input_torque, dtype=float) * np.tan(gearbox.lead_angle) / gearbox.radius_ratio


def internal_forces(
    gearbox: Gearbox,
    tau_in: ArrayLike,
    tau_d: ArrayLike,
    omega_worm: ArrayLike,
    alpha_worm: ArrayLike = 0.0,
    alpha_gear: ArrayLike | None = None,
    switching_torque: ArrayLike | None = None,
    *,
    worm_inertia: ArrayLike | None = None,
    gear_inertia: ArrayLike | None = None,
    eps: float = 1e-9,
) -> InternalForces:
    """Normal force, friction force and mu from torques and accelerations (Eqs 21-23).

    In the frame of motion, with A = (T - J_w a_w)/r_w and B = (D + J_g a_g)/r_g:
      Eq. 21  N = |A sin(lambda) + B cos(lambda)| / cos(phi_n),  s = sign(A sin(lambda) + B cos(lambda))
      Eq. 22  F_f = A cos(lambda) - B sin(lambda)
      Eq. 23  mu = F_f / N

    Args:
        gearbox: geometry; worm_inertia/gear_inertia default to gearbox.worm_inertia and
            gearbox.gear_inertia (the shafts alone: tau_in and tau_d are the torques at
            the couplings, see module docstring) [kg m^2].
        tau_in, tau_d, omega_worm, alpha_worm: see module docstring.
        alpha_gear: defaults to the kinematic ratio * alpha_worm (Eq. 27, worm-referenced).
        switching_torque: tau_sw >= 0 [N m] for the mode classification only; None means
            0 (the pure model, no pseudo-resistive band).  See :func:`switching_torque`.
        eps: |omega_worm| below this [rad/s] is standstill.
    Returns:
        InternalForces.  At standstill (|omega| < eps) the statics are still evaluated (the
        friction force is then the static one actually needed, sigma from tau_in) but
        mode = STANDSTILL and valid = False.  Non-finite input: NaN forces, flank 0,
        mode STANDSTILL, valid False.  Never raises for bad samples.
    """
    alpha_g_in = gearbox.ratio * np.asarray(alpha_worm, dtype=float) if alpha_gear is None else alpha_gear
    tsw_in = 0.0 if switching_torque is None else switching_torque
    jw_in = gearbox.worm_inertia if worm_inertia is None else worm_inertia
    jg_in = gearbox.gear_inertia if gear_inertia is None else gear_inertia
    t_in, t_d, w, a_w, a_g, tsw, jw, jg = np.broadcast_arrays(
        *(np.asarray(x, dtype=float) for x in (tau_in, tau_d, omega_worm, alpha_worm, alpha_g_in, tsw_in, jw_in, jg_in))
    )
    sigma = motion_sign(w, t_in, eps)
    D, signed_n, friction = _frame_forces(gearbox, sigma, t_in, t_d, a_w, a_g, jw, jg, *_trigonometry(gearbox))
    normal = np.abs(signed_n)
    with np.errstate(divide="ignore", invalid="ignore"):
        mu = friction / normal  # Eq. 23

    finite = np.isfinite(t_in) & np.isfinite(t_d) & np.isfinite(w) & np.isfinite(a_w) & np.isfinite(a_g)
    finite &= np.isfinite(tsw) & np.isfinite(jw) & np.isfinite(jg)
    valid = finite & (np.abs(w) >= eps)
    nan = np.full(valid.shape, np.nan)
    normal, friction, mu = (np.where(finite, x, nan) for x in (normal, friction, mu))
    flank = np.where(finite, np.sign(np.nan_to_num(signed_n)), Flank.NONE).astype(np.int8)
    mode = np.where(valid, classify_mode(D, tsw), Mode.STANDSTILL).astype(np.int8)
    mu_valid = valid & (mu >= 0.0) & (mu <= gearbox.mu_engagement_max)
    return InternalForces(
        normal_force=normal,
        friction_force=friction,
        mu=mu,
        flank=flank,
        mode=mode,
        switching_torque=tsw.copy(),
        mu_valid=np.asarray(mu_valid),
        valid=np.asarray(valid),
    )


def _trigonometry(gearbox: Gearbox) -> tuple[float, float, float]:
    """(sin(lambda), cos(lambda), cos(phi_n)) as floats (numpy's values, so both forms below agree)."""
    return (float(np.sin(gearbox.lead_angle)), float(np.cos(gearbox.lead_angle)),
            float(np.cos(gearbox.normal_pressure_angle)))


def _frame_forces(gearbox: Gearbox, sigma, tau_in, tau_d, alpha_worm, alpha_gear, worm_inertia, gear_inertia,
                  sl: float, cl: float, cphi: float):
    """Eqs 21-22 in the frame of motion: (D, s N, F_f). Plain arithmetic: floats or arrays.

    With A = (T - J_w a_w)/r_w and B = (D + J_g a_g)/r_g (T, D, a in the frame of motion
    sigma): s N = (A sin(lambda) + B cos(lambda)) / cos(phi_n), F_f = A cos(lambda) - B sin(lambda).
    Shared by :func:`internal_forces` (arrays) and :func:`internal_forces_float` (one sample).
    """
    D = sigma * tau_d
    A = (sigma * tau_in - worm_inertia * sigma * alpha_worm) / gearbox.worm_pitch_radius
    B = (D + gear_inertia * sigma * alpha_gear) / gearbox.gear_pitch_radius
    return D, (A * sl + B * cl) / cphi, A * cl - B * sl


def internal_forces_float(
    gearbox: Gearbox, tau_in: float, tau_d: float, omega_worm: float, alpha_worm: float, *,
    worm_inertia: float, gear_inertia: float, eps: float = 1e-9,
) -> tuple[float, float, float, int]:
    """:func:`internal_forces` for one sample of floats, in plain math: (N, F_f, mu, flank).

    alpha_gear is the kinematic ratio * alpha_worm (the default of internal_forces).
    Same operations in the same order (shared :func:`_frame_forces`), so the two agree
    bit for bit; mu = F_f / N is +-inf or NaN where N == 0, as numpy's division.
    Non-finite input: (NaN, NaN, NaN, Flank.NONE). For per-sample loops (the
    simulator's scalar truth), where the array form costs ~100 us per call.
    """
    values = (tau_in, tau_d, omega_worm, alpha_worm, worm_inertia, gear_inertia)
    if not all(math.isfinite(x) for x in values):
        return math.nan, math.nan, math.nan, int(Flank.NONE)
    if abs(omega_worm) >= eps:  # motion_sign
        sigma = 1.0 if omega_worm > 0.0 else -1.0
    else:
        sigma = -1.0 if tau_in < 0.0 else 1.0
    alpha_gear = gearbox.ratio * alpha_worm
    _, signed_n, friction = _frame_forces(gearbox, sigma, tau_in, tau_d, alpha_worm, alpha_gear, worm_inertia,
                                          gear_inertia, *_trigonometry(gearbox))
    normal = abs(signed_n)
    if normal != 0.0:
        mu = friction / normal
    else:  # x / +0.0 as numpy: +-inf, NaN for 0 / 0
        mu = math.nan if friction == 0.0 or friction != friction else math.copysign(math.inf, friction)
    flank = 1 if signed_n > 0.0 else (-1 if signed_n < 0.0 else 0)
    return normal, friction, mu, flank
