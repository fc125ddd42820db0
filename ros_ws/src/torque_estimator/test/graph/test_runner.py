"""The graph runner reads every form of node section ROS 2 parameter files take, namespaces included,
and starts each node the way `ros2 run ... --ros-args -r __ns:=... --params-file ...` would (no process
is started here: the commands are checked)."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from torque_estimator.graph.runner import (Graph, graph_nodes, graph_sections, process_file_name, rig_computer,
    split_name)
from torque_estimator.errors import GraphError

GRAPH = """\
/**:
  ros__parameters:
    use_sim_time: false
/arm/joint1/sim_node:
  ros__parameters:
    seed: 1
arm:
  joint2:
    sim_node:
      ros__parameters:
        seed: 2
    controller_node:
      ros__parameters:
        kp: 0.002
estimator_node:
  ros__parameters:
    method: knn
"""


@pytest.fixture
def graph_file(tmp_path: Path) -> Path:
    path = tmp_path / "graph.yaml"
    path.write_text(GRAPH, encoding="utf-8")
    return path


def test_nodes_flat_nested_and_plain(graph_file: Path) -> None:
    assert graph_nodes(graph_file) == ["/arm/joint1/sim_node", "/arm/joint2/sim_node", "/arm/joint2/controller_node",
                                       "estimator_node"]
    assert graph_sections(graph_file)["/arm/joint2/sim_node"] == {"seed": 2}
    assert split_name("/arm/joint2/sim_node") == ("/arm/joint2", "sim_node")
    assert split_name("estimator_node") == ("/", "estimator_node")


def test_a_section_that_is_neither_node_nor_namespace_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("arm:\n  joint1:\n    sim_node: 3\n", encoding="utf-8")
    with pytest.raises(GraphError, match="arm/joint1/sim_node: expected 'ros__parameters:'"):
        graph_nodes(path)


def test_a_namespaced_node_runs_with_its_namespace(graph_file: Path, monkeypatch) -> None:
    monkeypatch.setattr("torque_estimator.graph.runner.find_executable", lambda name: Path(f"/bin/{name}"))
    graph = Graph(graph_file, {"/arm/joint2/sim_node": ["seed:=5"]})
    assert graph.command("/arm/joint2/sim_node") == ["/bin/sim_node", "--ros-args", "-r", "__ns:=/arm/joint2",
                                                     "--params-file", str(graph_file), "-p", "seed:=5"]
    assert graph.command("estimator_node") == ["/bin/estimator_node", "--ros-args", "--params-file", str(graph_file)]


def test_a_rig_computer_groups_the_other_nodes_per_namespace(graph_file: Path) -> None:
    options = rig_computer(graph_file)
    assert options["together"] == [["/arm/joint2/controller_node"], ["estimator_node"]]


def test_a_group_shares_one_namespace_and_gets_its_overrides(graph_file: Path, tmp_path: Path) -> None:
    graph = Graph(graph_file, {"/arm/joint2/controller_node": ["kp:=0.003"]}, log_dir=tmp_path / "logs")
    with pytest.raises(GraphError, match="share one namespace"):
        graph.composed_command(["/arm/joint2/sim_node", "estimator_node"])
    command = graph.composed_command(["/arm/joint2/sim_node", "/arm/joint2/controller_node"])
    assert command[-4:] == ["--namespace", "/arm/joint2", "sim_node", "controller_node"]
    merged = yaml.safe_load(Path(command[command.index("--params-file") + 1]).read_text(encoding="utf-8"))
    assert merged["/arm/joint2/controller_node"]["ros__parameters"] == {"kp": 0.003}
    assert merged["/arm/joint1/sim_node"]["ros__parameters"] == {"seed": 1}
    assert merged["/**"]["ros__parameters"] == {"use_sim_time": False}
    assert process_file_name(["/arm/joint2/sim_node", "/arm/joint2/controller_node"]) == \
        "arm__joint2__sim_node+arm__joint2__controller_node"
