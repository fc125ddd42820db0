"""What the rig does with its commands on every sample: hold a voltage, run the speed loop, or stop.

One rig, plain Python (no ROS, no numpy per sample), so sim_node's real-time
thread and driver_node's serial reader run it on every 1 kHz sample for a few
microseconds. Modes:

  STOPPED  0 V: no command yet, or the last one is older than ``command_timeout``
           (the watchdog: a rig that loses its controller stops driving);
  VOLTAGE  a drive command (worm_msgs/DriveCommand): its voltage is held;
  SPEED    a speed command (worm_msgs/SpeedCommand): the PI of speed_loop runs on
           every sample with the command's set-point, feedforward torque and gains.

Feedforward at the rig: given a ``feedforward`` source (:class:`RigFeedforward`,
an estimator beside the PI: drive.feedforward_plugin finds one), the caller hands
every sample to :meth:`RigLoop.observe` before :meth:`RigLoop.step`, and a speed
command with ``at_rig`` set is fed the source's torque for the coming period in
place of its own ``feedforward``: the estimate of the sample just taken drives the
very next period, where a controller's command would reach the rig a batch and a
transit later. Without a source, ``at_rig`` commands use their ``feedforward``.

Timing (the firmware's): :meth:`RigLoop.step` is called when sample ``seq`` has
just been taken, at the start of the next sample period, and returns the voltage
for that period. A command takes effect at the first step after it arrived.
Times are seconds on one clock shared by the caller's threads (the rig's clock).

Latency accounting on the rig's own clock: a speed command computed from sample
``s`` (its ``source_seq``) that first drives the period after sample ``k`` acted
``(k - s)`` sample periods after ``s`` was stamped. :attr:`RigLoop.latencies`
counts those, per command, for /diagnostics and the benchmarks; the samples carry
the ``command_seq`` in force, so the same figure can be read from any recording.

Thread safety: commands are handed over as one immutable object (an attribute
assignment, atomic under the GIL); :meth:`step` reads it once per call.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, Protocol

from worm_model.physics.parameters import Rig
from worm_model.rig_data.estimate import Estimate
from worm_model.rig_data.samples import RigSample

from worm_rig_driver.drive.speed_loop import PiGains, PiLoop


class DriveMode(IntEnum):
    STOPPED = 0
    VOLTAGE = 1
    SPEED = 2


@dataclass(frozen=True)
class SpeedCommand:
    """A speed command as the rig takes it (the fields of worm_msgs/SpeedCommand it acts on).

    Attributes:
        setpoint: worm speed to hold [rad/s].
        feedforward: torque at the worm added to the PI output [N m].
        kp, ki: PI gains [N m s/rad], [N m/rad].
        voltage_limit: largest |V| [V] (the loop also clamps to the rig's supply).
        source_seq: seq of the newest rig sample the command was computed from (0: unknown).
        at_rig: feed the PI the rig's own feedforward (RigLoop's ``feedforward`` source) instead of
            ``feedforward``, when the rig has one.
    """

    setpoint: float
    feedforward: float
    kp: float
    ki: float
    voltage_limit: float
    source_seq: int = 0
    at_rig: bool = False

    def problem(self) -> str:
        """Why the rig refuses this command ('' if it is usable)."""
        for name in ("setpoint", "feedforward", "voltage_limit"):
            if not math.isfinite(getattr(self, name)):
                return f"{name}={getattr(self, name)} is not finite"
        if not self.voltage_limit > 0:
            return f"voltage_limit={self.voltage_limit} must be > 0"
        if not (0 <= self.kp < math.inf and 0 <= self.ki < math.inf):
            return f"gains kp={self.kp}, ki={self.ki} must be finite and >= 0"
        return ""


def voltage_problem(voltage: float) -> str:
    """Why the rig refuses a drive command of ``voltage`` [V] ('' if it takes it; a finite voltage beyond the
    supply is clamped, not refused)."""
    return "" if math.isfinite(voltage) else f"voltage={voltage} is not finite"


class RigFeedforward(Protocol):
    """A feedforward the rig computes itself, one sample at a time (module docstring).

    ``observe`` takes the rig's sample (its worm speed, drive current, the drive voltage of the sample and the
    worm encoder angle are what an estimator reads) as the loop's sample ``seq``; ``torque`` gives the torque
    at the worm [N m] (positive turns the worm positively) to add to the PI output for the period that
    follows, at worm speed set-point ``setpoint`` [rad/s]: 0 when the estimate is unusable. Both run in the
    rig's sample thread, so they must take microseconds, not milliseconds. ``observe`` returns the sample's
    load estimate (worm_model.rig_data.estimate.Estimate: tau_d, uncertainty, flags, the filtered speed and
    current), which the rig publishes as the graph's estimate (nodes.rig_topics); ``method`` names its
    estimator.
    """

    method: str

    def observe(self, sample: RigSample, seq: int) -> Estimate: ...

    def torque(self, setpoint: float) -> float: ...


@dataclass(frozen=True)
class LoopOutput:
    """One step's result: the voltage [V] for the coming period, the mode, and the speed command's
    source seq in force (0 outside SPEED); ``saturated``: the PI hit its voltage limit;
    ``feedforward``: the torque at the worm [N m] added to the PI output."""

    voltage: float
    mode: DriveMode
    command_seq: int
    saturated: bool
    feedforward: float = 0.0


class RigLoop:
    """The rig's command handling and speed loop (see module docstring).

    Args:
        rig: rig parameters (drive motor, supply voltage).
        sample_period: [s] between steps (the PI's dt).
        command_timeout: [s] a command older than this stops the drive.
        gains: PI gains until a speed command brings its own.
        seq_period: [s] per unit of the samples' seq (default: sample_period; a rig streaming
            every n-th tick of its clock has sample_period = n * seq_period).
        feedforward: the rig's own feedforward source (None: commands bring theirs).
    """

    def __init__(self, rig: Rig, sample_period: float, command_timeout: float, gains: PiGains,
                 seq_period: float | None = None, feedforward: RigFeedforward | None = None) -> None:
        if not (sample_period > 0 and command_timeout > 0):
            raise ValueError(f"need sample_period > 0 and command_timeout > 0, got {sample_period}, {command_timeout}")
        self.rig = rig
        self.sample_period = sample_period
        self.seq_period = sample_period if seq_period is None else seq_period
        self.command_timeout = command_timeout
        self.supply = rig.supply_voltage
        self.pi = PiLoop(rig, gains, self.supply)
        self._pending: tuple[DriveMode, object, float] | None = None  # (mode, command, received at)
        self._active: object = None  # the command in force (identity tells a new one)
        self.mode = DriveMode.STOPPED
        self.commanded = False  # a command arrived at some point (STOPPED after that: the watchdog)
        self.latencies: Counter[int] = Counter()  # seq units from source sample to effect -> commands
        self.feedforward = feedforward
        self.feedforward_at_rig = 0  # periods driven with the rig's own feedforward

    # --- commands (any thread) -------------------------------------------------------------
    def command_voltage(self, voltage: float, now: float) -> str:
        """Hold ``voltage`` [V] (clamped to the supply); returns why it was refused, '' if taken."""
        if problem := voltage_problem(voltage):
            return problem
        self._pending = (DriveMode.VOLTAGE, max(-self.supply, min(self.supply, float(voltage))), now)
        return ""

    def command_speed(self, command: SpeedCommand, now: float) -> str:
        """Run the speed loop on ``command``; returns why it was refused, '' if taken."""
        problem = command.problem()
        if not problem:
            self._pending = (DriveMode.SPEED, command, now)
        return problem

    def stop(self) -> None:
        """Forget every command: 0 V from the next step until a new command arrives."""
        self._pending = None

    # --- every sample (the rig's thread) ---------------------------------------------------
    def observe(self, sample: RigSample, seq: int) -> Any:
        """Hand ``sample`` to the rig's feedforward source, if any (call for every sample, before :meth:`step`),
        as the loop's sample ``seq``. Returns the source's estimate of the sample (RigFeedforward.observe), None
        without a source."""
        if self.feedforward is None:
            return None
        return self.feedforward.observe(sample, seq)

    def step(self, now: float, omega_measured: float, seq: int) -> LoopOutput:
        """The voltage for the period starting at ``now`` [s], sample ``seq`` having just been taken
        (``omega_measured`` [rad/s] its worm speed)."""
        pending = self._pending
        if pending is None or now - pending[2] > self.command_timeout:
            if self.mode != DriveMode.STOPPED:
                self.pi.reset()
            self.mode, self._active = DriveMode.STOPPED, None
            return LoopOutput(0.0, DriveMode.STOPPED, 0, False)
        mode, command, _received = pending
        self.commanded = True
        if mode == DriveMode.VOLTAGE:
            self.mode, self._active = mode, command
            return LoopOutput(command, mode, 0, False)
        if self.mode != DriveMode.SPEED:
            self.pi.reset()  # a fresh start, not the integral of an earlier run
        if command is not self._active:
            self._active = command
            if (command.kp, command.ki) != (self.pi.gains.kp, self.pi.gains.ki):
                self.pi.gains = PiGains(command.kp, command.ki)
            self.pi.voltage_limit = min(command.voltage_limit, self.supply)
            if command.source_seq:
                self.latencies[max(seq - command.source_seq, 0)] += 1
        self.mode = DriveMode.SPEED
        feedforward = command.feedforward
        if command.at_rig and self.feedforward is not None:
            feedforward = self.feedforward.torque(command.setpoint)
            self.feedforward_at_rig += 1
        voltage = self.pi.update(self.sample_period, command.setpoint, omega_measured, feedforward)
        return LoopOutput(voltage, mode, command.source_seq, self.pi.saturated, feedforward)

    @property
    def watchdog_stopped(self) -> bool:
        """Stopped although commands came before: they went stale."""
        return self.mode == DriveMode.STOPPED and self.commanded

    def latency_percentile(self, q: float) -> float:
        """The q-th percentile [s] of command latency (source sample stamped -> in force), NaN if none."""
        total = sum(self.latencies.values())
        if not total:
            return math.nan
        rank, seen = q / 100.0 * total, 0
        for periods in sorted(self.latencies):
            seen += self.latencies[periods]
            if seen >= rank:
                return periods * self.seq_period
        return max(self.latencies) * self.seq_period


__all__ = ["DriveMode", "LoopOutput", "RigFeedforward", "RigLoop", "SpeedCommand", "voltage_problem"]
