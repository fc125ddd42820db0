"""measure_operating_points: quasi-static points on an ensemble of simulated rigs (physics.md section 8)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.simulated_rig import SimulatedRig
from torque_estimator.calibration.operating_points import SteadyStateCriterion, measure_operating_points
from worm_rig_driver.drive.speed_loop import PiGains, SpeedController

RIG = load_rig()
MOTOR = RIG.drive_motor
GAINS = PiGains(kp=2e-3, ki=0.05)
CRITERION = SteadyStateCriterion(window=0.2, settle_time=0.3, timeout=2.0)  # short, to keep the test fast
# resistive and assistive loads in both directions, low to high speed
SPEEDS = np.array([80.0, -80.0, 200.0, -200.0, 300.0, -150.0])
TORQUES = np.array([0.2, 0.2, -0.15, 0.1, 0.05, -0.2])


def _measure(rig=RIG, speeds=SPEEDS, torques=TORQUES, criterion=CRITERION, seed=1, progress=None):
    sim = SimulatedRig(rig, n=len(speeds), seed=seed)
    controller = SpeedController(rig, GAINS, n=len(speeds))
    return measure_operating_points(sim, controller, speeds, torques, criterion, progress), sim


def test_every_point_settles_at_its_set_points() -> None:
    progress: list[float] = []
    points, _sim = _measure(progress=progress.append)
    assert points.settled.all()
    assert progress and progress[-1] == 1.0 and np.all(np.diff(progress) >= 0)
    np.testing.assert_array_equal(points.speed_setpoint, SPEEDS)
    np.testing.assert_array_equal(points.torque_setpoint, TORQUES)
    window = int(round(CRITERION.window * RIG.sensors.sample_rate_hz))
    np.testing.assert_array_equal(points.samples, window)

    # mean speed within the steady-state criterion
    allowed = CRITERION.speed_tolerance * np.abs(SPEEDS) + CRITERION.speed_floor
    assert np.all(np.abs(points.omega_worm - SPEEDS) <= allowed)

    # the load motors apply the set-point (truth) and their currents measure it within the noise
    np.testing.assert_allclose(points.tau_true, TORQUES, rtol=1e-9)
    standard_error = points.tau_std / np.sqrt(points.samples)
    assert np.all(np.abs(points.tau_load - TORQUES) < 5 * standard_error)
    assert np.all(np.abs(points.tau_load - points.tau_true) < 5 * standard_error)

    # spreads come from the sensor noise: finite, positive, at least the noise itself
    for spread in (points.omega_std, points.current_std, points.tau_std):
        assert np.all(np.isfinite(spread)) and np.all(spread > 0)
    assert np.all(points.omega_std >= 0.9 * RIG.sensors.tacho_noise_std)
    assert np.all(points.current_std >= 0.9 * RIG.sensors.current_noise_std)


def test_mean_current_is_the_quasi_static_model_current() -> None:
    """K_t i = b w + c sign(w) + reflected(gear_side_load(tau, w), w): Eq. 28 with a_w = 0 and Eq. 29."""
    points, _sim = _measure()
    w = points.omega_worm
    mu = friction_coefficient(RIG.friction, RIG.gearbox, w)
    torque = (MOTOR.viscous_drag * w + MOTOR.coulomb_drag * np.sign(w)
              + reflected_input_torque(RIG.gearbox, mu, gear_side_load(RIG, points.tau_true, w), w))
    expected = torque / MOTOR.torque_constant
    # the controller feeds tacho noise into the current, so samples are correlated over a few
    # periods: allow 5 naive standard errors
    standard_error = points.current_std / np.sqrt(points.samples)
    assert np.all(np.abs(points.current_drive - expected) < 5 * standard_error)
    # the points span both signs of drive current (resistive/assistive, both directions)
    assert (points.current_drive > 0).any() and (points.current_drive < 0).any()


def test_without_noise_the_load_torque_spread_vanishes() -> None:
    quiet = replace(RIG, sensors=replace(RIG.sensors, current_noise_std=0.0, tacho_noise_std=0.0))
    points, _sim = _measure(rig=quiet)
    assert points.settled.all()
    np.testing.assert_allclose(points.tau_std, 0.0, atol=1e-12)  # constant currents, quantised identically
    lsb = RIG.sensors.current_lsb
    assert np.all(np.abs(points.tau_load - TORQUES) <= RIG.load_motor.torque_constant * 2 * 0.5 * lsb + 1e-12)


def test_unreachable_point_is_kept_and_marked_unsettled() -> None:
    no_load_speed = RIG.supply_voltage / MOTOR.back_emf_constant
    speeds = np.array([150.0, 1.2 * no_load_speed])
    torques = np.array([0.1, 0.1])
    criterion = replace(CRITERION, timeout=0.8)
    points, sim = _measure(speeds=speeds, torques=torques, criterion=criterion)
    np.testing.assert_array_equal(points.settled, [True, False])
    assert sim.time == pytest.approx(criterion.timeout)  # gave up at the timeout
    assert np.all(np.isfinite(points.omega_worm)) and np.all(np.isfinite(points.current_std))
    assert points.omega_worm[1] < no_load_speed  # the last window of the saturated rig


def test_set_point_shapes_must_match_the_ensemble() -> None:
    sim = SimulatedRig(RIG, n=3)
    with pytest.raises(ValueError):
        measure_operating_points(sim, SpeedController(RIG, GAINS, n=3), [1.0, 2.0], [0.0, 0.0, 0.0])
