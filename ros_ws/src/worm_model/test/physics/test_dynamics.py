"""Eq. 28: accelerations consistent with Eqs 19-20, feedforward torque, power balance, breakaway."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.dynamics import (
    breakaway,
    disturbance_from_gear_axis,
    effective_worm_inertia,
    gear_velocity,
    inertia_at_flank_factor,
    load_per_flank,
    make_reflected_input_torque_float,
    reflected_input_torque,
    worm_acceleration,
)
from worm_model.physics.efficiency import flank_factor
from worm_model.physics.efficiency import forward_efficiency
from worm_model.physics.friction import sliding_velocity
from worm_model.physics.internal_forces import internal_forces, switching_torque
from worm_model.physics.modes import Mode
from worm_model.physics.parameters import load_rig

RIG = load_rig()
GB = RIG.gearbox
JW, JG = RIG.total_worm_inertia, RIG.total_gear_inertia


def test_worm_acceleration_satisfies_eqs_19_20() -> None:
    rng = np.random.default_rng(7)
    n = 2000
    mu = rng.uniform(0.01, 0.2, n)  # both sides of self-locking (0.094)
    tau_in = rng.normal(0, 0.05, n)
    tau_d = rng.normal(0, 0.5, n)
    omega = rng.choice([-1, 1], n) * rng.uniform(1, 400, n)
    alpha, flank = worm_acceleration(GB, mu, tau_in, tau_d, omega, JW, JG)
    assert set(np.unique(flank)) == {-1, 1}
    # back in the frame of motion: N from Eq. 20 must be >= 0 and Eq. 19 must hold
    sig = np.sign(omega)
    T, D, a = sig * tau_in, sig * tau_d, sig * alpha
    cphi, sl, cl = np.cos(GB.normal_pressure_angle), np.sin(GB.lead_angle), np.cos(GB.lead_angle)
    N = (JG * GB.ratio * a + D) / (GB.gear_pitch_radius * (flank * cphi * cl - mu * sl))
    assert np.all(N >= -1e-9)
    rhs19 = T - GB.worm_pitch_radius * (flank * N * cphi * sl + mu * N * cl)
    assert np.allclose(JW * a, rhs19, rtol=1e-9, atol=1e-12)
    # and Eqs 21-23 recover the same contact state from (tau, alpha)
    res = internal_forces(GB, tau_in, tau_d, omega, alpha, worm_inertia=JW, gear_inertia=JG)
    assert np.allclose(res.normal_force, N, rtol=1e-7, atol=1e-9)
    big = N > 1e-3
    assert np.allclose(res.mu[big], mu[big], rtol=1e-6)
    assert np.array_equal(res.flank[big], flank[big])


def test_reflected_input_torque_is_quasi_static_equilibrium() -> None:
    mu = 0.04
    tau_d = np.array([0.3, -0.3, 0.3, -0.3, 0.0])
    omega = np.array([100.0, 100.0, -100.0, -100.0, 50.0])
    tau_in = reflected_input_torque(GB, mu, tau_d, omega)
    alpha, _ = worm_acceleration(GB, mu, tau_in, tau_d, omega, JW, JG)
    assert np.allclose(alpha, 0.0, atol=1e-9)
    # resistive case: T_min = i D / eta (section 6)
    assert tau_in[0] == pytest.approx(GB.ratio * 0.3 / forward_efficiency(GB, mu))
    assert tau_in[3] == pytest.approx(-tau_in[0]) and tau_in[2] == pytest.approx(-tau_in[1])  # mirror images


def test_load_per_flank_inverts_the_input_torque() -> None:
    """Every (mu, tau_d, omega) is found again on the flank that carries it; in the self-locking V a driving
    torque has a second load on the other flank needing the same torque, and below the V's vertex none."""
    rng = np.random.default_rng(3)
    n = 4000
    mu = rng.uniform(0.01, 0.2, n)  # both sides of self-locking (0.094)
    tau_d = rng.normal(0, 0.4, n)
    omega = rng.choice([-1, 1], n) * rng.uniform(0.1, 400, n)
    tau_in = reflected_input_torque(GB, mu, tau_d, omega)
    driving, coast = load_per_flank(GB, mu, tau_in, omega)
    found = np.where(np.sign(omega) * tau_d >= 0, driving, coast)
    np.testing.assert_allclose(found, tau_d, rtol=1e-12, atol=1e-15)
    both = np.isfinite(driving) & np.isfinite(coast)
    assert both.any() and np.all(mu[both] > GB.self_locking_mu)
    for branch in (driving[both], coast[both]):
        np.testing.assert_allclose(reflected_input_torque(GB, mu[both], branch, omega[both]), tau_in[both],
                                   rtol=1e-12, atol=1e-15)
    # a self-locking box: no load at all needs less than the torque at D = 0 (0 N m), driving or braking
    none_d, none_c = load_per_flank(GB, 0.15, -0.01, 100.0)
    assert np.isnan(none_d) and np.isnan(none_c)


def test_the_float_twins_are_the_array_functions_to_the_bit() -> None:
    rng = np.random.default_rng(4)
    mu = rng.uniform(0.01, 0.2, 500)
    tau_d = np.concatenate([rng.normal(0, 0.4, 497), [0.0, -0.0, 0.2]])
    omega = np.concatenate([rng.choice([-1, 1], 497) * rng.uniform(0.1, 400, 497), [0.0, 150.0, -1e-12]])
    reflected = make_reflected_input_torque_float(GB)
    scalar = [reflected(float(m), float(t), float(w)) for m, t, w in zip(mu, tau_d, omega)]
    torque, factor, flank = (np.array(column) for column in zip(*scalar))
    np.testing.assert_array_equal(torque, reflected_input_torque(GB, mu, tau_d, omega))
    np.testing.assert_array_equal(factor, flank_factor(GB, mu, flank))
    j_eff = [inertia_at_flank_factor(GB, float(k), JW, JG) for k in factor]
    np.testing.assert_array_equal(j_eff, effective_worm_inertia(GB, mu, flank, JW, JG))


def test_self_locking_box_needs_driving_torque_under_aiding_load() -> None:
    assert reflected_input_torque(GB, 0.15, -0.3, 100.0) > 0  # mu > cos(phi_n) tan(lambda)
    assert reflected_input_torque(GB, 0.02, -0.3, 100.0) < 0  # back-drivable: the worm brakes


@pytest.mark.parametrize("hand, sigma", list(itertools.product((1, -1), (1, -1))))
def test_quasi_static_power_balance_each_mode(hand: int, sigma: int) -> None:
    """tau_in omega_w = tau_d omega_g + F_f v_s with a_w = 0 (worm-referenced gear speed i omega_w)."""
    gb = replace(GB, hand=hand)
    mu, omega = 0.05, sigma * 150.0
    t0 = 0.01  # worm drag read as input torque: gives the pseudo-resistive band
    tsw = switching_torque(gb, t0)
    D = np.array([0.3, -0.5 * float(tsw), -0.3])
    tau_d = sigma * D
    tau_in = reflected_input_torque(gb, mu, tau_d, omega)
    tau_in[1] = sigma * t0
    res = internal_forces(gb, tau_in, tau_d, omega, 0.0, None, tsw)
    assert list(res.mode) == [Mode.RESISTIVE, Mode.PSEUDO_RESISTIVE, Mode.ASSISTIVE]
    assert list(res.flank) == [1, 1, -1]
    # physical gear-axis power equals the worm-referenced one
    omega_g_axis = gear_velocity(gb, omega)
    tau_axis = disturbance_from_gear_axis(gb, tau_d)
    assert np.allclose(-tau_axis * omega_g_axis, tau_d * gb.ratio * omega)
    balance = tau_d * gb.ratio * omega + res.friction_force * sliding_velocity(gb, omega)
    assert np.allclose(tau_in * omega, balance, rtol=1e-6)  # i = n/Z vs r_w tan(lambda)/r_g
    assert np.all(res.friction_force[[0, 2]] > 0)


def test_breakaway_self_locking() -> None:
    mu_s = 0.15  # > self_locking_mu = 0.094
    tau_d = 0.2  # load pushes the worm towards -
    t_min = float(reflected_input_torque(GB, mu_s, tau_d, 1.0))
    tau_in = np.array([0.0, 0.5 * t_min, 1.5 * t_min, -0.002, -0.05])
    assert list(breakaway(GB, mu_s, tau_in, tau_d, JW, JG)) == [0, 0, 1, 0, -1]


def test_breakaway_back_drivable_and_nan() -> None:
    out = breakaway(GB, 0.02, np.array([0.0, 0.0, np.nan]), np.array([0.2, -0.2, 0.2]), JW, JG)
    assert list(out) == [-1, 1, 0]


def test_breakaway_never_both_directions() -> None:
    rng = np.random.default_rng(3)
    n = 5000
    mu = rng.uniform(0.0, 0.3, n)
    t, d = rng.normal(0, 0.05, n), rng.normal(0, 0.5, n)
    from worm_model.physics.dynamics import _frame_acceleration

    a_p, _ = _frame_acceleration(GB, mu, t, d, JW, JG)
    a_m, _ = _frame_acceleration(GB, mu, -t, -d, JW, JG)
    assert not np.any((a_p > 0) & (a_m > 0))
