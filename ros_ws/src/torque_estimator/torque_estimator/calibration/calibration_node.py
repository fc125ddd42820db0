"""The ROS shell of `calibrate --live`: drive whatever rig is on the graph through the grid.

Publishes the current point's load torque on /rig/load_command
(worm_msgs/LoadCommand) and its worm speed on /controller/speed_setpoint
(std_msgs/Float64), both reliable and latched; reads /rig/samples (RigSamples)
and /rig/speed_command (SpeedCommand). The rig is sim_node or driver_node, held
by its own speed loop on the set-point controller_node sends: calibrate does
not close a loop over DDS itself, so the rig is held by the same controller
(gains, limits, watchdog) as in operation. A point's samples are counted from
the first sample after controller_node's speed commands carry the new set-point. Sequencing,
steady-state detection and the journal live in live_calibration.
"""
from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.node import Node
from std_msgs.msg import Float64
from worm_msgs.msg import LoadCommand, RigSamples, SpeedCommand

from worm_model.ros.qos import COMMAND, STREAM

from torque_estimator.calibration.live import TOPICS, LiveRigError, PointByPoint
from torque_estimator.calibration.rig_session_node import rig_session


class CalibrationClient(Node):
    """Commands the rig's set-points and feeds its samples to a PointByPoint run."""

    def __init__(self, run: PointByPoint) -> None:
        super().__init__("calibrate")
        self.run = run
        self.samples = 0
        self.last_sample = time.monotonic()
        self.speed_commands = 0
        self.controller_setpoint: float | None = None
        self.speed_pub = self.create_publisher(Float64, TOPICS["speed_setpoint"], COMMAND)
        self.load_pub = self.create_publisher(LoadCommand, TOPICS["load_command"], COMMAND)
        self.create_subscription(RigSamples, TOPICS["samples"], self.on_samples, STREAM)
        self.create_subscription(SpeedCommand, TOPICS["speed_command"], self.on_speed_command, STREAM)

    def on_samples(self, msg: RigSamples) -> None:
        self.samples += len(msg.omega_worm)
        self.last_sample = time.monotonic()
        for omega, current, load in zip(msg.omega_worm, msg.current_drive, msg.tau_load):
            self.run.add(omega, current, load)

    def on_speed_command(self, msg: SpeedCommand) -> None:
        self.speed_commands += 1
        self.controller_setpoint = msg.speed_setpoint

    def stop_rig(self) -> None:
        self.command(0.0, 0.0)

    def command(self, speed: float, torque: float) -> None:
        """Ask for a worm speed [rad/s] and a load torque [N m] (positive opposing + rotation)."""
        load = LoadCommand(torque=float(torque))
        load.header.stamp = self.get_clock().now().to_msg()
        self.load_pub.publish(load)
        self.speed_pub.publish(Float64(data=float(speed)))


def run_live(run: PointByPoint, *, start_timeout: float = 30.0, ack_timeout: float = 5.0,
             stall_timeout: float = 5.0, on_point: Callable[[], None] | None = None,
             on_tick: Callable[[], None] | None = None) -> None:
    """Measure every pending point of `run` on the rig of the current ROS graph.

    Args:
        start_timeout: wait this long [s] for rig samples and controller_node's speed commands.
        ack_timeout: wait this long [s] for controller_node to take a new set-point.
        stall_timeout: samples stopping for this long [s] aborts the run.
        on_point: called after every finished (journalled) point.
        on_tick: called about every 0.1 s (progress display).

    Raises:
        LiveRigError: no rig, no controller, or the rig stopped sending; the
            journal keeps every point finished before.
        KeyboardInterrupt: Ctrl-C (or SIGTERM turned into it by the caller).
    On every exit the load torque and the speed set-point are commanded to 0.
    """
    with rig_session(lambda: CalibrationClient(run), start_timeout=start_timeout, on_tick=on_tick) as (
            node, spin_until):
        while (point := run.current) is not None:
            node.command(point.speed, point.torque)
            if not spin_until(lambda: node.controller_setpoint == point.speed, ack_timeout):
                raise LiveRigError(f"controller_node did not take the speed set-point {point.speed:g} rad/s "
                                   f"within {ack_timeout:g} s (its speed commands say "
                                   f"{node.controller_setpoint!r})")
            run.start()
            node.last_sample = time.monotonic()
            spin_until(lambda: run.current != point or time.monotonic() - node.last_sample > stall_timeout,
                       float("inf"))
            if run.current == point:
                raise LiveRigError(f"no samples on {TOPICS['samples']} for {stall_timeout:g} s "
                                   f"(point {point.plan_index}: {point.speed:g} rad/s, {point.torque:g} N m)")
            if on_point is not None:
                on_point()


__all__ = ["CalibrationClient", "run_live"]
