"""One master for the motor over real DDS: while controller_node drives the rig, a second node's speed commands
change nothing at the rig and show up on its /diagnostics; once the controller is gone, the second node takes
over after the rig's command_timeout.

sim_node (command_timeout 0.5 s: a controller held off a loaded machine's cores for the rig's default 0.1 s
would lose its claim to the watchdog, which is the rule, not what is tested here) and controller_node (holding
100 rad/s) run as their own processes; the probe node publishes worm_msgs/SpeedCommand at 50 Hz asking for
-80 rad/s, as a stray `ros2 topic pub` would. The rig's speed is judged on its own samples, the ownership on
sim_node's /diagnostics (command_owner, refused_commands, refused_from); a std_msgs/Empty on /rig/release_command
frees the claim, and a command the rig itself refuses (a negative gain) takes no claim. Publishers are
told apart by the GID rclpy hands with each message: the test needs an rclpy that hands one (Kilted and newer;
Jazzy's does not, and the rig then takes every command).
"""
from __future__ import annotations

import signal
from collections.abc import Callable

import pytest
import rclpy.subscription
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Empty
from worm_msgs.msg import RigSample, RigSamples, SpeedCommand

from torque_estimator.graph.runner import Graph
from worm_model.rig_data.samples import unbatch
from worm_model.ros.qos import STREAM
from worm_model.ros.testing import probe_node, spin_until
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS

pytestmark = pytest.mark.skipif(
    "publisher_gid" not in getattr(getattr(rclpy.subscription, "MessageInfo", None), "__annotations__", {}),
    reason="this rclpy hands no publisher GID with a message (Jazzy)")

PARAMS = """\
sim_node:
  ros__parameters:
    command_timeout: 0.5
controller_node:
  ros__parameters:
    feedforward: false
    speed_setpoint: 100.0
"""
PROBE = "stray_commander"


def test_a_second_commander_is_refused_until_the_controller_is_gone(start_graph: Callable[[str, str], Graph]
                                                                     ) -> None:
    graph = start_graph(PARAMS, "one_master")
    with probe_node(PROBE) as (node, executor):
        samples: list = []
        status: dict[str, str] = {}

        def on_diagnostics(msg: DiagnosticArray) -> None:
            for s in msg.status:
                if s.name.endswith("sim_node"):
                    status.clear()
                    status.update({kv.key: kv.value for kv in s.values})

        node.create_subscription(RigSamples, "/rig/samples", lambda m: samples.extend(unbatch(m)), STREAM)
        node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
        stray = node.create_publisher(SpeedCommand, "/rig/speed_command", STREAM)

        def publish() -> None:
            stray.publish(SpeedCommand(speed_setpoint=-80.0, kp=DEFAULT_GAINS.kp, ki=DEFAULT_GAINS.ki,
                                       voltage_limit=12.0))

        assert spin_until(executor, lambda: bool(samples) and samples[-1].omega_worm > 90.0, 60.0), (
            f"the controller never brought the rig to 100 rad/s; logs in {graph.log_dir}")
        assert spin_until(executor, lambda: status.get("command_owner") == "/controller_node", 10.0), str(status)
        timer = node.create_timer(0.02, publish)
        assert spin_until(executor, lambda: int(status.get("refused_commands", "0")) >= 20, 30.0), status
        # two seconds of the rig's own samples while the stray commands flow: the controller's speed held
        samples.clear()
        assert spin_until(executor, lambda: len(samples) >= 2000, 60.0), "the rig stopped sampling"
        stopped = sum(bool(s.status & RigSample.STATUS_WATCHDOG_STOP) for s in samples)
        assert min(s.omega_worm for s in samples) > 90.0, (min(s.omega_worm for s in samples),
                                                            f"{stopped} samples stopped by the watchdog")
        assert status["command_owner"] == "/controller_node" and f"/{PROBE} (" in status["refused_from"], status

        graph.processes["controller_node"].send_signal(signal.SIGKILL)
        graph.processes["controller_node"].wait(10)
        assert spin_until(executor, lambda: bool(samples) and samples[-1].omega_worm < -70.0, 30.0), (
            f"the stray commander never took over: {status}")
        assert spin_until(executor, lambda: status.get("command_owner") == f"/{PROBE}", 10.0), str(status)
        timer.cancel()
        # the claim freed at once, as `ros2 topic pub --once /rig/release_command std_msgs/msg/Empty` frees it
        # (reliable, volatile)
        release = node.create_publisher(Empty, "/rig/release_command", QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE))
        assert spin_until(executor, lambda: release.get_subscription_count() > 0, 10.0)
        release.publish(Empty())
        assert spin_until(executor, lambda: status.get("command_owner") == "nobody", 10.0), str(status)
        # a command the rig refuses (finite, but a negative gain: the speed loop's own check) takes no claim
        rejected = int(status["rejected_commands"])
        for _ in range(5):
            stray.publish(SpeedCommand(speed_setpoint=-80.0, kp=-1.0, ki=DEFAULT_GAINS.ki, voltage_limit=12.0))
        assert spin_until(executor, lambda: int(status.get("rejected_commands", "0")) >= rejected + 5, 10.0), status
        assert status["command_owner"] == "nobody", status
    graph.processes.pop("controller_node")  # killed on purpose: not part of the clean-exit check
    assert not graph.failed(), graph.failed()
    assert graph.stop() == {"sim_node": 0}
