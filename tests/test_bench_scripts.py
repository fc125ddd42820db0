"""The benchmark scripts `make bench` runs read the graph files as they are shipped.

`make bench` only prints figures and never asserts, so a script broken by a change of the graph
file would print nan and nothing would fail; these tests run the parts that read project files.
"""
from __future__ import annotations

import importlib.util
import subprocess
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


def test_discovery_bench_hears_the_graph(ros_env: dict[str, str]) -> None:
    """One bare probe started beside the shipped graph learns of /rig/samples, then takes a message of it; the
    figures are printed in order (known before taken) and the run exits 0."""
    done = subprocess.run([sys.executable, str(BENCH / "discovery_bench.py"), "--starts", "1", "--ranges",
                           "LOCALHOST"], env=ros_env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    figures = {line.split(":")[0]: float(line.split()[1]) for line in done.stdout.splitlines() if ": " in line}
    assert set(figures) == {f"dds_{name}_localhost" for name in ("discovery_p50", "discovery_max", "first_sample_p50",
                                                                 "first_sample_max", "probe_start_p50")}
    assert 0 < figures["dds_discovery_p50_localhost"] <= figures["dds_first_sample_p50_localhost"] < 15, figures
    assert 0 < figures["dds_probe_start_p50_localhost"] < 15, figures


def test_the_update_timers_feed_the_streams_by_name() -> None:
    """observer_bench's timer (momentum_bench times the momentum observer through it) feeds each sample to a stream
    as the nodes do: a call the streams refuse would leave `make bench` printing nan."""
    from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
    from worm_model.physics.parameters import load_rig

    timer = bench_module("observer_bench").update_cpu_us
    rig = load_rig(None)
    assert 0 < timer(rig, samples=20, repeats=1) < 1e5
    momentum = build_estimator(EstimatorSettings("momentum"), rig=rig).estimator
    assert 0 < timer(rig, samples=20, repeats=1, estimator=momentum, voltage=False) < 1e5
