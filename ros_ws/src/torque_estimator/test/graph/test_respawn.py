"""The graph runner's respawn on real processes: tiny shell executables found where `ros2 run` finds them
(``<prefix>/lib/<pkg>/<exe>`` of AMENT_PREFIX_PATH), so no DDS and no node is needed. Each prints its pid and
an environment variable into its log, then sleeps until it is killed. The graph of real nodes respawned over
DDS (the rig, a process of two nodes, the recorder): tests/test_respawn_dds.py."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from torque_estimator.errors import GraphError
from torque_estimator.graph.runner import Graph

#: executable -> its shell body; "worker" and "other" run until killed, "refuser" refuses its input at once
EXECUTABLES = {
    "worker": 'echo "start $$ $RESPAWN_TEST_MARK"; exec sleep 600',
    "other": 'echo "start $$"; exec sleep 600',
    "refuser": 'echo "refuser: parameter x: refused" >&2; exit 2',
}
DELAY = 0.5  # [s] respawn_delay in these tests
TIMEOUT = 30.0  # [s] for anything to happen on a busy machine


@pytest.fixture
def graph_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A graph of the three executables, installed under a prefix of their own put first on AMENT_PREFIX_PATH."""
    lib = tmp_path / "prefix" / "lib" / "respawn_test"
    lib.mkdir(parents=True)
    for name, body in EXECUTABLES.items():
        (lib / name).write_text(f"#!/bin/sh\n{body}\n", encoding="utf-8")
        (lib / name).chmod(0o755)
    monkeypatch.setenv("AMENT_PREFIX_PATH", os.pathsep.join([str(tmp_path / "prefix"),
                                                             os.environ.get("AMENT_PREFIX_PATH", "")]))
    monkeypatch.setenv("RESPAWN_TEST_MARK", "same-environment")
    path = tmp_path / "graph.yaml"
    path.write_text("worker:\n  ros__parameters:\n    x: 1\nother:\n  ros__parameters:\n    x: 2\n", encoding="utf-8")
    return path


@pytest.fixture
def graphs() -> Iterator[list[Graph]]:
    """Graphs a test started; stopped at its end whatever happened."""
    started: list[Graph] = []
    yield started
    for graph in started:
        graph.stop(grace=2.0)


def starts(log: Path) -> list[str]:
    """The "start <pid> ..." lines a process wrote into its log, one per start."""
    if not log.exists():
        return []
    return [line for line in log.read_text(encoding="utf-8").splitlines() if line.startswith("start ")]


def wait_for(condition, what: str, timeout: float = TIMEOUT) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"not within {timeout:g} s: {what}"
        time.sleep(0.02)


def kill(graph: Graph, name: str) -> int:
    """SIGKILL process ``name`` of ``graph`` and wait for it; returns its pid."""
    proc = graph.processes[name]
    proc.send_signal(signal.SIGKILL)
    proc.wait(TIMEOUT)
    return proc.pid


def supervise_until_restarted(graph: Graph, name: str) -> float:
    """Call supervise every 20 ms until it restarts ``name``; returns [s] from its first call to the restart."""
    first = time.monotonic()
    while (restarted := graph.supervise()) != [name]:
        assert restarted == [], restarted
        assert time.monotonic() - first < TIMEOUT, f"{name} not restarted within {TIMEOUT:g} s"
        time.sleep(0.02)
    return time.monotonic() - first


def test_a_killed_respawnable_process_comes_back_after_its_delay(graph_file: Path, tmp_path: Path,
                                                                  graphs: list[Graph]) -> None:
    """kill -9: the process is down but not failed; supervise starts it again no sooner than respawn_delay after
    it saw the exit, with a new pid, the same command and environment, the log appended to; restarts counts it."""
    logs = tmp_path / "logs"
    graph = Graph(graph_file, {}, logs, respawn=["worker"], respawn_delay=DELAY)
    graphs.append(graph)
    graph.start()
    assert graph.restarts == {"worker": 0, "other": 0}
    wait_for(lambda: len(starts(logs / "worker.log")) == 1, "worker started")
    first_command = graph.processes["worker"].args
    old = kill(graph, "worker")

    assert graph.failed() == {}, "a respawnable process that is down is not a failure"
    waited = supervise_until_restarted(graph, "worker")
    assert waited >= DELAY, f"restarted {waited:.3f} s after the exit was seen, before respawn_delay {DELAY} s"
    new = graph.processes["worker"]
    assert new.pid != old and new.poll() is None and new.args == first_command
    assert graph.restarts == {"worker": 1, "other": 0}
    assert graph.last_exit["worker"][0] == -signal.SIGKILL and graph.last_exit["worker"][1] >= DELAY
    wait_for(lambda: len(starts(logs / "worker.log")) == 2, "the restarted worker wrote into its log")
    lines = starts(logs / "worker.log")
    assert lines == [f"start {old} same-environment", f"start {new.pid} same-environment"], lines
    assert graph.supervise() == [] and graph.failed() == {}


def test_what_is_not_respawned_is_failed(graph_file: Path, tmp_path: Path, graphs: list[Graph]) -> None:
    """A process no respawn names, one past respawn_max, and one that refused its input (exit code 2, it would
    refuse again) stay down and are what failed() reports; nothing is restarted once stop() has begun."""
    graph = Graph(graph_file, {}, tmp_path / "logs", respawn=["worker"], respawn_delay=0.0, respawn_max=1)
    graphs.append(graph)
    graph.start()
    kill(graph, "other")
    assert graph.supervise() == [] and graph.failed() == {"other": -signal.SIGKILL}

    kill(graph, "worker")
    supervise_until_restarted(graph, "worker")
    kill(graph, "worker")  # past respawn_max: final
    assert graph.supervise() == [] and graph.failed() == {"other": -signal.SIGKILL, "worker": -signal.SIGKILL}
    assert graph.restarts["worker"] == 1

    refusing = tmp_path / "refusing.yaml"
    refusing.write_text("refuser:\n  ros__parameters:\n    x: 1\n", encoding="utf-8")
    graph = Graph(refusing, {}, tmp_path / "logs_refusing", respawn=["refuser"], respawn_delay=0.0)
    graphs.append(graph)
    graph.start()
    wait_for(lambda: graph.processes["refuser"].poll() is not None, "refuser exited")
    assert graph.supervise() == [] and graph.failed() == {"refuser": 2} and graph.restarts == {"refuser": 0}

    graph = Graph(graph_file, {}, tmp_path / "logs_stopped", respawn=["worker", "other"], respawn_delay=0.0)
    graphs.append(graph)
    graph.start()
    graph.stop(grace=2.0)
    assert graph.supervise() == [] and all(p.poll() is not None for p in graph.processes.values())


def test_unknown_respawn_names_start_nothing(graph_file: Path, tmp_path: Path) -> None:
    graph = Graph(graph_file, {}, tmp_path / "logs", respawn=["worker", "sim_node"])
    with pytest.raises(GraphError, match=r"respawn names nodes not in .*graph.yaml: \['sim_node'\]"):
        graph.start()
    assert graph.processes == {} and not (tmp_path / "logs").exists()


def run_graph(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "torque_estimator.graph.run_graph", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_run_graph_respawns_and_says_so_then_stops_when_another_node_dies(graph_file: Path, tmp_path: Path) -> None:
    """--respawn worker: worker killed twice comes back each time (one line on stderr each, counted); other
    killed stops the graph with exit code 1, as without --respawn."""
    logs = tmp_path / "logs"
    proc = run_graph(str(graph_file), "--log-dir", str(logs), "--respawn", "worker", "--respawn-delay", "0.3")
    try:
        for restart in (1, 2):
            wait_for(lambda n=restart: len(starts(logs / "worker.log")) == n and starts(logs / "other.log"),
                     f"worker started for the {restart}. time")
            os.kill(int(starts(logs / "worker.log")[-1].split()[1]), signal.SIGKILL)
        wait_for(lambda: len(starts(logs / "worker.log")) == 3, "worker restarted twice")
        assert proc.poll() is None, "run_graph stopped although only a respawned node died"
        os.kill(int(starts(logs / "other.log")[-1].split()[1]), signal.SIGKILL)
        out, err = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 1, (out, err)
    respawned = [line for line in err.splitlines() if "respawned" in line]
    assert len(respawned) == 2, err
    for n, line in enumerate(respawned, 1):
        assert line.startswith(f"run_graph: worker exited with code {-signal.SIGKILL}; respawned after 0.")
        assert line.endswith(f" s (restart {n})"), line
    assert f"run_graph: other exited on its own with code {-signal.SIGKILL}" in err, err


@pytest.mark.parametrize("args, says", [
    (["--respawn", "worker,sim_node"], "respawn names nodes not in"),
    (["--respawn", ","], "--respawn: no node named"),
    (["--respawn", "all", "--respawn-delay", "-1"], "--respawn-delay"),
    (["--respawn", "all", "--respawn-delay", "nan"], "--respawn-delay"),
    (["--respawn", "all", "--respawn-max", "-1"], "--respawn-max"),
])
def test_run_graph_refuses_bad_respawn_options(graph_file: Path, tmp_path: Path, args: list[str], says: str) -> None:
    """One line naming the option, exit 2, nothing started (no node wrote a log)."""
    logs = tmp_path / "logs"
    out, err = run_graph(str(graph_file), "--log-dir", str(logs), *args).communicate(timeout=TIMEOUT)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and "Traceback" not in err, err
    assert not list(logs.glob("*.log")), "a node was started"


def test_run_graph_help_explains_respawn() -> None:
    done = subprocess.run([sys.executable, "-m", "torque_estimator.graph.run_graph", "--help"], capture_output=True,
                          text=True, timeout=TIMEOUT)
    assert done.returncode == 0
    for option in ("--respawn NODE,NODE,...", "--respawn-delay SECONDS", "--respawn-max N", "all"):
        assert option in done.stdout, done.stdout
