"""model_node over real DDS: when it processes its queued samples.

model_node runs alone as its own process; the probe publishes rig/samples and reads
gearbox/forces. It processes once the queued samples span publish_period on the
stream's own clock (their sample_period), so the forces follow the stream however its
messages arrive; a stream that stops short of a period is processed when publish_period
passes on the node's clock.

ROS_DOMAIN_ID: the environment's if set, else a random one in 100..230;
discovery stays on this host (the ros_env fixture of tests/conftest.py).
"""
from __future__ import annotations

import time
from collections.abc import Callable

from worm_msgs.msg import GearboxForces, RigSamples

from torque_estimator.graph.runner import Graph
from worm_model.rig_data.samples import FIELDS
from worm_model.ros.qos import STREAM
from worm_model.ros.testing import probe_node, spin_until

PERIOD = 0.02  # [s] model_node's publish_period
WARM_UP = 1001  # first seq of the messages that wait for model_node to take the probe's


def batch(first_seq: int, n: int, sample_period: float) -> RigSamples:
    """``n`` samples of a worm turning at 100 rad/s against 0.1 N m, from ``first_seq``."""
    values = {name: [0] * n for name in FIELDS}
    values.update(omega_worm=[100.0] * n, current_drive=[0.5] * n, tau_load=[0.1] * n)
    msg = RigSamples(first_seq=first_seq, sample_period=sample_period, command_seq=[0] * n, **values)
    msg.header.stamp.sec = 1000 + first_seq
    return msg


def test_forces_follow_the_streams_clock_and_a_stalled_stream_is_processed(
        start_graph: Callable[[str, str], Graph]) -> None:
    graph = start_graph(f"model_node:\n  ros__parameters:\n    publish_period: {PERIOD}\n", "model_node")
    with probe_node("model_node_probe") as (node, executor):
        forces: list = []
        sub = node.create_subscription(GearboxForces, "/gearbox/forces", forces.append, STREAM)
        pub = node.create_publisher(RigSamples, "/rig/samples", STREAM)
        assert spin_until(executor, lambda: pub.get_subscription_count() > 0 and sub.get_publisher_count() > 0,
                          30.0), f"logs in {graph.log_dir}"
        # each side matches the other in its own time: a period of samples until its forces come back says
        # that model_node takes the probe's messages, not only that the probe sees model_node
        deadline = time.monotonic() + 30.0
        while not forces and time.monotonic() < deadline:
            pub.publish(batch(WARM_UP, 2, 0.01))
            spin_until(executor, lambda: bool(forces), 0.2)
        assert forces, f"model_node never answered a period of samples; logs in {graph.log_dir}"
        forces.clear()

        # 20 messages of 2 samples 10 ms apart (a period of stream each), sent within ~40 ms of the node's
        # clock: one forces message per message, for its newest sample. A node that processed on its own
        # clock would publish two or three.
        newest = []
        for k in range(20):
            pub.publish(batch(1 + 2 * k, 2, 0.01))
            newest.append(2 + 2 * k)
            executor.spin_once(timeout_sec=0.002)

        def burst() -> list[int]:  # a warm-up message still in flight may answer now: its forces are left out
            return [f.seq for f in forces if f.seq != WARM_UP + 1]

        assert spin_until(executor, lambda: len(burst()) >= 20, 5.0) or len(burst()) >= 15, (
            f"{len(burst())} forces messages for 20 periods of samples; logs in {graph.log_dir}")
        assert set(burst()) <= set(newest), sorted(burst())

        # half a period of stream, then nothing: processed after publish_period of the node's clock
        forces.clear()
        pub.publish(batch(41, 1, 0.01))
        assert spin_until(executor, lambda: bool(forces), 5.0), "a stream that stalled short of a period " \
                                                                   "was never processed"
        assert [f.seq for f in forces] == [41]
    assert not graph.failed(), graph.failed()
