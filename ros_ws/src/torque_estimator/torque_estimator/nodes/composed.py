"""Several nodes of a graph in one process, on one executor: the graph runner's ``--together``.

    python -m torque_estimator.nodes.composed --params-file graph.yaml [--namespace /arm/joint2] \\
        sim_node controller_node ...

Each node is the very class its executable runs (``ros2 run <pkg> <node>``
stays the way to run it alone) and reads its own section of the parameter file
by its name. Why: every process that talks DDS pays for its own wake-ups,
deserialisation and participant; nodes in one process share an executor and a
participant, which measured ~25 % less CPU per endpoint and much shorter
latency tails under load (bench/graph_bench.py). A node that blocks its
callbacks now delays the others: keep callbacks short (ours are).
"""
from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable

from rclpy.node import Node

from worm_model.ros.lifecycle import run_nodes

#: executable (= node) name -> "module:Class" of the nodes this project ships
NODE_CLASSES: dict[str, str] = {
    "sim_node": "worm_rig_driver.nodes.sim_node:SimNode",
    "driver_node": "worm_rig_driver.nodes.driver_node:DriverNode",
    "recorder": "worm_rig_driver.nodes.recorder_node:RecorderNode",
    "model_node": "worm_model.nodes.model_node:ModelNode",
    "estimator_node": "torque_estimator.nodes.estimator_node:EstimatorNode",
    "controller_node": "torque_estimator.nodes.controller_node:ControllerNode",
    "joint_state_merger": "worm_rig_driver.nodes.joint_state_merger:JointStateMergerNode",
}


def node_class(name: str) -> Callable[[], Node]:
    """The class of node ``name``.

    Raises:
        KeyError: not a node of this project.
    """
    module, _, cls = NODE_CLASSES[name].partition(":")
    return getattr(importlib.import_module(module), cls)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="composed", description=__doc__.split("\n\n")[0])
    parser.add_argument("--params-file", required=True, help="ROS 2 parameter file (each node reads its section)")
    parser.add_argument("--namespace", default="/", help="namespace of every node of this process (-r __ns:=)")
    parser.add_argument("nodes", nargs="+", choices=sorted(NODE_CLASSES), help="nodes to run in this process")
    args = parser.parse_args(argv)
    remap = ["-r", f"__ns:={args.namespace}"] if args.namespace != "/" else []
    return run_nodes([node_class(n) for n in args.nodes],
                     ["composed", "--ros-args", *remap, "--params-file", args.params_file])


if __name__ == "__main__":
    raise SystemExit(main())
