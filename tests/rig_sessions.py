"""What the tests of a session with a live rig share (calibrate --live, identify, health_check over DDS): the
graph such a session drives, and the speed command the rig is left with."""
from __future__ import annotations

import time

from worm_msgs.msg import SpeedCommand

from worm_model.ros.qos import STREAM
from worm_model.ros.testing import probe_node


def session_graph(seed: int) -> str:
    """sim_node (the rig; driver_node takes its place on the real rig) and controller_node with feedforward off
    (a session runs before there is a calibration or an identified rig file), as a graph file."""
    return f"""\
sim_node:
  ros__parameters:
    seed: {seed}
    batch_size: 5
    channel_decimation: 10
    publish_truth: false
    command_timeout: 0.5
controller_node:
  ros__parameters:
    feedforward: false
    speed_setpoint: 0.0
"""


def last_speed_command(probe: str, timeout: float = 10.0) -> SpeedCommand | None:
    """The 20th speed command controller_node sends the rig from now (fewer if ``timeout`` [s] runs out; None if
    none came), heard by a probe node of this name in this process."""
    got: list[SpeedCommand] = []
    with probe_node(probe) as (node, executor):
        node.create_subscription(SpeedCommand, "/rig/speed_command", got.append, STREAM)
        deadline = time.monotonic() + timeout
        while len(got) < 20 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    return got[-1] if got else None
