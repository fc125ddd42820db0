"""sim_node: the simulated rig on the graph, a stand-in for driver_node.

Publishes, for every sample of the rig's clock (sensor-data QoS):
  /rig/sample       worm_msgs/RigSample       all channels of one sample period, with seq
  /rig/currents     worm_msgs/MotorCurrents   (every `channel_decimation`-th sample)
  /rig/joint_states sensor_msgs/JointState    worm and gear position, velocity, effort
  /rig/encoders     worm_msgs/EncoderCounts
  /sim/truth        worm_msgs/SimTruth        (when publish_truth, decimated like the channels)
and obeys /rig/drive_command (DriveCommand) and /rig/load_command (LoadCommand).
A drive command older than command_timeout stops the drive motor (as the rig's
watchdog does). The simulation advances in real time in chunks of
publish_period: every sample keeps its own stamp on the rig's exact clock.
The parameter effects_file switches on effects the model lacks (a
worm_rig_effects file, see effects.py); the model is not told.
"""
from __future__ import annotations

import math

import numpy as np
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState
from worm_msgs.msg import DriveCommand, EncoderCounts, LoadCommand, MotorCurrents, RigSample, SimTruth

from worm_model.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.physics.parameters import load_rig

from worm_rig_driver.sim.simulated_rig import SimulatedRig
from worm_rig_driver.sim.sensors import Measurement

#: Most samples produced by one timer tick. A starved process must not run the rig
#: open-loop on a stale command for long: beyond this the rig's time is dilated
#: (the samples are not simulated, no seq is skipped) and the shortfall is counted.
MAX_CATCH_UP = 20


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__("sim_node")
        rig_file = declare(self, "rig_file", "", "Rig parameter YAML (worm_model format); empty = bundled NMRV030 rig.")
        seed = declare(self, "seed", 0, "Seed of the sensor noise (same seed, same commands -> same samples).",
                       low=0, high=2**31 - 1)
        effects_file = declare(self, "effects_file", "",
                               "worm_rig_effects YAML: effects the model lacks, switched on in the simulator "
                               "only (see `python -m worm_rig_driver.sim.effects --list`); empty = none.")
        substeps = declare(self, "substeps", 1, "Integration steps per sample period (the armature step is exact; "
                           "the mechanics have a ~10 ms time constant).", low=1, high=50)
        self.publish_period = declare(self, "publish_period", 0.005,
                                      "Timer period [s]: samples due since the last tick are produced and published.",
                                      low=0.001, high=0.1)
        self.decimation = declare(self, "channel_decimation", 10,
                                  "Publish currents/joint_states/encoders/truth every N-th sample (RigSample: every one).",
                                  low=1, high=1000)
        self.publish_truth = declare(self, "publish_truth", True, "Publish the simulator's ground truth on /sim/truth.")
        self.command_timeout = declare(self, "command_timeout", 0.5,
                                       "Drive command age [s] after which the drive motor is stopped (watchdog).",
                                       low=0.01, high=10.0)
        self.frame_id = declare(self, "frame_id", "worm_rig", "frame_id of published headers.")

        self.rig = load_rig(rig_file or None)
        self.sim = SimulatedRig(self.rig, n=1, seed=seed, substeps=substeps, effects=effects_file or None)
        self.counts_per_rev = self.sim.sensors.counts_per_rev

        self.pub_sample = self.create_publisher(RigSample, "/rig/sample", STREAM)
        self.pub_currents = self.create_publisher(MotorCurrents, "/rig/currents", STREAM)
        self.pub_joints = self.create_publisher(JointState, "/rig/joint_states", STREAM)
        self.pub_encoders = self.create_publisher(EncoderCounts, "/rig/encoders", STREAM)
        self.pub_truth = self.create_publisher(SimTruth, "/sim/truth", STREAM) if self.publish_truth else None
        self.create_subscription(DriveCommand, "/rig/drive_command", self.on_drive_command, STREAM)
        self.create_subscription(LoadCommand, "/rig/load_command", self.on_load_command, COMMAND)

        self.start: Time | None = None  # the rig's clock starts at the first tick
        self.last_drive_command: Time | None = None
        self.watchdog_active = False
        self.rejected_commands = 0
        self.skipped_samples = 0
        self.create_timer(self.publish_period, self.on_tick)
        Diagnostics(self, self.report)
        effects = ", ".join(self.sim.effects.names) or "none"
        self.get_logger().info(f"simulating '{self.rig.name}' at {self.rig.sensors.sample_rate_hz:g} Hz "
                               f"(rig file: {self.rig.source}; effects: {effects})")

    # --- commands ----------------------------------------------------------------
    def on_drive_command(self, msg: DriveCommand) -> None:
        if not math.isfinite(msg.voltage):
            self.rejected_commands += 1
            self.get_logger().warning(f"rejected drive command: voltage={msg.voltage} is not finite",
                                   throttle_duration_sec=1.0)
            return
        self.sim.command(voltage_drive=msg.voltage)
        self.last_drive_command = self.get_clock().now()

    def on_load_command(self, msg: LoadCommand) -> None:
        if not math.isfinite(msg.torque):
            self.rejected_commands += 1
            self.get_logger().warning(f"rejected load command: torque={msg.torque} is not finite")
            return
        self.sim.command(load_torque=msg.torque)

    def _watchdog(self, now: Time) -> None:
        stale = (self.last_drive_command is None
                 or (now - self.last_drive_command).nanoseconds * 1e-9 > self.command_timeout)
        if stale and not self.watchdog_active and self.last_drive_command is not None:
            self.get_logger().warning(f"no drive command for {self.command_timeout} s: drive motor stopped")
        if stale:
            self.sim.command(voltage_drive=0.0)
        self.watchdog_active = stale

    # --- the clock ---------------------------------------------------------------
    def on_tick(self) -> None:
        now = self.get_clock().now()
        if self.start is None:
            self.start = now
        self._watchdog(now)
        due = int((now - self.start).nanoseconds * 1e-9 / self.sim.sample_period) - self.sim.seq
        if due > MAX_CATCH_UP:
            self.skipped_samples += due - MAX_CATCH_UP
            self.get_logger().warning(f"sim fell behind by {due} samples; skipping {due - MAX_CATCH_UP}",
                                   throttle_duration_sec=1.0)
            self.start += seconds((due - MAX_CATCH_UP) * self.sim.sample_period)
            due = MAX_CATCH_UP
        for _ in range(max(due, 0)):
            measured = self.sim.sample()
            stamp = (self.start + seconds(self.sim.time)).to_msg()
            self.publish_sample(measured, stamp)

    def publish_sample(self, m: Measurement, stamp) -> None:
        seq = self.sim.seq
        status = int(m.status[0]) | (RigSample.STATUS_WATCHDOG_STOP if self.watchdog_active else 0)
        sample = RigSample(
            seq=seq, current_drive=float(m.current_drive[0]), current_load_1=float(m.current_load_1[0]),
            current_load_2=float(m.current_load_2[0]), omega_worm=float(m.omega_worm[0]),
            omega_gear=float(m.omega_gear[0]), theta_worm=float(m.theta_worm[0]),
            theta_gear=float(m.theta_gear[0]), count_drive=int(m.count_drive[0]),
            count_load_1=int(m.count_load_1[0]), count_load_2=int(m.count_load_2[0]),
            voltage_drive=float(m.voltage_drive[0]), tau_load=float(m.tau_load[0]), status=status)
        sample.header.stamp = stamp
        sample.header.frame_id = self.frame_id
        self.pub_sample.publish(sample)

        if seq % self.decimation:
            return
        self.publish_channels(sample)
        if self.pub_truth is not None:
            t = self.sim.truth()
            truth = SimTruth(seq=seq, tau_load=float(t.tau_load[0]), tau_in=float(t.tau_in[0]),
                             omega_worm=float(t.omega_worm[0]), current_drive=float(t.current_drive[0]),
                             normal_force=float(t.normal_force[0]), friction_force=float(t.friction_force[0]),
                             mu=float(t.mu[0]), mode=int(t.mode[0]), flank=int(t.flank[0]))
            truth.header = sample.header
            self.pub_truth.publish(truth)

    def publish_channels(self, s: RigSample) -> None:
        currents = MotorCurrents(header=s.header, drive=s.current_drive, load_1=s.current_load_1,
                                 load_2=s.current_load_2)
        self.pub_currents.publish(currents)
        joints = JointState(header=s.header, name=["worm", "gear"],
                            position=[s.theta_worm, s.theta_gear], velocity=[s.omega_worm, s.omega_gear],
                            effort=[float("nan"), s.tau_load])
        self.pub_joints.publish(joints)
        encoders = EncoderCounts(header=s.header, drive=s.count_drive, load_1=s.count_load_1,
                                 load_2=s.count_load_2, counts_per_rev=self.counts_per_rev)
        self.pub_encoders.publish(encoders)

    def report(self) -> tuple[bytes, str, dict]:
        level, message = OK, "running"
        if self.skipped_samples:
            level, message = WARN, "fell behind real time"
        if self.watchdog_active:
            level, message = WARN, "drive motor stopped: no drive commands"
        if not np.isfinite(self.sim.plant.state.omega_worm).all():
            level, message = ERROR, "simulation diverged"
        return level, message, {"samples": self.sim.seq, "skipped_samples": self.skipped_samples,
                                "rejected_commands": self.rejected_commands}


def seconds(value: float) -> Duration:
    return Duration(nanoseconds=int(round(value * 1e9)))


def main(args=None) -> int:
    return run_node(SimNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
