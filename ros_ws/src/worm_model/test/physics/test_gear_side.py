"""Gear-side drag of the load motors and the switching torque it causes (physics.md sections 3, 5)."""
from __future__ import annotations

import numpy as np

from worm_model.physics.dynamics import reflected_input_torque, worm_acceleration
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import (gear_side_drag, gear_side_load, make_gear_side_drag_float,
                                          no_load_switching_torque)
from worm_model.physics.modes import Flank
from worm_model.physics.parameters import load_rig

RIG = load_rig()
GB = RIG.gearbox
LOAD = RIG.load_motor
SPEEDS = np.array([-400.0, -150.0, -20.0, -0.5, 0.5, 20.0, 150.0, 400.0])


def test_drag_opposes_the_gear_motion_and_vanishes_at_rest() -> None:
    drag = gear_side_drag(RIG, SPEEDS)
    # positive load torque opposes positive rotation: the drag has the sign of the motion
    np.testing.assert_array_equal(np.sign(drag), np.sign(SPEEDS))
    assert gear_side_drag(RIG, 0.0) == 0.0
    omega_gear = GB.ratio * SPEEDS
    expected = RIG.load_motor_count * (LOAD.viscous_drag * omega_gear + LOAD.coulomb_drag * np.sign(omega_gear))
    np.testing.assert_allclose(drag, expected, rtol=1e-15)
    # the drag takes power out of the gear shaft at every speed
    assert np.all(drag * omega_gear > 0)


def test_the_float_drag_is_the_array_drag_to_the_bit() -> None:
    speeds = np.concatenate([SPEEDS, [0.0, -0.0, 1e-300, 123.456]])
    drag = make_gear_side_drag_float(RIG)
    np.testing.assert_array_equal([drag(float(w)) for w in speeds], gear_side_drag(RIG, speeds))


def test_gear_side_load_adds_drag_to_the_external_load() -> None:
    tau = np.linspace(-0.2, 0.2, SPEEDS.size)
    np.testing.assert_allclose(gear_side_load(RIG, tau, SPEEDS), tau + gear_side_drag(RIG, SPEEDS), rtol=1e-15)
    assert gear_side_load(RIG, 0.1, np.zeros(3)).shape == (3,)


def test_switching_torque_is_nonnegative_symmetric_and_grows_with_speed() -> None:
    speeds = np.linspace(0.1, 400.0, 50)
    tau_sw = no_load_switching_torque(RIG, speeds)
    assert np.all(tau_sw > 0)
    assert np.all(np.diff(tau_sw) > 0)  # viscous part: grows with speed (paper Fig. 8)
    np.testing.assert_allclose(no_load_switching_torque(RIG, -speeds), tau_sw, rtol=1e-15)
    # the low-speed limit is the load motors' Coulomb drag
    assert abs(no_load_switching_torque(RIG, 1e-9) - RIG.load_motor_count * LOAD.coulomb_drag) < 1e-12


def test_aiding_load_equal_to_switching_torque_unloads_the_mesh() -> None:
    sigma = np.sign(SPEEDS)
    tau_sw = no_load_switching_torque(RIG, SPEEDS)
    np.testing.assert_allclose(gear_side_load(RIG, -sigma * tau_sw, SPEEDS), 0.0, atol=1e-15)


def test_flank_changes_where_the_aiding_load_crosses_the_switching_torque() -> None:
    """Quasi-static operation (a_w = 0): driving flank just below tau_sw, coast flank just above."""
    sigma = np.sign(SPEEDS)
    tau_sw = no_load_switching_torque(RIG, SPEEDS)
    mu = friction_coefficient(RIG.friction, GB, SPEEDS)
    for factor, flank in ((0.9, Flank.DRIVING), (1.1, Flank.COAST)):
        mesh = gear_side_load(RIG, -factor * sigma * tau_sw, SPEEDS)
        tau_in = reflected_input_torque(GB, mu, mesh, SPEEDS)
        alpha, s = worm_acceleration(GB, mu, tau_in, mesh, SPEEDS, RIG.total_worm_inertia, RIG.total_gear_inertia)
        np.testing.assert_allclose(alpha, 0.0, atol=1e-9)
        np.testing.assert_array_equal(s, flank)
