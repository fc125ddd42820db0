"""Eqs 19-23: round trip through the paper's 12 configurations, vectorisation, NaN handling."""

from __future__ import annotations

import itertools
import warnings
from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.dynamics import disturbance_from_gear_axis
from worm_model.physics.internal_forces import internal_forces, internal_forces_float, switching_torque
from worm_model.physics.modes import Flank, Mode, classify_mode, motion_sign
from worm_model.physics.parameters import load_rig

GB = load_rig().gearbox
JW, JG = 1.4e-5, 6.5e-5  # total inertias [kg m^2]
TSW = 0.05  # switching torque used to classify [N m]


def forward_eqs_19_20(N, mu, s, a_w, a_g, jw=JW, jg=JG):
    """Eqs 19-20 in the frame of motion -> (T, D), written out independently of the package."""
    cphi, sl, cl = np.cos(GB.normal_pressure_angle), np.sin(GB.lead_angle), np.cos(GB.lead_angle)
    F = mu * N
    T = jw * a_w + GB.worm_pitch_radius * (s * N * cphi * sl + F * cl)
    D = GB.gear_pitch_radius * (s * N * cphi * cl - F * sl) - jg * a_g
    return T, D


# (mode, N [N], mu, flank, a_w [rad/s^2]) in the frame of motion; a_g = i a_w (kinematic)
CASES = {
    Mode.RESISTIVE: (200.0, 0.05, 1, 10.0),
    Mode.PSEUDO_RESISTIVE: (0.5, 0.06, 1, 9000.0),  # load aids, but the gear inertia keeps the driving flank
    Mode.ASSISTIVE: (100.0, 0.04, -1, -20.0),
}


@pytest.mark.parametrize(
    "hand, sigma, mode", list(itertools.product((1, -1), (1, -1), CASES)), ids=lambda v: str(v)
)
def test_round_trip_twelve_configurations(hand: int, sigma: int, mode: Mode) -> None:
    gb = replace(GB, hand=hand)
    N, mu, s, a_w = CASES[mode]
    T, D = forward_eqs_19_20(N, mu, s, a_w, gb.ratio * a_w)
    assert classify_mode(D, TSW) == mode  # the case really is in that mode
    # fixed frame: the worm turns sigma-wise; the load motors act about the gear axis
    tau_gear_axis = -hand * sigma * D
    tau_d = disturbance_from_gear_axis(gb, tau_gear_axis)
    res = internal_forces(
        gb, sigma * T, tau_d, sigma * 50.0, sigma * a_w, None, TSW, worm_inertia=JW, gear_inertia=JG
    )
    assert res.normal_force == pytest.approx(N, rel=1e-9)
    assert res.friction_force == pytest.approx(mu * N, rel=1e-9)
    assert res.mu == pytest.approx(mu, rel=1e-9)
    assert res.flank == s
    assert res.mode == mode
    assert res.valid and res.mu_valid


def test_vectorised_equals_per_sample() -> None:
    rng = np.random.default_rng(1)
    n = 500
    args = (
        rng.normal(0, 0.05, n),
        rng.normal(0, 0.3, n),
        rng.choice([-1, 1], n) * rng.uniform(1, 400, n),
        rng.normal(0, 50, n),
        rng.normal(0, 2, n),
        rng.uniform(0, 0.1, n),
    )
    vec = internal_forces(GB, *args)
    for k in range(0, n, 37):
        one = internal_forces(GB, *(a[k] for a in args))
        for name in ("normal_force", "friction_force", "mu", "flank", "mode", "mu_valid", "valid"):
            assert getattr(vec, name)[k] == pytest.approx(getattr(one, name)), name
    assert vec.normal_force.shape == (n,)
    assert np.all(vec.normal_force >= 0)


def test_broadcasting_scalar_and_array() -> None:
    res = internal_forces(GB, 0.02, np.linspace(-0.5, 0.5, 7), 100.0)
    assert res.mode.shape == (7,) and res.switching_torque.shape == (7,)
    assert list(res.mode[:3]) == [Mode.ASSISTIVE] * 3 and list(res.mode[4:]) == [Mode.RESISTIVE] * 3


def test_nan_in_nan_out_never_raises() -> None:
    tau_in = np.array([0.02, np.nan, 0.02, 0.02])
    omega = np.array([100.0, 100.0, np.inf, 100.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = internal_forces(GB, tau_in, 0.3, omega, alpha_gear=np.array([0, 0, 0, np.nan]))
    assert list(res.valid) == [True, False, False, False]
    assert np.isfinite(res.normal_force[0])
    assert np.all(np.isnan(res.normal_force[1:])) and np.all(np.isnan(res.mu[1:]))
    assert list(res.flank[1:]) == [Flank.NONE] * 3
    assert list(res.mode[1:]) == [Mode.STANDSTILL] * 3
    assert not res.mu_valid[1:].any()


def test_standstill_is_flagged_but_statics_evaluated() -> None:
    res = internal_forces(GB, -0.01, 0.2, 0.0)
    assert res.mode == Mode.STANDSTILL and not res.valid and not res.mu_valid
    assert np.isfinite(res.normal_force) and res.normal_force > 0


def test_mu_out_of_remark4_bounds_is_flagged() -> None:
    # no load, only drag on the worm: N from Eq. 21 is tiny and mu blows up (section 5)
    res = internal_forces(GB, 0.01, -0.9 * switching_torque(GB, 0.01), 100.0)
    assert res.valid and res.mu > GB.mu_engagement_max and not res.mu_valid


def test_switching_torque_is_where_n_vanishes() -> None:
    t0 = np.array([0.005, 0.01, 0.02])
    tsw = switching_torque(GB, t0)
    res = internal_forces(GB, t0, -tsw, 100.0)
    assert np.allclose(res.normal_force, 0.0, atol=1e-9)
    assert np.allclose(tsw, t0 * GB.gear_pitch_radius / GB.worm_pitch_radius * np.tan(GB.lead_angle))


def test_motion_sign() -> None:
    sig = motion_sign([2.0, -2.0, 0.0, 0.0, 0.0, 1e-12, np.nan], [-1.0, 1.0, -1.0, 1.0, 0.0, -3.0, 1.0])
    assert list(sig[:6]) == [1, -1, -1, 1, 1, -1] and np.isnan(sig[6])


def test_classify_mode_boundaries() -> None:
    modes = classify_mode([0.1, 0.0, -0.05, -0.051, np.nan], 0.05)
    assert list(modes) == [Mode.RESISTIVE, Mode.PSEUDO_RESISTIVE, Mode.PSEUDO_RESISTIVE, Mode.ASSISTIVE,
                           Mode.STANDSTILL]


def test_mesh_power_balance_with_accelerations_every_mode() -> None:
    """Power into the mesh = power out to the gear + F_f v_s, sample by sample (Eqs 19-22).

    (tau_in - J_w alpha_w) omega_w = (tau_d + J_g alpha_g) omega_g + F_f v_s, with
    omega_g = r_w tan(lambda)/r_g omega_w; holds in every mode and on both flanks, also when
    accelerating (the quasi-static case is in test_dynamics.py).
    """
    from worm_model.physics.friction import sliding_velocity

    rng = np.random.default_rng(11)
    n = 3000
    tau_in, tau_d = rng.normal(0, 0.05, n), rng.normal(0, 0.4, n)
    omega = rng.choice([-1, 1], n) * rng.uniform(1, 400, n)
    alpha_w, alpha_g = rng.normal(0, 300, n), rng.normal(0, 10, n)
    res = internal_forces(GB, tau_in, tau_d, omega, alpha_w, alpha_g, TSW, worm_inertia=JW, gear_inertia=JG)
    assert set(np.unique(res.mode)) == {Mode.RESISTIVE, Mode.PSEUDO_RESISTIVE, Mode.ASSISTIVE}
    assert set(np.unique(res.flank)) == {-1, 1}
    p_in = (tau_in - JW * alpha_w) * omega
    p_out = (tau_d + JG * alpha_g) * GB.geometric_ratio * omega
    p_friction = res.friction_force * sliding_velocity(GB, omega)
    assert np.allclose(p_in, p_out + p_friction, rtol=1e-9, atol=1e-12)


def test_the_float_form_is_the_array_form_bit_for_bit() -> None:
    """internal_forces_float (one sample, plain math) against internal_forces, incl. standstill, N = 0, NaN."""
    rng = np.random.default_rng(8)
    n = 3000
    tau_in, tau_d = rng.normal(0, 0.05, n), rng.normal(0, 0.3, n)
    omega, alpha = rng.normal(0, 100, n), rng.normal(0, 500, n)
    omega[:200] = 0.0  # standstill: sigma from tau_in
    tau_in[200:300], tau_d[200:300], alpha[200:300] = 0.0, 0.0, 0.0  # N = F_f = 0: mu NaN
    tau_d[300], omega[301] = np.nan, np.inf
    jw, jg = 2e-5, 3e-4
    ref = internal_forces(GB, tau_in, tau_d, omega, alpha, worm_inertia=jw, gear_inertia=jg)
    got = np.array([internal_forces_float(GB, *map(float, x), worm_inertia=jw, gear_inertia=jg)
                    for x in zip(tau_in, tau_d, omega, alpha)])
    for k, name in enumerate(("normal_force", "friction_force", "mu", "flank")):
        np.testing.assert_array_equal(got[:, k], getattr(ref, name), err_msg=name)
