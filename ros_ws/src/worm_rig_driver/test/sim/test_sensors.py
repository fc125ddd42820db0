"""SensorModel: ADC sequencing, quantisation and noise, tacho ripple, 4x encoders with int32 wrap, load torque."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.plant import PlantOutputs, PlantState
from worm_rig_driver.protocol.scaling import RigScaling
from worm_rig_driver.sim.sensors import (
    STATUS_DRIVE_LIMIT,
    STATUS_SIMULATED,
    AdcChain,
    SensorModel,
    Trajectory,
    wrap_int32,
)

RIG = load_rig()
QUIET = replace(RIG, sensors=replace(RIG.sensors, current_noise_std=0.0, tacho_noise_std=0.0))
LSB = RIG.sensors.current_lsb
COUNTS_PER_REV = RIG.sensors.encoder_pulses_per_rev * RIG.sensors.encoder_decoding
RIPPLE_ORDER = RIG.sensors.tacho_ripple_order  # 7 on the bundled rig


def _state(n: int, current=0.0, omega=0.0, theta=0.0, current_load=0.0) -> PlantState:
    def full(x):
        return np.broadcast_to(np.asarray(x, float), (n,)).copy()

    return PlantState(full(current), full(omega), full(theta), full(current_load))


def _outputs(n: int, voltage=0.0, saturated=False) -> PlantOutputs:
    zeros = np.zeros(n)
    return PlantOutputs(tau_in=zeros, tau_load=zeros, gear_load=zeros, alpha_worm=zeros, mu=zeros,
                        voltage_drive=np.broadcast_to(np.asarray(voltage, float), (n,)).copy(),
                        drive_saturated=np.broadcast_to(np.asarray(saturated), (n,)).copy())


def _measure(rig, state, outputs=None, seed=0):
    return SensorModel(rig, np.random.default_rng(seed)).measure(state, outputs or _outputs(state.omega_worm.size))


def test_encoder_resolution_is_500_ppr_decoded_4x() -> None:
    assert COUNTS_PER_REV == 2000
    assert SensorModel(RIG, np.random.default_rng(0)).counts_per_rev == COUNTS_PER_REV


def test_current_is_quantised_to_one_adc_step_without_noise() -> None:
    true = np.linspace(-3.0, 3.0, 1001)
    m = _measure(QUIET, _state(true.size, current=true, current_load=true))
    for measured in (m.current_drive, m.current_load_1, m.current_load_2):
        steps = measured / LSB
        np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)  # on the ADC grid
        assert np.all(np.abs(measured - true) <= 0.5 * LSB + 1e-12)  # nearest step
    assert len(np.unique(np.round(m.current_drive / LSB))) > 200  # not a coarser grid


def test_current_noise_then_quantisation_statistics() -> None:
    n = 20000
    true = np.full(n, 1.234)
    m = _measure(RIG, _state(n, current=true))
    error = m.current_drive - true
    np.testing.assert_allclose(m.current_drive / LSB, np.round(m.current_drive / LSB), atol=1e-9)
    expected_std = np.sqrt(RIG.sensors.current_noise_std ** 2 + LSB ** 2 / 12)  # noise + rounding
    assert abs(error.std() / expected_std - 1) < 0.05
    assert abs(error.mean()) < 0.1 * LSB + 4 * expected_std / np.sqrt(n)


def _true(rig, state) -> dict:
    """The analogue signals before effects, noise and the ADC."""
    return SensorModel(rig, np.random.default_rng(0)).true_signals(Trajectory.held(state, rig.gearbox.ratio))


def test_tacho_ripple_has_the_commutator_order_and_amplitude() -> None:
    n = 4096
    theta = np.arange(n) * 2 * np.pi / n  # one worm revolution
    omega = 100.0
    relative = _true(QUIET, _state(n, omega=omega, theta=theta))["tacho_drive"] / omega - 1.0
    spectrum = np.abs(np.fft.rfft(relative)) * 2 / n  # harmonic k = cycles per revolution
    assert np.argmax(spectrum) == RIPPLE_ORDER
    assert spectrum[RIPPLE_ORDER] == pytest.approx(RIG.sensors.tacho_ripple, rel=1e-6)
    assert np.delete(spectrum, RIPPLE_ORDER).max() < 1e-9


def test_gear_tacho_ripple_is_in_gear_angle() -> None:
    n = 4096
    ratio = RIG.gearbox.ratio
    theta_worm = np.arange(n) * 2 * np.pi / n / ratio  # one gear revolution
    signals = _true(QUIET, _state(n, omega=60.0, theta=theta_worm))
    for name in ("tacho_load_1", "tacho_load_2"):
        relative = signals[name] / (ratio * 60.0) - 1.0
        spectrum = np.abs(np.fft.rfft(relative)) * 2 / n
        assert np.argmax(spectrum) == RIPPLE_ORDER
        assert spectrum[RIPPLE_ORDER] == pytest.approx(RIG.sensors.tacho_ripple, rel=1e-6)


def test_tachos_are_quantised_by_the_adc_with_a_range_per_shaft() -> None:
    sensor = SensorModel(QUIET, np.random.default_rng(0))
    # the rig file's resolutions, as the driver scales the codes (one source for simulator and driver)
    scaling = RigScaling.from_rig(RIG)
    drive_lsb = RIG.sensors.tacho_drive_lsb
    assert sensor.tacho_lsb["tacho_drive"] == drive_lsb == scaling.tacho_drive_lsb == 500 / 512
    assert sensor.tacho_lsb["tacho_load_1"] == RIG.sensors.tacho_load_lsb == scaling.tacho_load_lsb == 20 / 512
    # each full scale (512 codes either side of mid-scale) above its shaft's top speed
    no_load_speed = RIG.supply_voltage / RIG.drive_motor.back_emf_constant
    assert no_load_speed < 512 * drive_lsb and RIG.gearbox.ratio * no_load_speed < 512 * RIG.sensors.tacho_load_lsb
    omega = np.linspace(-400.0, 400.0, 997)
    m = sensor.measure(_state(omega.size, omega=omega), _outputs(omega.size))
    np.testing.assert_allclose(m.omega_worm / drive_lsb, np.round(m.omega_worm / drive_lsb), atol=1e-9)
    # ripple (1 % at theta = 0: sin 0 = 0, so none here) + rounding: within half a step
    assert np.all(np.abs(m.omega_worm - omega) <= 0.5 * drive_lsb + 1e-9)
    gear_lsb = sensor.tacho_lsb["tacho_load_1"]
    assert np.all(np.abs(m.omega_gear - RIG.gearbox.ratio * omega) <= 0.5 * gear_lsb + 1e-9)


def test_readings_clip_at_the_ends_of_the_adc_range() -> None:
    m = _measure(QUIET, _state(2, current=[100.0, -100.0], omega=[2000.0, -2000.0]))
    np.testing.assert_allclose(m.current_drive, [511 * LSB, -512 * LSB])
    lsb = SensorModel(QUIET, np.random.default_rng(0)).tacho_lsb["tacho_drive"]
    np.testing.assert_allclose(m.omega_worm, [511 * lsb, -512 * lsb])


def test_tacho_noise_level() -> None:
    n = 20000
    m = _measure(RIG, _state(n, omega=0.0))
    lsb = SensorModel(RIG, np.random.default_rng(0)).tacho_lsb
    sigma = RIG.sensors.tacho_noise_std
    # noise, then rounding to the ADC step (Sheppard: + lsb^2/12 while sigma is not << lsb)
    assert abs(m.omega_worm.std() / np.sqrt(sigma ** 2 + lsb["tacho_drive"] ** 2 / 12) - 1) < 0.05
    # the gear speed averages two independent tachos (their steps are 25x finer)
    assert abs(m.omega_gear.std() / np.sqrt((sigma ** 2 + lsb["tacho_load_1"] ** 2 / 12) / 2) - 1) < 0.05


# --- the ADC sequence through the two multiplexers ---------------------------------------------------

def test_adc_sequence_timing_follows_the_atmega_conversion_time() -> None:
    adc = AdcChain()
    times = adc.sample_times(RIG.sensors)
    conversion = 13 / (16e6 / 128)  # 13 ADC clocks at 125 kHz = 104 us
    assert list(times) == [ch.signal for ch in adc.channels]
    np.testing.assert_allclose(np.diff(list(times.values())), conversion)
    assert times["current_drive"] == pytest.approx(1.5 / 125e3)
    assert adc.sequence_time(RIG.sensors) == pytest.approx(6 * conversion) and adc.sequence_time() < 1e-3
    # the instants the estimators read from the rig file are the simulator's, to the bit
    assert RIG.sensors.sample_times() == times == SensorModel(RIG, np.random.default_rng(0)).sample_time
    # two 8:1 multiplexers: currents on one, tachos on the other, distinct inputs
    assert {ch.mux for ch in adc.channels} == {0, 1}
    assert len({(ch.mux, ch.mux_input) for ch in adc.channels}) == len(adc.channels)
    assert all(0 <= ch.mux_input < 8 for ch in adc.channels)


def test_a_sample_rate_the_sequence_does_not_fit_is_refused() -> None:
    fast = replace(RIG, sensors=replace(RIG.sensors, sample_rate_hz=2000.0))  # 500 us < 624 us
    with pytest.raises(ValueError, match="does not fit"):
        SensorModel(fast, np.random.default_rng(0))


def test_each_channel_is_sampled_at_its_own_instant_and_encoders_at_the_tick() -> None:
    """A trajectory ramping through the period: every channel reads the ramp at its own time."""
    period, steps, n = 1e-3, 4, 1
    times = np.linspace(0.0, period, steps + 1)
    ramp = 2000.0 * times  # 0 .. 2 A over the period (20 ms ramp slope: 2 mA per us)
    slow = 1e5 * times  # 0 .. 100 rad/s
    states = {"current_drive": ramp[:, None], "current_load": ramp[:, None] + 0.5,
              "omega_worm": slow[:, None], "theta_worm": 50.0 + 0.5 * 1e5 * times[:, None] ** 2,
              "omega_gear": RIG.gearbox.ratio * slow[:, None],
              "theta_gear": RIG.gearbox.ratio * (50.0 + 0.5 * 1e5 * times[:, None] ** 2)}
    sensor = SensorModel(QUIET, np.random.default_rng(0))
    trajectory = Trajectory(period, states)
    signals = sensor.true_signals(trajectory)
    t = AdcChain().sample_times(RIG.sensors)
    assert signals["current_drive"][0] == pytest.approx(2000.0 * t["current_drive"])
    assert signals["current_load_1"][0] == pytest.approx(2000.0 * t["current_load_1"] + 0.5)
    assert signals["current_load_2"][0] == pytest.approx(2000.0 * t["current_load_2"] + 0.5)
    theta = 50.0 + 0.5 * 1e5 * t["tacho_drive"] ** 2  # (linear interpolation of theta: error < 1e-3 rad)
    expected = 1e5 * t["tacho_drive"] * (1 + RIG.sensors.tacho_ripple * np.sin(RIPPLE_ORDER * theta))
    assert signals["tacho_drive"][0] == pytest.approx(expected, rel=1e-3)
    m = sensor.measure_period(trajectory, _outputs(n))
    assert m.current_load_2[0] - m.current_load_1[0] == pytest.approx(2000.0 * (t["current_load_2"]
                                                                               - t["current_load_1"]), abs=LSB)
    count, _ = sensor._encoder(np.array([50.0]))  # latched at the tick, not at the end of the period
    assert m.count_drive[0] == count[0]
def test_encoder_counts_per_revolution_and_resolved_angle() -> None:
    revs = np.array([-3.0, -1.0, 0.0, 1.0, 2.0, 7.0])
    offset = 0.3 * 2 * np.pi / COUNTS_PER_REV  # inside a count, away from edges
    theta = revs * 2 * np.pi + offset
    m = _measure(QUIET, _state(revs.size, theta=theta))
    np.testing.assert_array_equal(m.count_drive, (revs * COUNTS_PER_REV).astype(np.int64))
    assert m.count_drive.dtype == np.int32
    step = 2 * np.pi / COUNTS_PER_REV
    assert np.all((theta - m.theta_worm >= 0) & (theta - m.theta_worm < step))
    # gear encoder: one gear turn = 1/ratio worm turns = COUNTS_PER_REV counts
    ratio = RIG.gearbox.ratio
    gear_theta = revs / ratio * 2 * np.pi + offset / ratio
    g = _measure(QUIET, _state(revs.size, theta=gear_theta))
    np.testing.assert_array_equal(g.count_load_1, (revs * COUNTS_PER_REV).astype(np.int64))
    np.testing.assert_array_equal(g.count_load_2, g.count_load_1)


def test_wrap_int32_at_the_boundaries() -> None:
    counts = np.array([0, 2**31 - 1, 2**31, 2**31 + 5, -2**31, -2**31 - 1, 2**32, -2**32 - 3], dtype=np.int64)
    wrapped = wrap_int32(counts)
    assert wrapped.dtype == np.int32
    np.testing.assert_array_equal(wrapped, [0, 2**31 - 1, -2**31, -2**31 + 5, -2**31, 2**31 - 1, 0, -3])
    # wrapping is a congruence mod 2^32
    assert np.all((wrapped.astype(np.int64) - counts) % 2**32 == 0)


def test_encoder_counter_wraps_but_angle_stays_unwrapped() -> None:
    step = 2 * np.pi / COUNTS_PER_REV
    true_counts = np.array([2**31 - 2, 2**31 + 5, -2**31 - 7], dtype=np.int64)
    theta = (true_counts + 0.5) * step
    m = _measure(QUIET, _state(true_counts.size, theta=theta))
    np.testing.assert_array_equal(m.count_drive, [2**31 - 2, -2**31 + 5, 2**31 - 7])
    np.testing.assert_allclose(m.theta_worm, true_counts * step, rtol=1e-12)


def test_load_torque_is_load_torque_constant_times_summed_load_currents() -> None:
    n = 500
    per_motor = np.linspace(-2.5, 2.5, n)
    m = _measure(RIG, _state(n, current_load=per_motor))
    assert not np.array_equal(m.current_load_1, m.current_load_2)  # independent channels
    np.testing.assert_allclose(m.tau_load, RIG.load_motor.torque_constant * (m.current_load_1 + m.current_load_2),
                               rtol=1e-12, atol=1e-15)
    # and it estimates the applied torque count * K_t * i within the noise
    applied = RIG.load_motor_count * RIG.load_motor.torque_constant * per_motor
    assert (np.abs(m.tau_load - applied).max()
            < RIG.load_motor.torque_constant * 2 * (5 * RIG.sensors.current_noise_std + LSB))


def test_status_and_voltage_pass_through() -> None:
    m = _measure(RIG, _state(2), _outputs(2, voltage=[24.0, 3.0], saturated=[True, False]))
    np.testing.assert_array_equal(m.status, [STATUS_DRIVE_LIMIT | STATUS_SIMULATED, STATUS_SIMULATED])
    assert m.status.dtype == np.uint32
    np.testing.assert_array_equal(m.voltage_drive, [24.0, 3.0])
