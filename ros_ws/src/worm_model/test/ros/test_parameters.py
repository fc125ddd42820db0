"""Parameters no node declares are named (worm_model.ros.parameters): found from the arguments before anything
starts, with the closest declared name; and what run_graph checks of every node before it starts one."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from rclpy.node import Node

from worm_model.ros.parameters import (declare, declared_parameters, given_names, parameters_problem, ros_value,
                                       undeclared_problem)
from worm_model.ros.testing import local_domain


class Small(Node):
    def __init__(self) -> None:
        super().__init__("small_node")
        declare(self, "sample_rate", 1000.0, "Rig sample rate [Hz].", low=1.0, high=1e5)
        declare(self, "method", "knn", "Estimator.", choices=("knn", "observer"))
        declare(self, "k", 4, "Neighbours.", low=1, high=64)
        self.create_timer(1.0, lambda: None)


def test_given_names_follow_rcl(tmp_path: Path) -> None:
    graph = tmp_path / "graph.yaml"
    graph.write_text("small_node:\n  ros__parameters: {methd: knn}\n/**:\n  ros__parameters: {shared: 1}\n"
                     "other_node:\n  ros__parameters: {x: 1}\nns:\n  small_node:\n    ros__parameters: {k: 3}\n")
    argv = ["--ros-args", "--params-file", str(graph), "-p", "sampel_rate:=1000", "-p", "other_node:y:=2"]
    assert given_names(argv, "small_node") == {"methd": f"--params-file {graph}", "k": f"--params-file {graph}",
                                               "sampel_rate": "-p"}
    problem = undeclared_problem([Small], argv)
    assert problem.startswith(f"parameter methd (--params-file {graph}): small_node declares no such parameter "
                              "(did you mean 'method'?)"), problem
    assert undeclared_problem([Small], ["--ros-args", "-p", "k:=3", "--params-file", str(graph)][:3]) is None
    assert "did you mean 'sample_rate'" in undeclared_problem([Small], ["--ros-args", "-p", "sampel_rate:=1"])


def test_values_a_node_would_refuse_are_found_before_it_starts() -> None:
    declared = declared_parameters(Small)
    assert parameters_problem("small_node", declared, {"k": 3, "method": "observer", "sample_rate": 500.0}) is None
    for values, message in (({"k": ros_value("abc")}, "expected an integer like its default 4, got 'abc'"),
                            ({"k": 100}, "100 is out of range: must be in [1, 64]"),
                            ({"method": "kalman"}, "'kalman' is not one of knn, observer"),
                            ({"sample_rate": 1}, "expected a double"),  # rclpy refuses an integer for a double
                            ({"methd": "knn"}, "did you mean 'method'")):
        name, problem = parameters_problem("small_node", declared, values)
        assert name == next(iter(values)) and message in problem, problem
    assert parameters_problem("small_node", declared, {"sample_rate": ros_value("1e3")}) is None  # rcl reads a double


NODE = textwrap.dedent("""
    import sys
    from rclpy.node import Node
    from worm_model.ros.lifecycle import run_node
    from worm_model.ros.parameters import declare

    class Small(Node):
        def __init__(self):
            super().__init__("small_node")
            declare(self, "sample_rate", 1000.0, "Rig sample rate [Hz].", low=1.0, high=1e5)
            self.get_logger().info("built")  # a refusal must come before the node says a word

    sys.exit(run_node(Small, sys.argv))
""")


def test_a_node_refuses_an_undeclared_parameter_and_an_unreadable_parameter_file(tmp_path: Path) -> None:
    env = {**os.environ, **local_domain()}
    graph = tmp_path / "graph.yaml"
    graph.write_text("small_node:\n  ros__parameters: &p {sample_rate: 500.0}\nother:\n  ros__parameters: *p\n")
    for args, message in ((["-p", "sampel_rate:=1000.0"], "parameter sampel_rate (-p): small_node "
                                                          "declares no such parameter (did you mean 'sample_rate'?)"),
                          (["--params-file", str(graph)], "anchors, aliases or merge keys")):
        done = subprocess.run([sys.executable, "-c", NODE, "--ros-args", *args], capture_output=True, text=True,
                              env=env, timeout=120)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2 and len(lines) == 1 and message in lines[0], done.stderr
