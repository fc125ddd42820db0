"""SpeedController on the simulated plant: tracking, anti-windup, feedforward (physics.md sections 6-8)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.efficiency import forward_efficiency
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.plant import RigPlant
from worm_rig_driver.drive.speed_loop import PiGains, SpeedController
from worm_model.physics.steady_state import balancing_torque as feedforward_torque

RIG = load_rig()
GB = RIG.gearbox
MOTOR = RIG.drive_motor
GAINS = PiGains(kp=2e-3, ki=0.05)  # the bundled rig's design gains (speed loop ~60 rad/s)
PERIOD = 1e-3  # control period [s]; the plant integrates in two 0.5 ms substeps


class WindupController(SpeedController):
    """The same PI without anti-windup: the integrator never sees the limit; only the output is clipped."""

    def update(self, dt, omega_ref, omega_measured, tau_ff=0.0):
        limit = self.voltage_limit
        self.voltage_limit = np.inf
        try:
            out = super().update(dt, omega_ref, omega_measured, tau_ff)
        finally:
            self.voltage_limit = limit
        return replace(out, voltage=np.clip(out.voltage, -limit, limit), saturated=np.abs(out.voltage) > limit)


def _closed_loop(controller: SpeedController, refs, loads, feedforward: bool = False) -> np.ndarray:
    """Run controller + plant (true speed fed back, no noise); refs/loads shape (steps, n). Returns omega."""
    n = refs.shape[1]
    plant = RigPlant(RIG, n)
    tau_load = np.zeros(n)
    history = np.empty_like(refs)
    for k in range(refs.shape[0]):
        ff = feedforward_torque(RIG, tau_load, plant.state.omega_worm) if feedforward else 0.0
        out = controller.update(PERIOD, refs[k], plant.state.omega_worm, ff)
        for _ in range(2):
            tau_load = plant.step(PERIOD / 2, out.voltage, loads[k]).tau_load
        history[k] = plant.state.omega_worm
    return history


# --- pure functions ---------------------------------------------------------------------------------

def test_feedforward_is_i_d_over_eta_for_resistive_loads_in_both_directions() -> None:
    omega = np.array([20.0, 150.0, 400.0, -20.0, -150.0, -400.0])
    tau = np.array([0.05, 0.2, 0.27, -0.05, -0.2, -0.27])  # opposing the motion in every case
    mu = friction_coefficient(RIG.friction, GB, omega)
    expected = np.sign(omega) * GB.ratio * np.abs(tau) / forward_efficiency(GB, mu)  # T_min = i D / eta
    # (r_w/r_g) K_+ = i / eta holds to the geometric consistency of i = r_w tan(lambda) / r_g
    # (the bundled lead angle is rounded to 1e-6 deg: ~2e-8 relative)
    assert abs(GB.geometric_ratio / GB.ratio - 1) < 1e-7
    np.testing.assert_allclose(feedforward_torque(RIG, tau, omega), expected, rtol=1e-6)


def test_feedforward_of_nan_load_is_zero() -> None:
    ff = feedforward_torque(RIG, np.array([np.nan, 0.1, np.nan]), np.array([100.0, 100.0, -50.0]))
    assert np.all(np.isfinite(ff))
    assert ff[0] == 0.0 and ff[2] == 0.0 and ff[1] > 0.0


def test_output_follows_the_torque_domain_law() -> None:
    ctrl = SpeedController(RIG, GAINS, n=2)
    ref, meas, ff = np.array([100.0, -50.0]), np.array([90.0, -55.0]), np.array([0.01, -0.002])
    out = ctrl.update(PERIOD, ref, meas, ff)
    error = ref - meas
    torque = GAINS.kp * error + GAINS.ki * error * PERIOD + ff
    np.testing.assert_allclose(out.torque_command, torque, rtol=1e-12)
    np.testing.assert_allclose(out.voltage, MOTOR.resistance * torque / MOTOR.torque_constant
                               + MOTOR.back_emf_constant * ref, rtol=1e-12)  # V = R tau/K_t + K_e w_ref
    np.testing.assert_array_equal(out.feedforward_torque, ff)
    assert not out.saturated.any()


def test_nan_measurement_holds_the_integrator_and_drops_p() -> None:
    ctrl = SpeedController(RIG, GAINS, n=1)
    ctrl.update(PERIOD, 100.0, 90.0)
    held = ctrl.integral.copy()
    out = ctrl.update(PERIOD, 100.0, np.nan)
    np.testing.assert_array_equal(ctrl.integral, held)
    np.testing.assert_allclose(out.torque_command, held)
    ctrl.reset()
    np.testing.assert_array_equal(ctrl.integral, 0.0)


def test_argument_checks() -> None:
    with pytest.raises(ValueError):
        PiGains(kp=-1.0, ki=0.0)
    with pytest.raises(ValueError):
        SpeedController(RIG, GAINS, voltage_limit=0.0)


def test_voltage_is_clipped_and_flagged_at_the_limit() -> None:
    ctrl = SpeedController(RIG, GAINS, voltage_limit=10.0, n=2)
    out = ctrl.update(PERIOD, np.array([400.0, -400.0]), np.zeros(2))
    np.testing.assert_array_equal(out.voltage, [10.0, -10.0])
    np.testing.assert_array_equal(out.saturated, [True, True])


# --- closed loop on the plant -----------------------------------------------------------------------

def test_tracks_set_points_with_zero_steady_state_error_under_load() -> None:
    refs = np.array([150.0, -150.0, 300.0, -80.0])
    loads = np.array([0.1, 0.1, -0.15, -0.05])  # resistive, assistive, assistive, resistive
    steps = 1500
    with_integral = _closed_loop(SpeedController(RIG, GAINS, n=4), np.tile(refs, (steps, 1)),
                                 np.tile(loads, (steps, 1)))
    error = with_integral[-100:] - refs
    assert np.abs(error).max() < 1e-2
    # the integral is what removes it: P alone leaves a load-dependent offset
    p_only = _closed_loop(SpeedController(RIG, PiGains(GAINS.kp, 0.0), n=4), np.tile(refs, (steps, 1)),
                          np.tile(loads, (steps, 1)))
    assert np.all(np.abs(p_only[-1] - refs) > 50 * np.abs(error).max())


def test_anti_windup_limits_overshoot_after_saturated_acceleration() -> None:
    """Start from rest to 400 rad/s against 0.25 N m: the 24 V supply saturates the whole run-up."""
    steps = 600
    refs, loads = np.full((steps, 1), 400.0), np.full((steps, 1), 0.25)
    overshoot_aw = _closed_loop(SpeedController(RIG, GAINS), refs, loads).max() - 400.0
    overshoot_windup = _closed_loop(WindupController(RIG, GAINS), refs, loads).max() - 400.0
    assert overshoot_windup > 5.0  # the scenario does wind a plain integrator up
    assert overshoot_aw < 0.1 * overshoot_windup


def test_anti_windup_recovers_quickly_after_an_unreachable_set_point() -> None:
    """0.8 s at an unreachable 500 rad/s (no-load speed ~436), then 300 rad/s."""
    steps, switch = 1300, 800
    refs = np.where(np.arange(steps) < switch, 500.0, 300.0)[:, None]
    loads = np.full((steps, 1), 0.1)
    aw = _closed_loop(SpeedController(RIG, GAINS), refs, loads)[switch:, 0]
    windup = _closed_loop(WindupController(RIG, GAINS), refs, loads)[switch:, 0]
    excess_aw = np.maximum(aw - 300.0, 0).sum() * PERIOD  # [rad] spent above the new set-point
    excess_windup = np.maximum(windup - 300.0, 0).sum() * PERIOD
    assert excess_aw < 0.05 * excess_windup
    assert np.abs(aw[-100:] - 300.0).max() < 0.5


def test_feedforward_reduces_the_speed_dip_after_a_load_step() -> None:
    steps, step_at = 1000, 500
    refs = np.full((steps, 1), 150.0)
    loads = np.where(np.arange(steps) < step_at, 0.0, 0.25)[:, None]
    plain = _closed_loop(SpeedController(RIG, GAINS), refs, loads)
    with_ff = _closed_loop(SpeedController(RIG, GAINS), refs, loads, feedforward=True)
    assert abs(plain[step_at - 1, 0] - 150.0) < 0.1 and abs(with_ff[step_at - 1, 0] - 150.0) < 0.1
    dip_plain = 150.0 - plain[step_at:].min()
    dip_ff = 150.0 - with_ff[step_at:].min()
    assert dip_plain > 1.0
    assert dip_ff < 0.5 * dip_plain
    assert abs(with_ff[-1, 0] - 150.0) < 0.05


# --- which estimate is fed forward (controller_node's rule) -----------------------------------------

def test_feedforward_gate_uses_only_fresh_usable_estimates() -> None:
    from torque_estimator.estimation.base import EstimateFlags
    from torque_estimator.control.feedforward import FeedforwardGate

    gate = FeedforwardGate(timeout=0.05)
    assert gate.load(10.0) is None  # nothing offered yet
    gate.offer(0.12, 0, stamp=10.0)
    assert gate.load(10.001) == 0.12
    assert gate.load(10.049) == 0.12 and gate.load(10.051) is None  # stale beyond the timeout
    for flag in (EstimateFlags.AMBIGUOUS, EstimateFlags.TRANSIENT):
        gate.offer(0.1, int(flag), stamp=11.0)
        assert gate.load(11.0) == 0.1, flag.name  # still the best guess
    for flag in (EstimateFlags.INVALID_INPUT, EstimateFlags.OUT_OF_CALIBRATION):
        gate.offer(0.1, int(flag | EstimateFlags.AMBIGUOUS), stamp=12.0)
        assert gate.load(12.0) is None, flag.name
    gate.offer(float("nan"), 0, stamp=13.0)
    assert gate.load(13.0) is None
    gate.offer(-0.2, 0, stamp=14.0)
    gate.enabled = False
    assert gate.load(14.0) is None
    gate.enabled = True
    assert gate.load(14.0) == -0.2
