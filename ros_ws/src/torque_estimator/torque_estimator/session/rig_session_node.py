"""A client's session with the rig on the ROS graph: what `calibrate --live` and `identify` share.

:class:`RigClient` is the client node (it publishes set-points on
/controller/speed_setpoint and /rig/load_command and counts /rig/samples and
/rig/speed_command; a session's measurement subclasses it). :func:`rig_session` starts
rclpy with one, waits for the rig and for controller_node, hands the caller a
``spin_until`` to drive it with, and on every exit commands the rig to 0 rad/s and 0 N m
and takes rclpy down again. :func:`await_setpoint` and :func:`measure_until` are a session's two waits.

Ctrl-C and SIGTERM only set a flag; ``spin_until`` turns it into a KeyboardInterrupt
between two executor steps. An interrupt raised asynchronously could land inside the
executor or a callback that is writing the journal, and the clean-up would then run on
a broken executor (seen as a traceback instead of exit 130, about 1 run in 10 on a
loaded machine).
"""
from __future__ import annotations

import signal
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64
from worm_msgs.msg import LoadCommand, RigSamples, SpeedCommand

from worm_model.ros.qos import COMMAND, STREAM

from torque_estimator.errors import LiveRigError
from torque_estimator.session.topics import TOPICS


class RigClient(Node):
    """A client of the rig on the graph: publishes its set-points (speed on /controller/speed_setpoint, load on
    /rig/load_command, reliable and latched), counts the rig's samples and controller_node's speed commands.
    A subclass takes each /rig/samples batch in :meth:`take`."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.samples = 0  # rig samples received so far
        self.last_sample = time.monotonic()  # [s] monotonic time of the last batch
        self.speed_commands = 0  # controller_node's speed commands received so far
        self.controller_setpoint: float | None = None  # [rad/s] the set-point its last speed command carried
        self.speed_pub = self.create_publisher(Float64, TOPICS["speed_setpoint"], COMMAND)
        self.load_pub = self.create_publisher(LoadCommand, TOPICS["load_command"], COMMAND)
        self.create_subscription(RigSamples, TOPICS["samples"], self.on_samples, STREAM)
        self.create_subscription(SpeedCommand, TOPICS["speed_command"], self.on_speed_command, STREAM)

    def on_samples(self, msg: RigSamples) -> None:
        self.samples += len(msg.omega_worm)
        self.last_sample = time.monotonic()
        self.take(msg)

    def take(self, msg: RigSamples) -> None:
        """One batch of the rig's samples (the subclass's measurement)."""

    def on_speed_command(self, msg: SpeedCommand) -> None:
        self.speed_commands += 1
        self.controller_setpoint = msg.speed_setpoint

    def publish_setpoints(self, speed: float, torque: float) -> None:
        """Ask for a worm speed [rad/s] and a load torque [N m] (positive opposing + rotation)."""
        load = LoadCommand(torque=float(torque))
        load.header.stamp = self.get_clock().now().to_msg()
        self.load_pub.publish(load)
        self.speed_pub.publish(Float64(data=float(speed)))

    def stop_rig(self) -> None:
        """Command 0 rad/s and 0 N m."""
        self.publish_setpoints(0.0, 0.0)


SpinUntil = Callable[[Callable[[], bool], float], bool]
N = TypeVar("N", bound=RigClient)


@contextmanager
def rig_session(make_node: Callable[[], N], *, start_timeout: float,
                on_tick: Callable[[], None] | None = None) -> Iterator[tuple[N, SpinUntil]]:
    """Yields (the client node, spin_until).

    ``spin_until(done, timeout)`` spins until ``done()`` (True) or ``timeout`` [s] (False), calling
    ``on_tick`` about every 0.1 s, and raises KeyboardInterrupt after a Ctrl-C or SIGTERM.

    Raises:
        LiveRigError: no rig samples, or no speed commands from controller_node, within ``start_timeout`` [s].
    """
    interrupted: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, _frame: interrupted.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = make_node()
    executor = EventsExecutor()
    executor.add_node(node)

    def spin_until(done: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        next_tick = time.monotonic()
        while not done():
            if interrupted:
                raise KeyboardInterrupt(f"signal {interrupted[0]}")
            now = time.monotonic()
            if now > deadline:
                return False
            if on_tick is not None and now >= next_tick:
                on_tick()
                next_tick = now + 0.1
            executor.spin_once(timeout_sec=0.02)
        return True

    try:
        if not spin_until(lambda: node.samples > 0, start_timeout):
            raise LiveRigError(f"no samples on {TOPICS['samples']} within {start_timeout:g} s: "
                               "is sim_node (or driver_node) running on this ROS_DOMAIN_ID?")
        if not spin_until(lambda: node.speed_commands > 0, start_timeout):
            raise LiveRigError(f"no speed commands on {TOPICS['speed_command']} within {start_timeout:g} s: "
                               "is controller_node running?")
        yield node, spin_until
    finally:
        # Leave the rig unloaded and stopped; reliable + latched, so give discovery a moment.
        node.stop_rig()
        interrupted.clear()  # a second Ctrl-C must not cut the stop command short
        try:
            spin_until(lambda: False, 0.3)
        except KeyboardInterrupt:
            pass
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def await_setpoint(node: RigClient, spin_until: SpinUntil, speed: float, timeout: float) -> None:
    """Spin until controller_node's speed commands carry ``speed`` [rad/s] (the rig holds the new set-point).

    Raises:
        LiveRigError: not within ``timeout`` [s].
    """
    if not spin_until(lambda: node.controller_setpoint == speed, timeout):
        raise LiveRigError(f"controller_node did not take the speed set-point {speed:g} rad/s within {timeout:g} s "
                           f"(its speed commands say {node.controller_setpoint!r})")


def measure_until(node: RigClient, spin_until: SpinUntil, done: Callable[[], bool], stall_timeout: float,
                  where: str) -> None:
    """Spin while the rig sends until ``done()``; ``where`` names the step for the error.

    Raises:
        LiveRigError: no samples for ``stall_timeout`` [s] before that.
    """
    node.last_sample = time.monotonic()
    spin_until(lambda: done() or time.monotonic() - node.last_sample > stall_timeout, float("inf"))
    if not done():
        raise LiveRigError(f"no samples on {TOPICS['samples']} for {stall_timeout:g} s ({where})")


__all__ = ["RigClient", "SpinUntil", "await_setpoint", "measure_until", "rig_session"]
