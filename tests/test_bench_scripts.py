"""The benchmark scripts `make bench` runs read the graph files as they are shipped.

`make bench` only prints figures and never asserts, so a script broken by a change of the graph
file would print nan and nothing would fail; these tests run the parts that read project files.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"


def bench_module(name: str):
    """bench/<name>.py imported as a module (the folder is scripts, not a package)."""
    spec = importlib.util.spec_from_file_location(f"bench_{name}", BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(BENCH))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCH))
    return module


def test_controller_bench_reads_the_shipped_graph() -> None:
    """The shipped graph runs no estimator_node: the estimator is the rig's feedforward one (sim_node's
    feedforward_estimator) and the gains are controller_node's."""
    bench = bench_module("controller_bench")
    params = bench.graph_parameters(None, ["controller_node.kp=0.002"])
    assert params["estimator_node"] == {"method": "observer"}
    assert params["controller_node"]["kp"] == 0.002 and params["controller_node"]["ki"] == 0.02


def test_controller_bench_reads_a_graph_with_an_estimator_node(tmp_path: Path) -> None:
    graph = tmp_path / "graph.yaml"
    graph.write_text("estimator_node:\n  ros__parameters:\n    method: knn\n    k: 6\n"
                     "controller_node:\n  ros__parameters:\n    kp: 0.001\n    ki: 0.02\n", encoding="utf-8")
    bench = bench_module("controller_bench")
    params = bench.graph_parameters(graph, ["estimator_node.input_filter=0.005"])
    assert params["estimator_node"] == {"method": "knn", "k": 6, "input_filter": 0.005}
    with pytest.raises(SystemExit, match="--set"):
        bench.graph_parameters(graph, ["sim_node.seed=1"])
