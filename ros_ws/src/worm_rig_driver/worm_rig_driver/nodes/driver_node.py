"""driver_node: the real rig (ATmega2560 firmware over a serial port) on the graph.

Publishes what sim_node publishes, from the rig's telemetry (sensor-data QoS):
  /rig/sample       worm_msgs/RigSample       every telemetry frame, seq = the firmware's sample tick
  /rig/currents     worm_msgs/MotorCurrents   (every `channel_decimation`-th sample)
  /rig/joint_states sensor_msgs/JointState    worm and gear position, velocity, effort
  /rig/encoders     worm_msgs/EncoderCounts
  /diagnostics      diagnostic_msgs/DiagnosticArray  link state and statistics, 1 Hz
and forwards /rig/drive_command (DriveCommand) and /rig/load_command
(LoadCommand) to the firmware, refusing (with a logged reason) anything
non-finite or beyond max_drive_voltage / max_load_torque.

The port is owned by a reader thread (serial_link.SerialLink: why a thread is
said there); the protocol, the limits and the statistics are link.LinkCore.
"""
from __future__ import annotations

import json

from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState
from worm_msgs.msg import DriveCommand, EncoderCounts, LoadCommand, MotorCurrents, RigSample

from worm_model.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.physics.parameters import load_rig

import worm_rig_driver.protocol.table as table
from worm_rig_driver.link.core import CommandLimits, LinkConfig, LinkCore, LinkState, Sample
from worm_rig_driver.protocol.scaling import RigScaling
from worm_rig_driver.link.serial_link import SUPPORTED_BAUDS, SerialLink


class DriverNode(Node):
    def __init__(self) -> None:
        super().__init__("driver_node")
        port = declare(self, "port", "/dev/ttyACM0", "Serial device of the rig (a /dev/serial/by-id/... link "
                       "survives re-enumeration); reopened within reconnect_period when it comes back.")
        baud = declare(self, "baud", table.BAUD, f"Line rate [bit/s]; the firmware uses {table.BAUD}.",
                       low=min(SUPPORTED_BAUDS), high=max(SUPPORTED_BAUDS))
        rig_file = declare(self, "rig_file", "", "Rig parameter YAML (worm_model format); empty = bundled NMRV030 rig.")
        rate = declare(self, "stream_rate_hz", table.SAMPLE_RATE_HZ,
                       f"Telemetry rate [Hz]: 0 or a divisor of {table.SAMPLE_RATE_HZ}.", low=0,
                       high=table.SAMPLE_RATE_HZ)
        self.decimation = declare(self, "channel_decimation", 10,
                                  "Publish currents/joint_states/encoders every N-th sample (RigSample: every one).",
                                  low=1, high=1000)
        command_timeout = declare(self, "command_timeout", 0.5,
                                  "Drive command age [s] after which the drive is set to zero (host watchdog; "
                                  f"the firmware's own stops the motors {table.WATCHDOG_MS} ms after the link dies).",
                                  low=0.01, high=10.0)
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

        self.scaling = RigScaling.from_rig(self.rig)
        core = LinkCore(self.scaling, CommandLimits(max_voltage, max_torque),
                        LinkConfig(stream_rate_hz=rate, rx_timeout=rx_timeout, command_timeout=command_timeout,
                                   clock_max_drift=drift))

        self.pub_sample = self.create_publisher(RigSample, "/rig/sample", STREAM)
        self.pub_currents = self.create_publisher(MotorCurrents, "/rig/currents", STREAM)
        self.pub_joints = self.create_publisher(JointState, "/rig/joint_states", STREAM)
        self.pub_encoders = self.create_publisher(EncoderCounts, "/rig/encoders", STREAM)
        self.create_subscription(DriveCommand, "/rig/drive_command", self.on_drive_command, STREAM)
        self.create_subscription(LoadCommand, "/rig/load_command", self.on_load_command, COMMAND)

        self.link = SerialLink(port, core, self.publish_samples, self.log_line, baud=baud,
                               reconnect_period=reconnect)
        Diagnostics(self, self.report)
        self.link.start()
        self.get_logger().info(f"rig '{self.rig.name}' on {port} at {baud} baud, telemetry {rate} Hz")

    def destroy_node(self) -> None:
        self.link.stop()
        # One machine-readable line with the totals (fil_run and the tests read it).
        self.get_logger().info("link statistics at exit: " + json.dumps(self.link.report(), sort_keys=True))
        super().destroy_node()

    # --- commands ---------------------------------------------------------------------------
    def on_drive_command(self, msg: DriveCommand) -> None:
        reason = self.link.command(lambda core, now: core.drive(msg.voltage, now))
        if reason:
            # .warning, not .warn: rclpy keys a call site's throttle filter on its caller, and
            # .warn (deprecated) is one caller for every site: a throttled and an unthrottled
            # .warn in one node raise "logging filters cannot be changed" in the second.
            self.get_logger().warning(f"rejected drive command: {reason}", throttle_duration_sec=1.0)

    def on_load_command(self, msg: LoadCommand) -> None:
        reason = self.link.command(lambda core, now: core.load(msg.torque, now))
        if reason:
            self.get_logger().warning(f"rejected load command: {reason}")

    # --- telemetry (called from the reader thread) ----------------------------------------------
    def publish_samples(self, samples: list[Sample]) -> None:
        for s in samples:
            msg = RigSample(
                seq=s.seq, current_drive=s.current_drive, current_load_1=s.current_load_1,
                current_load_2=s.current_load_2, omega_worm=s.omega_worm, omega_gear=s.omega_gear,
                theta_worm=s.theta_worm, theta_gear=s.theta_gear, count_drive=s.count_drive,
                count_load_1=s.count_load_1, count_load_2=s.count_load_2, voltage_drive=s.voltage_drive,
                tau_load=s.tau_load, status=s.status)
            msg.header.stamp = Time(nanoseconds=s.stamp_ns).to_msg()
            msg.header.frame_id = self.frame_id
            self.pub_sample.publish(msg)
            if s.seq % self.decimation == 0:
                self.publish_channels(msg)

    def publish_channels(self, s: RigSample) -> None:
        self.pub_currents.publish(MotorCurrents(header=s.header, drive=s.current_drive, load_1=s.current_load_1,
                                                load_2=s.current_load_2))
        self.pub_joints.publish(JointState(header=s.header, name=["worm", "gear"],
                                           position=[s.theta_worm, s.theta_gear],
                                           velocity=[s.omega_worm, s.omega_gear],
                                           effort=[float("nan"), s.tau_load]))
        self.pub_encoders.publish(EncoderCounts(header=s.header, drive=s.count_drive, load_1=s.count_load_1,
                                                load_2=s.count_load_2, counts_per_rev=self.scaling.counts_per_rev))

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
        values = self.link.report()
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
