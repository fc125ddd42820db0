"""sim_node: the simulated rig on the graph, a stand-in for driver_node.

The rig's clock runs in its own thread, one sample period (1 ms) at a time on
absolute deadlines: each tick simulates the period that just ended, runs the
rig's speed loop on that sample (worm_rig_driver.drive.rig_loop, as the
firmware or driver_node does on the real rig) and sets the voltage for the next
period. Samples keep their exact stamps on the rig's clock; a tick that wakes late
simulates the periods it missed at once (up to ``max_catch_up``; beyond, the rig's
time is dilated and the shortfall counted), so the rig never runs open-loop on a
stale voltage for long.

Topics (rig_topics.py): /rig/samples (worm_msgs/RigSamples, every sample,
``batch_size`` per message), /rig/sample (RigSample, one by one, only while
subscribed), /rig/currents, /rig/joint_states, /rig/encoders (every
``channel_decimation``-th sample, while subscribed), the simulator's ground
truth when ``publish_truth``, each only while subscribed: /sim/truth_samples
(SimTruths, every sample, in batches aligned with /rig/samples': same
first_seq, stamp and length) and /sim/truth (SimTruth, decimated like the
channels), /diagnostics. Commands:
/rig/speed_command (SpeedCommand: the speed loop), /rig/drive_command
(DriveCommand: hold a voltage), /rig/load_command (LoadCommand). A drive or
speed command older than ``command_timeout`` stops the drive motor (watchdog;
the samples say so in STATUS_WATCHDOG_STOP). With ``feedforward_estimator`` set, an
estimator runs beside the speed loop on every sample, and speed commands with
feedforward_at_rig get its feedforward on the very next period (rig_topics.
declare_rig_feedforward; the rig's figures in bench/controller_bench.py's rig
timing). The parameter effects_file switches
on effects the model lacks (a worm_rig_effects file, see sim/effects/); the
model is not told.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import replace

from rclpy.node import Node
from rclpy.time import Time
from worm_msgs.msg import DriveCommand, LoadCommand, SimTruth, SimTruths, SpeedCommand
from worm_msgs.msg import RigSample as RigSampleMsg

from worm_model.cli.node_options import RIG_FILE
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.samples import SIM_TRUTHS_TOPIC, TRUTH_FIELDS
from worm_model.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare, declare_option
from worm_model.ros.qos import STREAM

from worm_rig_driver.drive.realtime import make_realtime
from worm_rig_driver.drive.rig_loop import DriveMode, RigLoop
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS
from worm_rig_driver.nodes.rig_topics import (RigEstimate, RigTopics, declare_rig_feedforward, log_refusal,
                                             speed_command_from_msg, subscribe_commands)
from worm_rig_driver.sim.simulated_rig import SimulatedRig, rig_sample

_WATCHDOG = RigSampleMsg.STATUS_WATCHDOG_STOP
_LIMIT = RigSampleMsg.STATUS_DRIVE_LIMIT


class SimNode(Node):
    #: the command gate reads each command's publisher GID (rig_topics.CommandGate; ros.lifecycle.executor_for)
    takes_message_info = True

    def __init__(self) -> None:
        super().__init__("sim_node")
        rig_file = declare_option(self, RIG_FILE)
        seed = declare(self, "seed", 0, "Seed of the sensor noise (same seed, same commands -> same samples).",
                       low=0, high=2**31 - 1)
        effects_file = declare(self, "effects_file", "",
                               "worm_rig_effects YAML: effects the model lacks, switched on in the simulator "
                               "only (see `ros2 run worm_rig_driver worm_effects --list`); empty = none.")
        substeps = declare(self, "substeps", 1, "Integration steps per sample period (the armature step is exact; "
                           "the mechanics have a ~10 ms time constant).", low=1, high=50)
        batch_size = declare(self, "batch_size", 5, "Samples per /rig/samples message (5: 200 messages/s at "
                             "1 kHz; the newest sample leaves the moment it is taken).", low=1, high=1000)
        decimation = declare(self, "channel_decimation", 10,
                             "Publish currents/joint_states/encoders/truth every N-th sample.", low=1, high=1000)
        self.publish_truth = declare(self, "publish_truth", True,
                                     "Publish the simulator's ground truth, each topic only while someone "
                                     "subscribes: /sim/truth_samples (every sample, batched like /rig/samples) "
                                     "and /sim/truth (every channel_decimation-th sample).")
        command_timeout = declare(self, "command_timeout", 0.1,
                                  "Age [s] of the last drive or speed command after which the drive motor is "
                                  "stopped (watchdog).", low=0.005, high=10.0)
        self.max_catch_up = declare(self, "max_catch_up", 100,
                                    "Most sample periods simulated at once by a tick that woke late; beyond, the "
                                    "rig's time is dilated and the shortfall counted.", low=1, high=100000)
        self.clock_priority = declare(self, "clock_priority", 50,
                                      "SCHED_FIFO priority of the rig's clock thread (1-99; 0: normal scheduling). "
                                      "Needs CAP_SYS_NICE; without it the thread runs at normal priority.",
                                      low=0, high=99)
        frame_id = declare(self, "frame_id", "worm_rig", "frame_id of published headers.")
        sample_rate = declare(self, "sample_rate", 0.0, "The rig's sample clock [Hz]; 0: the rig file's "
                              "sensors.sample_rate_hz (a drive among others of a robot runs at the robot's rate).",
                              low=0.0, high=100000.0)

        self.rig = load_rig(rig_file or None)
        if sample_rate > 0:
            self.rig = replace(self.rig, sensors=replace(self.rig.sensors, sample_rate_hz=float(sample_rate)))
        self.sim = SimulatedRig(self.rig, n=1, seed=seed, substeps=substeps, effects=effects_file or None)
        self.period = self.sim.sample_period
        feedforward = declare_rig_feedforward(self, self.rig, self.period)
        self.loop = RigLoop(self.rig, self.period, command_timeout, DEFAULT_GAINS, feedforward=feedforward)
        # its parameters first: everything a node declares comes before its first publisher (--help reads them)
        self.estimate = RigEstimate(self, self.rig, feedforward, frame_id)
        self.topics = RigTopics(self, frame_id, self.period, batch_size, decimation, self.sim.sensors.counts_per_rev)
        self.decimation = decimation
        self.pub_truth = self.create_publisher(SimTruth, "sim/truth", STREAM) if self.publish_truth else None
        self.pub_truths = self.create_publisher(SimTruths, SIM_TRUTHS_TOPIC, STREAM) if self.publish_truth else None
        self._truths: dict[str, list] | None = None  # the open /sim/truth_samples batch (None: not collecting)
        self._truths_first = (0, 0)  # its (first_seq, first stamp [ns])
        self.commands = subscribe_commands(self, self.on_speed_command, self.on_drive_command, self.on_load_command,
                                           command_timeout)

        self.rejected_commands = 0
        self.skipped_samples = 0  # periods never simulated (the rig's time was dilated)
        self.late_samples = 0  # periods simulated more than one period after they ended
        self._in_force = (0, 0)  # (command_seq, status bits) of the period being simulated
        self._start_mono = time.monotonic()
        self._start_ns = self.get_clock().now().nanoseconds
        self._stop = threading.Event()
        self._rig_thread = threading.Thread(target=self._run_clock, name="rig_clock", daemon=True)
        Diagnostics(self, self.report)
        effects = ", ".join(self.sim.effects.names) or "none"
        self.get_logger().info(f"simulating '{self.rig.name}' at {self.rig.sensors.sample_rate_hz:g} Hz "
                               f"(rig file: {self.rig.source}; effects: {effects})")
        self._rig_thread.start()

    def destroy_node(self) -> None:
        self._stop.set()
        if self._rig_thread.is_alive():
            self._rig_thread.join(timeout=2.0)
        super().destroy_node()

    # --- commands (executor thread) -------------------------------------------------------
    def _now(self) -> float:
        """The rig's clock [s since start], the time base of RigLoop."""
        return time.monotonic() - self._start_mono

    def _refused(self, what: str, reason: str | None) -> str:
        """Count and log a refused command; returns ``reason`` ('' when the command was taken)."""
        if reason:
            self.rejected_commands += 1
            log_refusal(self, what, reason)
        return reason or ""

    def on_speed_command(self, msg: SpeedCommand) -> str:
        return self._refused("speed", self.loop.command_speed(speed_command_from_msg(msg), self._now()))

    def on_drive_command(self, msg: DriveCommand) -> str:
        return self._refused("drive", self.loop.command_voltage(msg.voltage, self._now()))

    def on_load_command(self, msg: LoadCommand) -> None:
        if not math.isfinite(msg.torque):
            self._refused("load", f"torque={msg.torque} is not finite")
            return
        self.sim.command(load_torque=msg.torque)

    # --- the rig's clock (its own thread) -------------------------------------------------
    def _run_clock(self) -> None:
        self.get_logger().info(f"rig clock thread: {make_realtime(self.clock_priority)}")
        period = self.period
        while not self._stop.is_set():
            due = int((time.monotonic() - self._start_mono) / period)  # periods ended so far
            behind = due - self.sim.seq
            if behind > self.max_catch_up:
                skipped = behind - self.max_catch_up
                self.skipped_samples += skipped
                self._start_mono += skipped * period  # dilate: those periods are never simulated
                self._start_ns += int(round(skipped * period * 1e9))
                self.get_logger().warning(f"sim fell behind by {behind} samples; skipping {skipped}",
                                          throttle_duration_sec=1.0)
                behind = self.max_catch_up
            if behind > 1:
                self.late_samples += behind - 1
            for _ in range(max(behind, 0)):
                self._tick()
            delay = self._start_mono + (self.sim.seq + 1) * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)

    def _tick(self) -> None:
        """Simulate the period that just ended, publish its sample, set the voltage for the next."""
        m = self.sim.sample()
        seq = self.sim.seq
        command_seq, status_bits = self._in_force
        stamp_ns = self._start_ns + int(round(seq * self.period * 1e9))
        sample = rig_sample(m, seq, stamp_ns, status_bits, command_seq, self.topics.frame_id)
        estimate = self.loop.observe(sample, seq)
        out = self.loop.step(seq * self.period, sample.omega_worm, seq)
        self.sim.command(voltage_drive=out.voltage)
        self._in_force = (out.command_seq, (_WATCHDOG if self.loop.watchdog_stopped or out.mode == DriveMode.STOPPED
                                            else 0) | (_LIMIT if out.saturated else 0))
        opens = self.pub_truths is not None and self.topics.opens_batch(seq)
        # the estimate (observed above) before the graph's stream: the controller waits for the estimate
        self.estimate.after_sample(seq, stamp_ns, self.topics.closes_batch(seq), estimate)
        self.topics.add(sample)
        if opens:
            # a /rig/samples batch started here: so does a truth batch, if anyone listens (asked once a batch)
            self._flush_truths()
            self._truths = {name: [] for name in TRUTH_FIELDS} if self.pub_truths.get_subscription_count() else None
            self._truths_first = (seq, stamp_ns)
        decimated = (self.pub_truth is not None and seq % self.decimation == 0
                     and self.pub_truth.get_subscription_count() > 0)
        if self._truths is not None or decimated:
            t = self.sim.truth()
            truth = {"tau_load": float(t.tau_load[0]), "tau_in": float(t.tau_in[0]),
                     "omega_worm": float(t.omega_worm[0]), "current_drive": float(t.current_drive[0]),
                     "normal_force": float(t.normal_force[0]), "friction_force": float(t.friction_force[0]),
                     "mu": float(t.mu[0]), "mode": int(t.mode[0]), "flank": int(t.flank[0])}
            if self._truths is not None:
                for name, column in self._truths.items():
                    column.append(truth[name])
            if decimated:
                single = SimTruth(seq=seq, **truth)
                single.header.stamp = Time(nanoseconds=stamp_ns).to_msg()
                single.header.frame_id = self.topics.frame_id
                self.pub_truth.publish(single)
        if self._truths is not None and not self.topics.pending:
            self._flush_truths()  # its /rig/samples batch just went out

    def _flush_truths(self) -> None:
        """Publish the open /sim/truth_samples batch (nothing if none or empty); the next one opens with
        the next /rig/samples batch."""
        columns, self._truths = self._truths, None
        if not columns or not columns["tau_load"]:
            return
        first_seq, first_stamp_ns = self._truths_first
        msg = SimTruths(first_seq=first_seq, sample_period=self.period, **columns)
        msg.header.stamp = Time(nanoseconds=first_stamp_ns).to_msg()
        msg.header.frame_id = self.topics.frame_id
        self.pub_truths.publish(msg)

    def report(self) -> tuple[bytes, str, dict]:
        level, message = OK, "running"
        if self.skipped_samples:
            level, message = WARN, "fell behind real time"
        if self.loop.watchdog_stopped:
            level, message = WARN, "drive motor stopped: no drive or speed commands"
        if not math.isfinite(float(self.sim.plant.state.omega_worm[0])):
            level, message = ERROR, "simulation diverged"
        return level, message, {
            "samples": self.sim.seq, "skipped_samples": self.skipped_samples, "late_samples": self.late_samples,
            "rejected_commands": self.rejected_commands, "mode": self.loop.mode.name,
            "feedforward_at_rig_samples": self.loop.feedforward_at_rig,
            "command_latency_p50_ms": self.loop.latency_percentile(50) * 1e3,
            "command_latency_p99_ms": self.loop.latency_percentile(99) * 1e3, **self.commands.report(),
            **self.estimate.report()}


def main(args=None) -> int:
    return run_node(SimNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
