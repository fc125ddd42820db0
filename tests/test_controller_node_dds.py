"""controller_node over real DDS: its output limit and anti-windup, with a probe as the rig.

controller_node runs alone (its own process, voltage_limit 3 V, feedforward
off). The probe publishes rig samples of a worm that does not turn (as a
blocked or unpowered rig would report) and speed set-points, and records the
drive commands. Asking for 300 rad/s must give exactly the limit, never more;
after that, asking for 0 rad/s must give ~0 V at once: the integrator did not
wind up while the output was limited (a plain PI would have integrated
ki x 300 rad/s x 0.3 s = 1.8 N m and still command the full 3 V).

ROS_DOMAIN_ID: the environment's if set, else a random one in 100..230;
discovery stays on this host (the ros_env fixture of tests/conftest.py).
"""
from __future__ import annotations

import time
from collections.abc import Callable

import pytest
from rclpy.executors import Executor
from rclpy.node import Node
from std_msgs.msg import Float64
from worm_msgs.msg import DriveCommand, RigSample

from torque_estimator.graph.runner import Graph
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.ros.testing import probe_node

LIMIT = 3.0  # [V]
PARAMS = f"""\
controller_node:
  ros__parameters:
    voltage_limit: {LIMIT}
    feedforward: false
    speed_setpoint: 0.0
"""


@pytest.fixture(scope="module")
def controller(start_graph: Callable[[str, str], Graph]) -> Graph:
    """controller_node alone (ros_env and start_graph: tests/conftest.py)."""
    return start_graph(PARAMS, "controller")


class RigProbe:
    def __init__(self, node: Node, executor: Executor) -> None:
        self.node = node
        self.executor = executor
        self.commands: list[DriveCommand] = []
        self.node.create_subscription(DriveCommand, "/rig/drive_command", self.commands.append, STREAM)
        self.samples = self.node.create_publisher(RigSample, "/rig/sample", STREAM)
        self.setpoint = self.node.create_publisher(Float64, "/controller/speed_setpoint", COMMAND)
        self.seq = 0

    def spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        return done()

    def send_samples(self, count: int, omega: float = 0.0) -> None:
        """`count` samples of a worm turning at omega [rad/s], 1 ms apart on the sample clock."""
        for _ in range(count):
            self.seq += 1
            sample = RigSample(seq=self.seq, omega_worm=omega, status=RigSample.STATUS_SIMULATED)
            sample.header.stamp = self.node.get_clock().now().to_msg()
            self.samples.publish(sample)
            if self.seq % 20 == 0:  # let the commands in; keep the controller's queue short
                self.spin_until(lambda: False, 0.005)


def test_output_limit_and_no_windup_over_dds(controller: Graph) -> None:
    with probe_node("controller_test_rig") as (node, executor):
        probe = RigProbe(node, executor)
        matched = probe.spin_until(lambda: probe.samples.get_subscription_count() > 0
                                   and probe.setpoint.get_subscription_count() > 0, 30.0)
        assert matched, f"controller_node did not subscribe; logs in {controller.log_dir}"
        probe.setpoint.publish(Float64(data=300.0))

        def taken(speed: float) -> bool:
            probe.send_samples(5)
            return any(c.speed_setpoint == speed for c in probe.commands[-5:])
        assert probe.spin_until(lambda: taken(300.0), 15.0), "controller_node did not take 300 rad/s"

        probe.commands.clear()
        probe.send_samples(300)  # 0.3 s of a worm at rest against a 300 rad/s set-point
        probe.spin_until(lambda: False, 0.5)
        saturated = [c for c in probe.commands if c.speed_setpoint == 300.0]
        assert len(saturated) > 100, f"only {len(saturated)} drive commands for 300 samples"
        assert all(c.voltage == LIMIT for c in saturated), sorted({c.voltage for c in saturated})

        probe.setpoint.publish(Float64(data=0.0))
        assert probe.spin_until(lambda: taken(0.0), 15.0), "controller_node did not take 0 rad/s"
        after = [c for c in probe.commands if c.speed_setpoint == 0.0]
        assert after and all(abs(c.voltage) < 0.01 for c in after), [c.voltage for c in after]
        assert all(abs(c.voltage) <= LIMIT for c in probe.commands)
    assert not controller.failed(), controller.failed()
