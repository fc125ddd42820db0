"""driver_node: the real rig (ATmega2560 firmware over a serial port) on the graph.

Publishes what sim_node publishes, from the rig's telemetry (rig_topics.py; seq =
the firmware's sample tick): /rig/samples (RigSamples, ``batch_size`` frames per
message), /rig/sample (RigSample, one by one, while subscribed), /rig/currents,
/rig/joint_states, /rig/encoders (every ``channel_decimation``-th sample, while
subscribed) and /diagnostics (link state and statistics, 1 Hz).

Commands: /rig/load_command (LoadCommand) goes to the firmware's load-current
loops; /rig/drive_command (DriveCommand, a voltage) and /rig/speed_command
(SpeedCommand) go to the rig's speed loop (worm_rig_driver.drive.rig_loop),
which this node runs on every telemetry frame in the reader thread, as the
firmware would: the drive voltage for the next tick is computed the moment a
frame arrives and sent back at once. Anything non-finite or beyond
max_drive_voltage / max_load_torque is refused with a logged reason; no drive or
speed command for ``command_timeout`` sets the drive to zero (and the firmware's
own watchdog stops the motors when the host goes quiet). With ``feedforward_estimator``
set, an estimator runs in that thread too, on every sample, and speed commands with
feedforward_at_rig get its feedforward on the next tick (rig_topics.declare_rig_feedforward).

The port is owned by a reader thread (serial_link.SerialLink: why a thread is
said there); the protocol, the limits and the statistics are link.LinkCore.
"""
from __future__ import annotations

import json
import os
import stat

import time

from rclpy.node import Node
from worm_msgs.msg import DriveCommand, LoadCommand, SpeedCommand
from worm_msgs.msg import RigSample as RigSampleMsg

from worm_model.cli.node_options import RIG_FILE
from worm_model.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare, declare_option
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.samples import RigSample

import worm_rig_driver.protocol.table as table
from worm_rig_driver.link.core import CommandLimits, LinkConfig, LinkCore, LinkState
from worm_rig_driver.protocol.scaling import RigScaling
from worm_rig_driver.link.serial_link import SUPPORTED_BAUDS, SerialLink
from worm_rig_driver.drive.realtime import make_realtime
from worm_rig_driver.drive.rig_loop import DriveMode, RigLoop
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS
from worm_rig_driver.nodes.rig_topics import (RigEstimate, RigTopics, declare_rig_feedforward, log_refusal,
                                             speed_command_from_msg, subscribe_commands)


class DriverNode(Node):
    #: the command gate reads each command's publisher GID (rig_topics.CommandGate; ros.lifecycle.executor_for)
    takes_message_info = True

    def __init__(self) -> None:
        super().__init__("driver_node")
        port = declare(self, "port", "/dev/ttyACM0", "Serial device of the rig (a /dev/serial/by-id/... link "
                       "survives re-enumeration); reopened within reconnect_period when it comes back.")
        if os.path.isdir(port) or (os.path.exists(port) and stat.S_ISREG(os.stat(port).st_mode)):
            # a port that is not there yet is waited for (reconnect_period); a folder or a plain file never
            # becomes a serial device
            raise ValueError(f"parameter port: {port!r} is a {'folder' if os.path.isdir(port) else 'regular file'}, "
                             "not a serial device (e.g. /dev/ttyACM0 or a /dev/serial/by-id/... link)")
        baud = declare(self, "baud", table.BAUD, f"Line rate [bit/s]; the firmware uses {table.BAUD}.",
                       low=min(SUPPORTED_BAUDS), high=max(SUPPORTED_BAUDS))
        rig_file = declare_option(self, RIG_FILE)
        rate = declare(self, "stream_rate_hz", table.SAMPLE_RATE_HZ,
                       f"Telemetry rate [Hz]: 0 or a divisor of {table.SAMPLE_RATE_HZ}.", low=0,
                       high=table.SAMPLE_RATE_HZ)
        batch_size = declare(self, "batch_size", 5, "Telemetry frames per rig/samples message.", low=1, high=1000)
        decimation = declare(self, "channel_decimation", 10,
                             "Publish currents/joint_states/encoders every N-th sample (while subscribed).",
                             low=1, high=1000)
        command_timeout = declare(self, "command_timeout", 0.1,
                                  "Age [s] of the last drive or speed command after which the drive is set to zero "
                                  f"(host watchdog; the firmware's own stops the motors {table.WATCHDOG_MS} ms after "
                                  "the link dies).", low=0.005, high=10.0)
        rx_timeout = declare(self, "rx_timeout", 0.25, "No frame from the rig for this long [s]: count a timeout "
                             "and handshake again.", low=0.01, high=10.0)
        reconnect = declare(self, "reconnect_period", 0.1, "Period [s] of attempts to reopen a lost port.",
                            low=0.01, high=1.0)
        drift = declare(self, "clock_max_drift", 0.005, "How fast [s/s] the firmware clock may fall behind the "
                        "host's when mapping its timestamps (0.005 covers a ceramic resonator; raise it for a "
                        "simulated rig slower than real time).", low=0.0, high=1.0)
        self.rig = load_rig(rig_file or None)
        max_voltage = declare(self, "max_drive_voltage", min(self.rig.drive_motor.max_voltage, self.rig.supply_voltage),
                              "Largest |DriveCommand.voltage| [V] forwarded; larger ones are refused.",
                              low=0.0, high=self.rig.supply_voltage)
        max_torque = declare(self, "max_load_torque", self.rig.max_load_torque,
                             "Largest |LoadCommand.torque| [N m] forwarded; larger ones are refused.", low=0.0)
        self.frame_id = declare(self, "frame_id", "worm_rig", "frame_id of published headers.")
        priority = declare(self, "reader_priority", 50,
                           "SCHED_FIFO priority of the serial reader thread, which runs the rig's speed loop "
                           "(1-99; 0: normal scheduling). Needs CAP_SYS_NICE; without it the thread runs at "
                           "normal priority.", low=0, high=99)

        self.scaling = RigScaling.from_rig(self.rig)
        self.max_voltage = max_voltage
        # The link's own drive watchdog backs the loop's up (the loop sends every frame).
        core = LinkCore(self.scaling, CommandLimits(max_voltage, max_torque),
                        LinkConfig(stream_rate_hz=rate, rx_timeout=rx_timeout, command_timeout=command_timeout,
                                   clock_max_drift=drift))
        tick = 1.0 / table.SAMPLE_RATE_HZ
        sample_period = tick * table.SAMPLE_RATE_HZ / max(rate, 1)
        self._seq_step = max(1, round(sample_period / tick))  # clock ticks per streamed sample
        feedforward = declare_rig_feedforward(self, self.rig, sample_period)
        self.loop = RigLoop(self.rig, sample_period, command_timeout, DEFAULT_GAINS, seq_period=tick,
                            feedforward=feedforward)
        # its parameters first: everything a node declares comes before its first publisher (--help reads them)
        self.estimate = RigEstimate(self, self.rig, feedforward, self.frame_id)
        self.topics = RigTopics(self, self.frame_id, tick, batch_size, decimation, self.scaling.counts_per_rev)
        self._command_seq = 0  # the speed command in force for the next frame (its source seq)
        self._sent_voltage = 0.0  # [V] the last drive voltage sent to the rig
        self._sent_at = 0.0  # [s] time.monotonic() it was sent
        self.command_timeout = command_timeout
        self.commands = subscribe_commands(self, self.on_speed_command, self.on_drive_command, self.on_load_command,
                                           command_timeout, core.limits.drive_problem)

        self.link = SerialLink(port, core, self.publish_samples, self.log_line, baud=baud,
                               reconnect_period=reconnect,
                               on_thread_start=lambda: self.log_line("info", f"serial reader thread: "
                                                                             f"{make_realtime(priority)}"))
        Diagnostics(self, self.report)
        self.link.start()
        self.get_logger().info(f"rig '{self.rig.name}' on {port} at {baud} baud, telemetry {rate} Hz")

    def destroy_node(self) -> None:
        link = self.__dict__.get("link")  # absent when a bad parameter stopped the constructor
        if link is not None:
            link.stop()
            # One machine-readable line with the totals (fil_run and the tests read it).
            self.get_logger().info("link statistics at exit: " + json.dumps(link.report(), sort_keys=True))
        super().destroy_node()

    # --- commands ---------------------------------------------------------------------------
    def _refused(self, what: str, reason: str | None) -> str:
        """Log a refused command; returns ``reason`` ('' when the command was taken)."""
        if reason:
            log_refusal(self, what, reason)
        return reason or ""

    def on_drive_command(self, msg: DriveCommand) -> str:
        reason = self.link.core.limits.drive_problem(msg.voltage) or self.loop.command_voltage(msg.voltage,
                                                                                               time.monotonic())
        if reason:
            self.link.core.stats.rejected_commands += 1
        return self._refused("drive", reason)

    def on_speed_command(self, msg: SpeedCommand) -> str:
        reason = self.loop.command_speed(speed_command_from_msg(msg), time.monotonic())
        if reason:
            self.link.core.stats.rejected_commands += 1
        return self._refused("speed", reason)

    def on_load_command(self, msg: LoadCommand) -> None:
        self._refused("load", self.link.command(lambda core, now: core.load(msg.torque, now)))

    # --- telemetry (called from the reader thread) ----------------------------------------------
    def publish_samples(self, samples: list[RigSample]) -> None:
        """Run the speed loop on the newest frame and send its voltage; publish every frame."""
        stopped = RigSampleMsg.STATUS_WATCHDOG_STOP if self.loop.watchdog_stopped else 0
        for s in samples:
            sample = s._replace(status=s.status | stopped, command_seq=self._command_seq, frame_id=self.frame_id)
            # every sample to the rig's own estimator, numbered in samples (its gaps are lost samples)
            estimate = self.loop.observe(sample, s.seq // self._seq_step)
            # its estimate before the graph's stream (the controller waits for the estimate), then the sample
            self.estimate.after_sample(s.seq, s.stamp_ns, self.topics.closes_batch(s.seq), estimate)
            self.topics.add(sample)
        newest = samples[-1]
        out = self.loop.step(time.monotonic(), newest.omega_worm, newest.seq)
        self._command_seq = out.command_seq
        # The rig holds the last voltage it was sent (the link keeps its watchdog fed): send a new one
        # when it changes, which in speed mode is every frame.
        voltage = max(-self.max_voltage, min(self.max_voltage, out.voltage))  # the driver's own limit
        if voltage != self._sent_voltage or (out.mode is not DriveMode.STOPPED and self._stale_drive()):
            self.link.command(lambda core, now: core.drive(voltage, now))
            self._sent_voltage = voltage
            self._sent_at = time.monotonic()

    def _stale_drive(self) -> bool:
        """The link's own drive watchdog would drop a voltage held this long without a command."""
        return time.monotonic() - self._sent_at > 0.5 * self.command_timeout

    def log_line(self, level: str, message: str) -> None:
        # One call site per severity: rclpy refuses a call site whose severity changes.
        log = self.get_logger()
        if level == "error":
            log.error(message)
        elif level == "warn":
            log.warning(message)
        else:
            log.info(message)

    def report(self) -> tuple[bytes, str, dict]:
        values = {**self.link.report(), "feedforward_at_rig_samples": self.loop.feedforward_at_rig,
                  **self.commands.report(), **self.estimate.report()}
        state = LinkState(values["state"])
        level, message = OK, "streaming"
        if state is LinkState.INCOMPATIBLE:
            level, message = ERROR, "firmware speaks another protocol version"
        elif state is LinkState.CLOSED:
            level, message = ERROR, f"port {values['port']} not open"
        elif state is LinkState.HANDSHAKE:
            level, message = WARN, "handshaking"
        elif self.link.core.watchdog_active or self.link.core.last_fw_status & table.STATUS_BITS["WATCHDOG_STOP"][0]:
            level, message = WARN, "motors stopped by a watchdog"
        return level, message, values


def main(args=None) -> int:
    return run_node(DriverNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
