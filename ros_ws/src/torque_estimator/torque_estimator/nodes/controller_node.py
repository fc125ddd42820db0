"""controller_node: worm speed control with the estimated load torque as feedforward.

Subscribes /rig/sample (feedback, every sample runs one control period),
/torque_estimate (the latest estimate is held) and /controller/speed_setpoint
(std_msgs/Float64 [rad/s]); publishes /rig/drive_command (worm_msgs/DriveCommand).
The PI law and the reflection of tau_d through the gearbox (Eq. 28) live in
speed_controller; this node wires them. Feedforward uses only fresh estimates
(younger than estimate_timeout, not flagged invalid or out of calibration:
speed_controller.FeedforwardGate); otherwise it is 0 and the PI alone holds
the speed. Output limit: the commanded voltage stays within +-voltage_limit
(default: the rig's supply), and the integrator does not wind up while the
output is limited (SpeedController's conditional integration). `feedforward`
and `speed_setpoint` may be changed at run time (ros2 param set).
"""
from __future__ import annotations

import math

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from std_msgs.msg import Float64
from worm_msgs.msg import DriveCommand, RigSample, TorqueEstimate

from worm_model.ros.diagnostics import OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.physics.parameters import load_rig

from torque_estimator.control.speed_controller import DEFAULT_GAINS, FeedforwardGate, PiGains, SpeedController, feedforward_torque


class ControllerNode(Node):
    def __init__(self) -> None:
        super().__init__("controller_node")
        rig_file = declare(self, "rig_file", "", "Rig parameter YAML (worm_model format); empty = bundled NMRV030 rig.")
        kp = declare(self, "kp", DEFAULT_GAINS.kp, "Proportional gain [N m s/rad].", low=0.0, high=10.0)
        ki = declare(self, "ki", DEFAULT_GAINS.ki, "Integral gain [N m/rad].", low=0.0, high=1000.0)
        self.rig = load_rig(rig_file or None)
        limit = declare(self, "voltage_limit", self.rig.supply_voltage,
                        "Largest drive voltage magnitude commanded [V].", low=0.0, high=1000.0)
        feedforward = declare(self, "feedforward", True,
                              "Add the estimated load torque, reflected through the gearbox, as feedforward.")
        self.speed_setpoint = declare(self, "speed_setpoint", 0.0, "Worm speed set-point [rad/s].",
                                      low=-1000.0, high=1000.0)
        estimate_timeout = declare(self, "estimate_timeout", 0.05,
                                   "Estimates older than this [s] are not used.", low=0.0, high=10.0)
        self.period = 1.0 / declare(self, "sample_rate", 1000.0, "Rig sample rate [Hz].", low=1.0, high=100000.0)
        self.controller = SpeedController(self.rig, PiGains(kp, ki), voltage_limit=limit)
        self.gate = FeedforwardGate(estimate_timeout, enabled=feedforward)
        self.add_on_set_parameters_callback(self.on_parameters)

        self.pub = self.create_publisher(DriveCommand, "/rig/drive_command", STREAM)
        self.create_subscription(RigSample, "/rig/sample", self.on_sample, STREAM)
        self.create_subscription(TorqueEstimate, "/torque_estimate", self.on_estimate, STREAM)
        self.create_subscription(Float64, "/controller/speed_setpoint", self.on_setpoint, COMMAND)
        self.estimate_stamp = None
        self.samples = 0
        self.feedforward_used = 0
        self.saturated = 0
        Diagnostics(self, self.report)

    def on_parameters(self, params) -> SetParametersResult:
        for p in params:
            if p.name == "feedforward":
                self.gate.enabled = bool(p.value)
            elif p.name == "speed_setpoint":
                self.speed_setpoint = float(p.value)
        return SetParametersResult(successful=True)

    def on_setpoint(self, msg: Float64) -> None:
        if not math.isfinite(msg.data):
            self.get_logger().warning(f"ignored speed set-point {msg.data}: not finite")
            return
        self.speed_setpoint = msg.data

    def on_estimate(self, msg: TorqueEstimate) -> None:
        self.gate.offer(msg.torque, msg.flags, seconds(msg.header.stamp))
        self.estimate_stamp = msg.header.stamp

    def on_sample(self, sample: RigSample) -> None:
        self.samples += 1
        tau_d = self.gate.load(seconds(sample.header.stamp))
        tau_ff = 0.0 if tau_d is None else float(feedforward_torque(self.rig, tau_d, self.speed_setpoint))
        out = self.controller.update(self.period, self.speed_setpoint, sample.omega_worm, tau_ff)
        cmd = DriveCommand(voltage=float(out.voltage[0]), sample_seq=sample.seq, sample_stamp=sample.header.stamp,
                           feedforward_torque=tau_ff, speed_setpoint=self.speed_setpoint)
        if tau_d is not None:
            cmd.feedforward_stamp = self.estimate_stamp
            self.feedforward_used += 1
        self.saturated += int(out.saturated[0])
        cmd.header.stamp = self.get_clock().now().to_msg()
        cmd.header.frame_id = sample.header.frame_id
        self.pub.publish(cmd)

    def report(self) -> tuple[bytes, str, dict]:
        fresh = self.feedforward_used
        level = WARN if self.gate.enabled and self.samples and not fresh else OK
        return level, ("feedforward wanted but no usable estimate" if level == WARN else "controlling"), {
            "samples": self.samples, "feedforward_used": fresh, "saturated": self.saturated,
            "speed_setpoint": self.speed_setpoint, "feedforward": self.gate.enabled}


def seconds(stamp) -> float:
    """A builtin_interfaces/Time as seconds (float)."""
    return stamp.sec + stamp.nanosec * 1e-9


def main(args=None) -> int:
    return run_node(ControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
