"""A client's session with the rig on the ROS graph: what `calibrate --live` and `identify` share.

:func:`rig_session` starts rclpy with a client node (a node that publishes set-points on
/controller/speed_setpoint and /rig/load_command and counts /rig/samples and
/rig/speed_command), waits for the rig and for controller_node, hands the caller a
``spin_until`` to drive it with, and on every exit commands the rig to 0 rad/s and 0 N m
and takes rclpy down again.

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
from typing import Protocol, TypeVar

import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from torque_estimator.calibration.live import TOPICS, LiveRigError


class RigClient(Protocol):
    samples: int  # rig samples received so far
    speed_commands: int  # controller_node's speed commands received so far

    def stop_rig(self) -> None:
        """Command 0 rad/s and 0 N m."""


SpinUntil = Callable[[Callable[[], bool], float], bool]
N = TypeVar("N", bound=Node)


@contextmanager
def rig_session(make_node: Callable[[], N], *, start_timeout: float,
                on_tick: Callable[[], None] | None = None) -> Iterator[tuple[N, SpinUntil]]:
    """Yields (the client node, spin_until); the node must be a RigClient.

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


__all__ = ["RigClient", "SpinUntil", "rig_session"]
