"""For the system tests and bench scripts that reach nodes over DDS. The nodes do not use it.

* :func:`local_domain`: environment variables that keep a run's graph to itself.
  The run gets its own ROS_DOMAIN_ID: the caller's if it set one, so that parallel
  runs can be given distinct ones, else a random one in 100..230. Discovery stays
  on this host.
* :func:`probe_node`: a node in the test's own process, with its own context,
  taken down in the order rclpy needs (see lifecycle.py).
* :func:`spin_until`: spins a probe's executor until a condition holds or a timeout
  passes.
* :func:`stop_process`: stops a node's process the way Ctrl-C does, and SIGKILLs
  it if it hangs.
* :func:`rig_samples`: a worm_msgs/RigSamples batch with every field filled, from
  the values a test cares about (the rest zero), as a rig would publish it.
"""
from __future__ import annotations

import os
import random
import signal
import subprocess
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager

import rclpy
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node

#: domains drawn when the caller sets none: clear of 0 (the default) and of small ids people pick
RANDOM_DOMAINS = (100, 230)


def _domains() -> tuple[int, int]:
    """RANDOM_DOMAINS, or this pytest-xdist worker's share of them (workers gw0, gw1, ... draw from disjoint
    ranges, so two test modules running at once never meet on one domain)."""
    low, high = RANDOM_DOMAINS
    worker, count = os.environ.get("PYTEST_XDIST_WORKER", ""), os.environ.get("PYTEST_XDIST_WORKER_COUNT", "")
    if not (worker.startswith("gw") and worker[2:].isdigit() and count.isdigit() and int(count) > 1):
        return low, high
    size = (high - low + 1) // int(count)
    first = low + int(worker[2:]) % int(count) * size
    return first, first + size - 1


def local_domain(environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST for a run of its own.

    Args:
        environ: where a ROS_DOMAIN_ID set by the caller is looked for; ``os.environ`` when None.
    """
    domain = (os.environ if environ is None else environ).get("ROS_DOMAIN_ID") or str(random.randint(*_domains()))
    return {"ROS_DOMAIN_ID": domain, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


@contextmanager
def probe_node(name: str, executor_type: Callable[..., Executor] = SingleThreadedExecutor
               ) -> Iterator[tuple[Node, Executor]]:
    """A node named ``name`` and an executor that holds it, in a fresh rclpy context.

    The caller spins the executor itself. When the block is left, the executor is
    shut down, then the node is destroyed, then the context is shut down.
    """
    context = Context()
    rclpy.init(context=context)
    node = Node(name, context=context)
    executor = executor_type(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def spin_until(executor: Executor, done: Callable[[], bool], timeout: float, step: float = 0.05) -> bool:
    """Spin ``executor`` until ``done()`` is true or ``timeout`` [s] has passed (monotonic clock), each wait at
    most ``step`` [s]; returns ``done()``."""
    deadline = time.monotonic() + timeout
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=step)
    return done()


def stop_process(process: subprocess.Popen, grace: float = 15.0) -> int:
    """Send SIGINT, as Ctrl-C does. If the process has not exited after ``grace`` [s], SIGKILL it.

    Returns:
        the exit code. A node that cleans up returns 0. -9 means it had to be killed.
    """
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        return process.wait(grace)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.wait()


def rig_samples(first_seq: int, n: int, stamp=None, sample_period: float = 1e-3, frame_id: str = "worm_rig",
                **values: object):
    """A worm_msgs/RigSamples message of ``n`` samples from ``first_seq``: each keyword is a field,
    given as a sequence of n values or one value for all; fields not given are 0."""
    from worm_msgs.msg import RigSamples

    columns = {}
    for name, kind in RigSamples.get_fields_and_field_types().items():
        if not kind.startswith("sequence<"):
            continue
        value = values.pop(name, 0)
        items = list(value) if isinstance(value, (list, tuple)) else [value] * n
        columns[name] = [float(v) for v in items] if "double" in kind else [int(v) for v in items]
    if values:
        raise TypeError(f"RigSamples has no fields {sorted(values)}")
    msg = RigSamples(first_seq=first_seq, sample_period=sample_period, **columns)
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    return msg
