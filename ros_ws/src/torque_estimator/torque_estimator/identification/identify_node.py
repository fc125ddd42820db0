"""The ROS shell of live ``identify``: drive whatever rig is on the graph through the excitation.

Publishes the timeline's load torque on /rig/load_command (worm_msgs/LoadCommand) and its worm
speed on /controller/speed_setpoint (std_msgs/Float64), reliable and latched (worm_model.ros.qos
COMMAND), as the rig's sample clock walks the timeline; reads /rig/samples (RigSamples batches)
and /rig/speed_command (SpeedCommand).  The rig (sim_node or driver_node) is held by its own
speed loop on the set-points controller_node sends, as in operation and as ``calibrate --live``.
Recording starts with the first sample after controller_node's speed commands carry the first
set-point.  Timeline, samples and journal: identification.recording (no ROS there).
"""
from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.node import Node
from std_msgs.msg import Float64
from worm_msgs.msg import LoadCommand, RigSamples, SpeedCommand

from worm_model.ros.qos import COMMAND, STREAM

from torque_estimator.calibration.live import TOPICS, LiveRigError
from torque_estimator.calibration.rig_session_node import rig_session
from torque_estimator.identification.recording import ExcitationRun

#: a set-point is published again once it moved by this much (speed [rad/s], load [N m])
RESEND = (0.05, 2e-4)


class IdentifyClient(Node):
    """Commands the timeline's set-points and feeds the rig's samples to an ExcitationRun."""

    def __init__(self, run: ExcitationRun) -> None:
        super().__init__("identify")
        self.run = run
        self.recording = False
        self.samples = 0
        self.last_sample = time.monotonic()
        self.speed_commands = 0
        self.controller_setpoint: float | None = None
        self.sent: tuple[float, float] | None = None
        self.speed_pub = self.create_publisher(Float64, TOPICS["speed_setpoint"], COMMAND)
        self.load_pub = self.create_publisher(LoadCommand, TOPICS["load_command"], COMMAND)
        self.create_subscription(RigSamples, TOPICS["samples"], self.on_samples, STREAM)
        self.create_subscription(SpeedCommand, TOPICS["speed_command"], self.on_speed_command, STREAM)

    def on_samples(self, msg: RigSamples) -> None:
        self.samples += len(msg.omega_worm)
        self.last_sample = time.monotonic()
        if not self.recording:
            return
        for k in range(len(msg.omega_worm)):
            self.run.add({"current_drive": msg.current_drive[k], "omega_worm": msg.omega_worm[k],
                          "theta_worm": msg.theta_worm[k], "tau_load": msg.tau_load[k],
                          "voltage_drive": msg.voltage_drive[k], "theta_gear": msg.theta_gear[k],
                          "current_load": msg.current_load_1[k] + msg.current_load_2[k]})
        target = self.run.setpoints()
        if target is not None:
            self.command(*target)

    def on_speed_command(self, msg: SpeedCommand) -> None:
        self.speed_commands += 1
        self.controller_setpoint = msg.speed_setpoint

    def stop_rig(self) -> None:
        self.recording = False
        self.command(0.0, 0.0, force=True)

    def command(self, speed: float, torque: float, force: bool = False) -> None:
        """Ask for a worm speed [rad/s] and a load torque [N m] (sent when it moved by RESEND or ``force``)."""
        if not force and self.sent is not None and abs(speed - self.sent[0]) < RESEND[0] \
                and abs(torque - self.sent[1]) < RESEND[1]:
            return
        self.sent = (speed, torque)
        load = LoadCommand(torque=float(torque))
        load.header.stamp = self.get_clock().now().to_msg()
        self.load_pub.publish(load)
        self.speed_pub.publish(Float64(data=float(speed)))


def run_live(run: ExcitationRun, *, start_timeout: float = 30.0, ack_timeout: float = 5.0,
             stall_timeout: float = 5.0, on_tick: Callable[[], None] | None = None) -> None:
    """Record every pending segment of ``run`` on the rig of the current ROS graph.

    Raises:
        LiveRigError: no rig, no controller, or the rig stopped sending (the journal keeps every
            finished segment).
        KeyboardInterrupt: Ctrl-C or SIGTERM (turned into it between two executor steps).
    On every exit the load torque and the speed set-point are commanded to 0: the rig is left stopped.
    """
    with rig_session(lambda: IdentifyClient(run), start_timeout=start_timeout, on_tick=on_tick) as (
            node, spin_until):
        first = run.setpoints()
        if first is not None:
            node.command(*first, force=True)
            if not spin_until(lambda: node.controller_setpoint == first[0], ack_timeout):
                raise LiveRigError(f"controller_node did not take the speed set-point {first[0]:g} rad/s within "
                                   f"{ack_timeout:g} s (its speed commands say {node.controller_setpoint!r})")
            node.recording = True
            node.last_sample = time.monotonic()
            spin_until(lambda: run.finished or time.monotonic() - node.last_sample > stall_timeout, float("inf"))
            if not run.finished:
                raise LiveRigError(f"no samples on {TOPICS['samples']} for {stall_timeout:g} s "
                                   f"(segment {run.segment} of {len(run.timeline)})")


__all__ = ["IdentifyClient", "run_live"]
