"""The rig's command handling: voltage and speed modes, the watchdog, refusals, latency accounting."""
from __future__ import annotations

import math

import pytest

from worm_model.physics.parameters import load_rig
from worm_model.rig_data.samples import RigSample
from worm_rig_driver.drive.rig_loop import DriveMode, RigLoop, SpeedCommand
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiGains, PiLoop

RIG = load_rig()
T = 1e-3
TIMEOUT = 0.1


def command(setpoint=100.0, feedforward=0.0, kp=DEFAULT_GAINS.kp, ki=DEFAULT_GAINS.ki, limit=24.0, source=0):
    return SpeedCommand(setpoint, feedforward, kp, ki, limit, source)


def test_stopped_until_commanded_then_stopped_again_by_the_watchdog() -> None:
    loop = RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS)
    out = loop.step(0.0, 0.0, 1)
    assert (out.voltage, out.mode) == (0.0, DriveMode.STOPPED) and not loop.watchdog_stopped
    assert loop.command_voltage(6.0, now=0.001) == ""
    assert loop.step(0.002, 0.0, 2).voltage == 6.0
    assert loop.step(0.001 + TIMEOUT, 0.0, 3).voltage == 6.0  # exactly the timeout: still fresh
    out = loop.step(0.0011 + TIMEOUT, 0.0, 4)
    assert (out.voltage, out.mode) == (0.0, DriveMode.STOPPED) and loop.watchdog_stopped


def test_voltage_is_clamped_to_the_supply_and_non_finite_commands_are_refused() -> None:
    loop = RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS)
    loop.command_voltage(1e6, 0.0)
    assert loop.step(0.0, 0.0, 1).voltage == RIG.supply_voltage
    assert "not finite" in loop.command_voltage(math.nan, 0.0)
    assert loop.step(0.0, 0.0, 2).voltage == RIG.supply_voltage  # the refused command changed nothing
    for bad, word in ((command(setpoint=math.inf), "setpoint"), (command(feedforward=math.nan), "feedforward"),
                      (command(limit=0.0), "voltage_limit"), (command(kp=-1.0), "gains"),
                      (command(ki=math.nan), "gains")):
        assert word in loop.command_speed(bad, 0.0)
    assert loop.mode == DriveMode.VOLTAGE


def test_speed_mode_runs_the_pi_law_with_the_commands_gains_and_limit() -> None:
    """Per step the loop's voltage is PiLoop's for the command in force; a new command keeps the integral."""
    loop = RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS)
    reference = PiLoop(RIG, PiGains(2e-3, 0.05), 10.0)
    loop.command_speed(command(setpoint=150.0, feedforward=0.01, kp=2e-3, ki=0.05, limit=10.0, source=7), 0.0)
    speeds = [0.0, 20.0, 60.0, 120.0, 140.0, 149.0, 151.0]
    for k, omega in enumerate(speeds):
        out = loop.step(k * T, omega, 8 + k)
        assert out.voltage == reference.update(T, 150.0, omega, 0.01)
        assert out.mode == DriveMode.SPEED and out.command_seq == 7
        assert out.saturated == reference.saturated
    # a new command with other gains: the integrator carries on (bumpless), the gains change
    loop.command_speed(command(setpoint=150.0, feedforward=0.0, kp=1e-3, ki=0.02, limit=10.0, source=20), 0.0075)
    reference.gains = PiGains(1e-3, 0.02)
    out = loop.step(0.008, 150.5, 21)
    assert out.voltage == reference.update(T, 150.0, 150.5, 0.0) and out.command_seq == 20


def test_mode_changes_restart_the_integrator() -> None:
    loop = RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS)
    loop.command_speed(command(setpoint=300.0), 0.0)
    for k in range(50):
        loop.step(k * T, 100.0, k + 1)
    assert loop.pi.integral > 0
    loop.command_voltage(3.0, 0.05)
    assert loop.step(0.051, 100.0, 52).voltage == 3.0
    loop.command_speed(command(setpoint=300.0), 0.052)
    loop.step(0.053, 100.0, 54)
    assert loop.pi.integral == pytest.approx(DEFAULT_GAINS.ki * 200.0 * T)  # one step's worth, not fifty


def test_latency_counts_periods_from_the_source_sample_to_the_first_period_driven() -> None:
    loop = RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS)
    # command from sample 10 taken at the step after sample 12: it drives period 13 -> 2 periods late
    loop.command_speed(command(source=10), 0.012)
    loop.step(0.012, 0.0, 12)
    loop.step(0.013, 0.0, 13)  # the same command again: counted once
    loop.command_speed(command(source=13), 0.0135)
    loop.step(0.014, 0.0, 14)  # from sample 13, first drives period 15: 1 period
    assert dict(loop.latencies) == {2: 1, 1: 1}
    assert loop.latency_percentile(50) == pytest.approx(1e-3)
    assert loop.latency_percentile(99) == pytest.approx(2e-3)
    assert math.isnan(RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS).latency_percentile(50))


def test_argument_checks() -> None:
    with pytest.raises(ValueError):
        RigLoop(RIG, 0.0, TIMEOUT, DEFAULT_GAINS)
    with pytest.raises(ValueError):
        RigLoop(RIG, T, 0.0, DEFAULT_GAINS)


def reading(omega: float, current: float, voltage: float, theta: float) -> RigSample:
    """A rig sample with these worm speed [rad/s], drive current [A], drive voltage [V] and worm angle [rad]."""
    return RigSample(0, 0, current, 0.0, 0.0, omega, 0.0, theta, 0.0, 0, 0, 0, voltage, 0.0, 0)


class _Recording:
    """A rig feedforward that gives back a torque made of the last sample it saw and the set-point."""

    def __init__(self) -> None:
        self.seen: list[tuple] = []

    def observe(self, sample: RigSample, seq: int) -> None:
        self.seen.append((sample.omega_worm, sample.current_drive, sample.voltage_drive, sample.theta_worm, seq))

    def torque(self, setpoint: float) -> float:
        return 1e-4 * self.seen[-1][4] + 1e-6 * setpoint


def test_a_command_at_rig_is_fed_the_rigs_own_feedforward_of_the_sample_just_taken() -> None:
    """observe() hands every sample over; step() then drives the next period with that sample's torque (at the
    command's set-point) in place of the command's feedforward, and counts those periods."""
    source = _Recording()
    loop = RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS, feedforward=source)
    reference = PiLoop(RIG, DEFAULT_GAINS, RIG.supply_voltage)
    loop.command_speed(SpeedCommand(150.0, 0.5, DEFAULT_GAINS.kp, DEFAULT_GAINS.ki, 24.0, 3, at_rig=True), 0.0)
    for seq in range(4, 9):
        loop.observe(reading(140.0 + seq, 0.3, 12.0, 0.01 * seq), seq)
        out = loop.step(seq * T, 140.0 + seq, seq)
        expected = 1e-4 * seq + 1e-6 * 150.0
        assert out.feedforward == expected and out.voltage == reference.update(T, 150.0, 140.0 + seq, expected)
    assert source.seen[-1] == (148.0, 0.3, 12.0, 0.08, 8) and len(source.seen) == 5
    assert loop.feedforward_at_rig == 5
    # the same rig, a command without at_rig: the command's own feedforward
    loop.command_speed(command(setpoint=150.0, feedforward=0.02, source=9), 0.009)
    loop.observe(reading(150.0, 0.3, 12.0, 0.1), 10)
    assert loop.step(0.010, 150.0, 10).feedforward == 0.02 and loop.feedforward_at_rig == 5


def test_a_command_at_rig_on_a_rig_without_an_estimator_uses_its_own_feedforward() -> None:
    loop = RigLoop(RIG, T, TIMEOUT, DEFAULT_GAINS)
    loop.observe(reading(1.0, 0.1, 1.0, 0.0), 1)  # nothing to hand it to: no effect
    loop.command_speed(SpeedCommand(150.0, 0.02, DEFAULT_GAINS.kp, DEFAULT_GAINS.ki, 24.0, 1, at_rig=True), 0.0)
    assert loop.step(0.001, 150.0, 2).feedforward == 0.02 and loop.feedforward_at_rig == 0
