"""The drive's speed PI: SpeedController (vectorised) and PiLoop (scalar) agree; tracking, anti-windup and
feedforward on the simulated plant (physics.md sections 6-8)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.plant import RigPlant
from worm_rig_driver.drive.speed_loop import PiGains, PiLoop, SpeedController
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


def test_scalar_loop_equals_the_vectorised_controller_step_by_step() -> None:
    """PiLoop (the live rig's) and SpeedController (batch calibration's) are one law: same outputs
    to the last bit over set-point steps, saturation both ways, NaN measurements and feedforward."""
    rng = np.random.default_rng(3)
    steps = 3000
    refs = np.repeat(rng.uniform(-450, 450, steps // 100), 100)
    measured = refs + rng.normal(0, 30, steps)
    measured[rng.integers(0, steps, 40)] = np.nan
    ff = rng.normal(0, 0.02, steps)
    ff[rng.integers(0, steps, 20)] = np.inf
    vector = SpeedController(RIG, GAINS, voltage_limit=12.0)
    scalar = PiLoop(RIG, GAINS, voltage_limit=12.0)
    saturated = 0
    for k in range(steps):
        out = vector.update(PERIOD, refs[k], measured[k], ff[k])
        voltage = scalar.update(PERIOD, float(refs[k]), float(measured[k]), float(ff[k]))
        assert voltage == float(out.voltage[0]), k
        assert scalar.integral == float(vector.integral[0]), k
        assert scalar.saturated == bool(out.saturated[0]), k
        saturated += scalar.saturated
    assert 100 < saturated < steps - 100  # the run does exercise the limit and the linear range
    with pytest.raises(ValueError):
        PiLoop(RIG, GAINS, voltage_limit=0.0)
