"""controller_node: worm speed control with the estimated load torque as feedforward.

The speed PI runs where the rig is, on every 1 kHz sample (sim_node, driver_node:
worm_rig_driver.drive), the way a motor drive runs its velocity loop; this node
tells it what to do, like a motion controller sending a drive its velocity
set-point and torque offset. Subscribes torque_estimate (worm_msgs/TorqueEstimate,
the estimator's newest estimate per batch of rig samples) and
controller/speed_setpoint (std_msgs/Float64 [rad/s]); publishes
rig/speed_command (worm_msgs/SpeedCommand: set-point, feedforward torque at the
worm, the PI gains and the voltage limit), all relative to the node's namespace.
A command goes out with an estimate (computed the moment it arrives): with every one
while this node's own feedforward is in use (it rides on the command); otherwise
(feedforward at the rig, or off) when the set-point, gains or feedforward settings
changed, or ``command_period`` has passed since the last on the estimates' own stamps (so
one every 20 ms of the rig's clock, however the estimates' transit jitters); and at least
every ``command_period`` without estimates, so the rig's watchdog (command_timeout) stops
the drive only when this node is gone.

The estimate comes from /torque_estimate by default (``feedforward_source``
torque_estimate: worm_msgs/TorqueEstimate, with its quality flags), or from
another stack's standard message: ``joint_state`` (sensor_msgs/JointState, the
effort of ``joint_name``: the torque the load applies in the joint's positive
direction, so tau_d = -effort) or ``wrench`` (geometry_msgs/WrenchStamped,
tau_d = -torque.z), on ``feedforward_topic`` (default: the estimator's topic
for that type). Those carry no flags: only fresh, finite, plausible values are used.

The feedforward is the estimated load tau_d reflected through the gearbox at the
set-point speed (Eq. 28, worm_model.physics.steady_state.balancing_torque), from
usable estimates only (younger than estimate_timeout when the command goes out: an estimate that
arrives late counts as that much older, FeedforwardGate; not flagged invalid or out
of calibration: control.feedforward.FeedforwardGate); otherwise it is 0 and the
PI alone holds the speed. With ``feedforward_at_rig`` the command asks the rig
to feed forward its own estimator's load instead (computed beside its PI on every
sample: the next period, not a batch and a transit later; a rig without one uses
this node's). `feedforward`, `feedforward_at_rig`, `speed_setpoint`, `kp`, `ki` and
`voltage_limit` may be changed at run time (ros2 param set).
"""
from __future__ import annotations

import math

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.time import Time
from geometry_msgs.msg import WrenchStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from worm_msgs.msg import SpeedCommand, TorqueEstimate

from worm_model.physics.parameters import load_rig
from worm_model.physics.steady_state import make_balancing_torque_float
from worm_model.ros.diagnostics import OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.cli.node_options import RIG_FILE
from worm_model.ros.parameters import declare, declare_option
from worm_model.ros.commands import subscribe_command
from worm_model.ros.qos import STREAM
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS

from torque_estimator.control.feedforward import FeedforwardGate


#: feedforward_source -> (message type, the estimator's topic for it)
SOURCES = {"torque_estimate": (TorqueEstimate, "torque_estimate"),
           "joint_state": (JointState, "torque_estimate/joint_states"),
           "wrench": (WrenchStamped, "torque_estimate/wrench")}


class ControllerNode(Node):
    def __init__(self) -> None:
        super().__init__("controller_node")
        rig_file = declare_option(self, RIG_FILE)
        self.kp = declare(self, "kp", DEFAULT_GAINS.kp, "Proportional gain of the rig's speed PI [N m s/rad].",
                          low=0.0, high=10.0)
        self.ki = declare(self, "ki", DEFAULT_GAINS.ki, "Integral gain of the rig's speed PI [N m/rad].",
                          low=0.0, high=1000.0)
        self.rig = load_rig(rig_file or None)
        self.voltage_limit = declare(self, "voltage_limit", self.rig.supply_voltage,
                                     "Largest drive voltage magnitude the rig's PI may command [V].",
                                     low=0.001, high=1000.0)
        feedforward = declare(self, "feedforward", True,
                              "Add the estimated load torque, reflected through the gearbox, as feedforward.")
        self.speed_setpoint = declare(self, "speed_setpoint", 0.0, "Worm speed set-point [rad/s].",
                                      low=-1000.0, high=1000.0)
        estimate_timeout = declare(self, "estimate_timeout", 0.05,
                                   "Estimates older than this [s] are not used.", low=0.0, high=10.0)
        max_load = declare(self, "max_load", 1.5 * self.rig.max_load_torque,
                           "Estimates of a larger load [N m] are not fed forward (implausible; default 1.5 x the "
                           "rig file's max_load_torque).", low=0.0, high=1e6)
        self.command_period = declare(self, "command_period", 0.02,
                                      "Longest time [s] between speed commands (keep it well below the rig's "
                                      "command_timeout); with estimates arriving and no feedforward of this "
                                      "node's riding on them, also the commands' period.", low=0.001, high=1.0)
        self.feedforward_at_rig = declare(
            self, "feedforward_at_rig", False,
            "Ask the rig to feed forward its own estimator's load (SpeedCommand.feedforward_at_rig; sim_node / "
            "driver_node parameter feedforward_estimator), computed beside its speed loop on every sample, "
            "instead of this node's; the command still carries this node's feedforward_torque, which a rig "
            "without an estimator uses. Only while feedforward is on.")
        self.gate = FeedforwardGate(estimate_timeout, enabled=feedforward, max_load=max_load)
        self.balancing_torque = make_balancing_torque_float(self.rig)
        self.add_on_set_parameters_callback(self.on_parameters)

        source = declare(self, "feedforward_source", "torque_estimate",
                         "Message the load estimate comes in: torque_estimate (worm_msgs/TorqueEstimate), "
                         "joint_state (sensor_msgs/JointState effort, tau_d = -effort) or wrench "
                         "(geometry_msgs/WrenchStamped, tau_d = -torque.z).", choices=tuple(SOURCES))
        topic = declare(self, "feedforward_topic", "",
                        "Topic of that message; empty = the estimator's: " +
                        ", ".join(f"{k}: {v[1]}" for k, v in SOURCES.items()) + ".")
        self.joint_name = declare(self, "joint_name", "gear", "Joint whose effort a JointState source gives.")
        self.pub = self.create_publisher(SpeedCommand, "rig/speed_command", STREAM)
        msg_type, default_topic = SOURCES[source]
        handler = {"torque_estimate": self.on_estimate, "joint_state": self.on_joint_state,
                   "wrench": self.on_wrench}[source]
        self.create_subscription(msg_type, topic or default_topic, handler, STREAM)
        subscribe_command(self, Float64, "controller/speed_setpoint", self.on_setpoint)
        self.create_timer(self.command_period, self.on_timer)
        self.estimate: TorqueEstimate | None = None
        self.last_sent = -math.inf  # [s] node clock
        self._estimate_stamp = 0.0  # [s] the newest estimate's stamp (the rig's clock)
        self._sent_stamp = -math.inf  # [s] that stamp when the last command went out
        self._sent_terms: tuple | None = None  # what the last command said, but its feedforward torque
        self.last_estimate_at = -math.inf  # [s] node clock
        self.commands = 0
        self.feedforward_used = 0
        self.late_estimates = 0
        Diagnostics(self, self.report)

    def on_parameters(self, params) -> SetParametersResult:
        for p in params:
            if p.name == "feedforward":
                self.gate.enabled = bool(p.value)
            elif p.name == "feedforward_at_rig":
                self.feedforward_at_rig = bool(p.value)
            elif p.name in ("speed_setpoint", "kp", "ki", "voltage_limit"):
                setattr(self, p.name, float(p.value))
        return SetParametersResult(successful=True)

    def on_setpoint(self, msg: Float64) -> None:
        if not math.isfinite(msg.data):
            self.get_logger().warning(f"ignored speed set-point {msg.data}: not finite")
            return
        self.speed_setpoint = msg.data

    def on_estimate(self, msg: TorqueEstimate) -> None:
        self._estimate_stamp = seconds(msg.header.stamp)
        self.gate.offer(msg.torque, msg.flags, self._estimate_stamp, self.clock_seconds())
        self._check_late()
        self.estimate = msg
        self.last_estimate_at = self.clock_seconds()
        if self._command_due():
            self.send()

    def _terms(self) -> tuple:
        return (self.speed_setpoint, self.kp, self.ki, self.voltage_limit, self.gate.enabled, self.feedforward_at_rig)

    def _command_due(self) -> bool:
        """Whether an estimate that just arrived sends a command (module docstring): always while this node's
        feedforward rides on the commands; else on a change of what they say, or after command_period on the
        estimates' stamps (exact on the rig's clock, where arrival times jitter: a 20 ms period judged on
        arrivals 10 ms apart would often wait for a third estimate). A stamp that went back (the rig started
        again) or a stream clock that stalls against this node's (1.5 periods) sends at once."""
        if self.gate.enabled and not self.feedforward_at_rig:
            return True
        since = self._estimate_stamp - self._sent_stamp
        return (self._terms() != self._sent_terms or not 0.0 <= since < self.command_period - 1e-9
                or self.clock_seconds() - self.last_sent >= 1.5 * self.command_period)

    def _check_late(self) -> None:
        """Count, and say at most once a second, that an estimate arrived too late to be fed forward."""
        late = self.gate.age(self.clock_seconds())
        if late > self.gate.timeout:
            self.late_estimates += 1
            self.get_logger().warning(
                f"estimate arrived {late * 1e3:.0f} ms later than the stream's usual lag "
                f"({self.gate.clock_lag * 1e3:.1f} ms): not fed forward (estimate_timeout "
                f"{self.gate.timeout * 1e3:.0f} ms)", throttle_duration_sec=1.0)

    def on_joint_state(self, msg: JointState) -> None:
        if self.joint_name not in msg.name:
            return
        k = msg.name.index(self.joint_name)
        effort = msg.effort[k] if k < len(msg.effort) else math.nan
        self._offer_plain(-effort, msg.header)

    def on_wrench(self, msg: WrenchStamped) -> None:
        self._offer_plain(-msg.wrench.torque.z, msg.header)

    def _offer_plain(self, tau_d: float, header) -> None:
        """An estimate from a standard message: no seq, no flags (only freshness and plausibility)."""
        self._estimate_stamp = seconds(header.stamp)
        self.gate.offer(tau_d, 0, self._estimate_stamp, self.clock_seconds())
        self._check_late()
        self.estimate = None
        self.last_estimate_at = self.clock_seconds()
        if self._command_due():
            self.send()

    def on_timer(self) -> None:
        """Commands without estimates (none arrive, or too rarely): the rig's watchdog must not starve."""
        now = self.clock_seconds()
        if now - self.last_estimate_at >= self.command_period and now - self.last_sent >= 0.5 * self.command_period:
            self.send()

    def clock_seconds(self) -> float:
        """This node's clock [s]."""
        return self.get_clock().now().nanoseconds * 1e-9

    def send(self) -> None:
        """One speed command for the rig, now (the node's clock), with the feedforward of the estimate
        usable now (FeedforwardGate: an estimate that arrives later than the stream's best is older by
        that much, one that never comes ages with this clock)."""
        clock_now = self.get_clock().now()
        tau_d = self.gate.load(clock_now.nanoseconds * 1e-9)
        tau_ff = 0.0 if tau_d is None else self.balancing_torque(tau_d, self.speed_setpoint)
        cmd = SpeedCommand(speed_setpoint=self.speed_setpoint, feedforward_torque=tau_ff, kp=self.kp, ki=self.ki,
                           voltage_limit=self.voltage_limit,
                           feedforward_at_rig=self.gate.enabled and self.feedforward_at_rig)
        if self.estimate is not None:
            cmd.sample_seq = self.estimate.seq
            cmd.sample_stamp = self.estimate.header.stamp
            cmd.header.frame_id = self.estimate.header.frame_id
            if tau_d is not None:
                cmd.feedforward_stamp = self.estimate.header.stamp
                self.feedforward_used += 1
        cmd.header.stamp = clock_now.to_msg()
        self.pub.publish(cmd)
        self._sent_terms = self._terms()
        self._sent_stamp = self._estimate_stamp
        self.commands += 1
        self.last_sent = clock_now.nanoseconds * 1e-9

    def report(self) -> tuple[bytes, str, dict]:
        level = WARN if self.gate.enabled and self.commands and not self.feedforward_used else OK
        return level, ("feedforward wanted but no usable estimate" if level == WARN else "controlling"), {
            "commands": self.commands, "feedforward_used": self.feedforward_used,
            "estimate_clock_lag_ms": round(self.gate.clock_lag * 1e3, 3), "late_estimates": self.late_estimates,
            "speed_setpoint": self.speed_setpoint, "feedforward": self.gate.enabled,
            "feedforward_at_rig": self.feedforward_at_rig}


def seconds(stamp) -> float:
    """A builtin_interfaces/Time as seconds (float)."""
    return Time.from_msg(stamp).nanoseconds * 1e-9


def main(args=None) -> int:
    return run_node(ControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
