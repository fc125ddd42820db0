"""The demo's live run: start the graph as a rig computer runs it, play a scenario on it, record every topic.

The ROS shell of the demo: a node that publishes the scenario's speed
set-points and load torques on schedule while a TopicRecorder writes every
topic of the graph to an MCAP bag.
"""
from __future__ import annotations

import time
from pathlib import Path

import rclpy
from rclpy.experimental import EventsExecutor
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64
from worm_msgs.msg import LoadCommand

from worm_model.ros.qos import COMMAND
from worm_model.bags.writer import BagWriter
from worm_rig_driver.nodes.recorder_node import TopicRecorder

from torque_estimator.graph.runner import Graph, rig_computer
from torque_estimator.evaluation.scenario import DEMO_SCENARIO, segment_at


#: what demo.load_run reads (the truth: every sample's, /sim/truth_samples)
ANALYSED_TOPICS = ("/rig/samples", "/sim/truth_samples", "/torque_estimate", "/rig/speed_command")


def live_run(graph_file: Path, calibration: Path, feedforward: bool, bag: Path, log_dir: Path) -> float:
    """Run the scenario on the live graph, recording every topic to `bag`; returns the start stamp [s]."""
    overrides = {"sim_node": [f"feedforward_calibration:={calibration}"],  # the rig's estimate is the graph's
                 "controller_node": [f"feedforward:={str(feedforward).lower()}", "speed_setpoint:=0.0"]}
    with Graph(graph_file, overrides, log_dir=log_dir, **rig_computer(graph_file)) as graph:
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node("demo_scenario")
        executor = EventsExecutor()
        executor.add_node(node)
        recorder = TopicRecorder(node, BagWriter(bag, "mcap"), message_info=False)
        try:
            recorder.subscribe_all()
            recorder.start_discovery(0.5)
            speed_pub = node.create_publisher(Float64, "controller/speed_setpoint", COMMAND)
            load_pub = node.create_publisher(LoadCommand, "rig/load_command", COMMAND)
            deadline = time.monotonic() + 60.0
            # Start the scenario only once every stream the analysis reads is being recorded: topics
            # are subscribed as discovery finds them, and a late /rig/samples or /sim/truth_samples would
            # leave the first seconds of the run out of the bag.
            while min(recorder.counts.get(t, 0) for t in ANALYSED_TOPICS) < 100:
                if graph.failed() or time.monotonic() > deadline:
                    raise RuntimeError(f"graph did not start (exited: {graph.failed()}); see {log_dir}")
                executor.spin_once(timeout_sec=0.05)
            start_stamp = node.get_clock().now().nanoseconds * 1e-9
            start = time.monotonic()
            current = None
            while (k := segment_at(DEMO_SCENARIO, time.monotonic() - start)) is not None:
                if k != current:
                    current = k
                    speed_pub.publish(Float64(data=DEMO_SCENARIO[k].speed))
                    load_pub.publish(LoadCommand(torque=DEMO_SCENARIO[k].load))
                executor.spin_once(timeout_sec=0.005)
            if graph.failed():
                raise RuntimeError(f"a node died during the run: {graph.failed()}; see {log_dir}")
        finally:
            recorder.close()
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown()
    return start_stamp
