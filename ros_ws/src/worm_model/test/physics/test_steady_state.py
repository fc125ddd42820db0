"""Steady worm speed (Eqs 28-30 with a_w = 0, di/dt = 0) against a closed form and its symmetries."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.efficiency import forward_efficiency
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.parameters import load_rig
from worm_model.physics.steady_state import (balancing_torque, make_balancing_torque_float, steady_worm_speed,
                                             torque_surplus)

RIG = load_rig()
GB = RIG.gearbox


def test_constant_mu_speed_is_the_root_of_the_linear_balance() -> None:
    """With a constant mu the balance is linear in w (w > 0), so its root is known in closed form."""
    rig = dataclasses.replace(RIG, friction=dataclasses.replace(RIG.friction, model="constant", mu_constant=0.05))
    m, lm, n = rig.drive_motor, rig.load_motor, rig.load_motor_count
    k = float(reflected_input_torque(rig.gearbox, 0.05, 1.0, 1.0))  # input torque per N m of resisting load
    voltage, tau = 12.0, 0.2
    # K_t (V - K_e w)/R - b w - c = k (tau + n (b_l i w + c_l)),  i = gear ratio
    slope = m.torque_constant * m.back_emf_constant / m.resistance + m.viscous_drag \
        + k * n * lm.viscous_drag * rig.gearbox.ratio
    offset = m.torque_constant * voltage / m.resistance - m.coulomb_drag - k * (tau + n * lm.coulomb_drag)
    assert steady_worm_speed(rig, voltage, tau) == pytest.approx(offset / slope, rel=1e-9)


@pytest.mark.parametrize("voltage, tau", [(12.0, 0.2), (12.0, -0.15), (20.0, 0.05), (6.0, 0.1)])
def test_speed_zeroes_the_surplus_and_mirrors_with_voltage_and_load(voltage: float, tau: float) -> None:
    w = steady_worm_speed(RIG, voltage, tau)
    assert 0.0 < w < voltage / RIG.drive_motor.back_emf_constant
    assert torque_surplus(RIG, voltage, tau, w) == pytest.approx(0.0, abs=1e-9)
    assert torque_surplus(RIG, voltage, tau, 0.9 * w) > 0.0  # slower: the motor wins, the worm speeds up
    assert steady_worm_speed(RIG, -voltage, -tau) == pytest.approx(-w, rel=1e-9)


def test_more_load_is_slower() -> None:
    assert steady_worm_speed(RIG, 12.0, 0.3) < steady_worm_speed(RIG, 12.0, 0.1) < steady_worm_speed(RIG, 12.0, 0.0)


def test_zero_voltage_is_refused() -> None:
    with pytest.raises(ValueError, match="voltage 0"):
        steady_worm_speed(RIG, 0.0, 0.1)


# --- the torque that balances a load (what a speed loop feeds forward) ---------------------------

def test_balancing_torque_is_i_d_over_eta_for_resistive_loads_in_both_directions() -> None:
    omega = np.array([20.0, 150.0, 400.0, -20.0, -150.0, -400.0])
    tau = np.array([0.05, 0.2, 0.27, -0.05, -0.2, -0.27])  # opposing the motion in every case
    mu = friction_coefficient(RIG.friction, GB, omega)
    expected = np.sign(omega) * GB.ratio * np.abs(tau) / forward_efficiency(GB, mu)  # T_min = i D / eta
    # (r_w/r_g) K_+ = i / eta holds to the geometric consistency of i = r_w tan(lambda) / r_g
    # (the bundled lead angle is rounded to 1e-6 deg: ~2e-8 relative)
    assert abs(GB.geometric_ratio / GB.ratio - 1) < 1e-7
    np.testing.assert_allclose(balancing_torque(RIG, tau, omega), expected, rtol=1e-6)


def test_balancing_torque_of_nan_load_is_zero() -> None:
    ff = balancing_torque(RIG, np.array([np.nan, 0.1, np.nan]), np.array([100.0, 100.0, -50.0]))
    assert np.all(np.isfinite(ff))
    assert ff[0] == 0.0 and ff[2] == 0.0 and ff[1] > 0.0


def test_the_float_balancing_torque_equals_the_array_one() -> None:
    rng = np.random.default_rng(5)
    loads = np.concatenate([rng.uniform(-0.3, 0.3, 400), [0.0, -0.0, 0.2, -0.2]])
    speeds = np.concatenate([rng.uniform(-450, 450, 400), [0.0, 150.0, -150.0, 1e-12]])
    torque = make_balancing_torque_float(RIG)
    scalar = np.array([torque(float(t), float(w)) for t, w in zip(loads, speeds)])
    np.testing.assert_allclose(scalar, balancing_torque(RIG, loads, speeds), rtol=1e-14, atol=1e-18)
    assert torque(float("nan"), 100.0) == 0.0
