"""Steady worm speed (Eqs 28-30 with a_w = 0, di/dt = 0) against a closed form and its symmetries."""

from __future__ import annotations

import dataclasses

import pytest

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.parameters import load_rig
from worm_model.physics.steady_state import steady_worm_speed, torque_surplus

RIG = load_rig()


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
