"""Respawn over real DDS: a graph started with Graph(respawn=...) heals itself after kill -9, and the recorder
started again records into a new bag beside the one it was killed writing.

The graph is sim_graph.yaml plus a `recorder` node (recording /rig/samples and /rig/speed_command into
<tmp>/bag), run as a rig computer runs it: sim_node alone, model_node and controller_node in one process; the
rig, that process (named by its controller_node) and the recorder are respawnable, 0.5 s after they exit. The
test calls Graph.supervise while it spins its probe, as run_graph does every 0.2 s. In turn, each is killed
with SIGKILL; it must come back as a new process (restarts 1) and its output must flow again, judged on the
stream's own stamps (a sample or command stamped after the kill can only come from the new process):

* the recorder: its killed bag reads up to its last flush with `bag info`, sequence check lost 0; the new
  process records into <tmp>/bag.1 (the killed bag untouched), whose flushed part reads lost 0 too, and at
  the end it stops cleanly with its verdict `recorder: lost nothing`;
* the rig: samples of a new rig clock (seq from 0 again) flow at 1 kHz of stamps;
* model_node+controller_node: speed commands flow again and the rig takes them (its samples name them).

(run_graph's options, a non-respawned node's death stopping it, and supervise's rules on tiny executables
without DDS: ros_ws/src/torque_estimator/test/graph/test_respawn.py.)
"""
from __future__ import annotations

import re
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from worm_msgs.msg import RigSamples, SpeedCommand

from torque_estimator.graph.runner import Graph, parse_overrides
from worm_model.rig_data.samples import unbatch
from worm_model.ros.ament import find_executable
from worm_model.ros.qos import STREAM
from worm_model.ros.testing import probe_node

REPO = Path(__file__).resolve().parents[1]
SIM_GRAPH = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
GROUP = "model_node+controller_node"
RESPAWN_DELAY = 0.5  # [s]
START_TIMEOUT = 60.0  # [s] a busy 2-core machine may take long to start Python nodes
SAMPLE_PERIOD_NS = 1_000_000
RECORDED = ("/rig/samples", "/rig/speed_command")


def stamp_ns(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


class Probe:
    """Records the rig's samples and the speed commands; spins only while a test waits, and supervises the
    graph on every turn, as run_graph's loop does."""

    def __init__(self, node, executor, graph: Graph) -> None:
        self.executor = executor
        self.graph = graph
        self.samples: list = []
        self.commands: list = []
        self.restarted: list[str] = []
        node.create_subscription(RigSamples, "/rig/samples", lambda m: self.samples.extend(unbatch(m)), STREAM)
        node.create_subscription(SpeedCommand, "/rig/speed_command", self.commands.append, STREAM)

    def spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.restarted += self.graph.supervise()
            if done():
                return True
            self.executor.spin_once(timeout_sec=0.05)
        return done()

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)


@pytest.fixture(scope="module")
def running(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Graph, Probe]]:
    folder = tmp_path_factory.mktemp("respawn")
    params = folder / "graph.yaml"
    params.write_text(SIM_GRAPH.read_text(encoding="utf-8") + (
        "recorder:\n  ros__parameters:\n"
        f"    output: {folder / 'bag'}\n    topics: [{', '.join(RECORDED)}]\n    discovery_period: 0.2\n"),
        encoding="utf-8")
    graph = Graph(params, parse_overrides(["controller_node.speed_setpoint=150.0"]), folder / "logs",
                  together=[["model_node", "controller_node"]], respawn=["sim_node", "controller_node", "recorder"],
                  respawn_delay=RESPAWN_DELAY)
    with probe_node("respawn_probe") as (node, executor):
        probe = Probe(node, executor, graph)
        graph.start()
        try:
            assert probe.spin_until(lambda: len(probe.samples) > 1000 and len(probe.commands) > 20
                                    and recorder_log(graph).count("Recording /") == 2, START_TIMEOUT), (
                f"the graph did not start: {len(probe.samples)} samples, {len(probe.commands)} commands, "
                f"exited {graph.failed()}; logs in {graph.log_dir}")
            yield graph, probe
        finally:
            codes = graph.stop()
    assert all(code == 0 for code in codes.values()), f"not a clean stop on SIGINT: {codes}; logs in {graph.log_dir}"
    assert probe.restarted == ["recorder", "sim_node", GROUP], probe.restarted
    log = recorder_log(graph)
    # the respawned recorder's own verdict when it stopped, from the DDS sequence numbers of what it received
    assert "Closed bag " + str(graph.log_dir.parent / "bag.1") in log and "recorder: lost nothing" in log, log


def recorder_log(graph: Graph) -> str:
    log = graph.log_dir / "recorder.log"
    return log.read_text(errors="replace") if log.exists() else ""


def kill(graph: Graph, name: str) -> tuple[int, int]:
    """SIGKILL process ``name``; returns (its pid, the system time [ns] just before, as the stamps)."""
    at = time.time_ns()
    proc = graph.processes[name]
    proc.send_signal(signal.SIGKILL)
    proc.wait(30)
    return proc.pid, at


def come_back(graph: Graph, probe: Probe, name: str, old_pid: int) -> None:
    """``name`` restarted once, by supervise, as a new process that is running."""
    assert graph.failed() == {}, f"a respawnable process counted as failed: {graph.failed()}"
    assert probe.spin_until(lambda: graph.restarts[name] == 1, START_TIMEOUT), (
        f"{name} not restarted: restarts {graph.restarts}; logs in {graph.log_dir}")
    new = graph.processes[name]
    assert new.pid != old_pid and new.poll() is None
    code, waited = graph.last_exit[name]
    assert code == -signal.SIGKILL and waited >= RESPAWN_DELAY, graph.last_exit


def bag_info(bag: Path, until: float = 0.0) -> tuple[dict[str, int], list[str]]:
    """`bag info`'s counts per topic and its sequence-check lines (a failure may be retried until the
    monotonic time ``until``: a recorder's file before its first flush is not yet readable)."""
    while True:
        done = subprocess.run([str(find_executable("bag")), "info", str(bag)], capture_output=True, text=True,
                              timeout=120)
        if done.returncode == 0 or time.monotonic() > until:
            break
        time.sleep(0.5)
    assert done.returncode == 0, done.stderr
    counts = {m[1]: int(m[2]) for m in re.finditer(r"Topic: (/\S+) \| Type: \S+ \| Count: (\d+)", done.stdout)}
    checks = re.findall(r"(/\S+: seq .*)", done.stdout)
    return counts, checks


def flushed(bag: Path, probe: Probe) -> tuple[dict[str, int], list[str]]:
    """`bag info` of a bag being recorded once its flushed part holds >= 100 sample batches and 20 commands
    (the recorder flushes every second; a recorder just started may wait seconds for DDS discovery to match
    the rig's publisher, so the wait is on the bag's counts, not a time)."""
    deadline = time.monotonic() + START_TIMEOUT
    while True:
        counts, checks = bag_info(bag, until=deadline)
        enough = counts.get("/rig/samples", 0) >= 100 and counts.get("/rig/speed_command", 0) >= 20
        if enough or time.monotonic() > deadline:
            return counts, checks
        probe.spin_for(1.0)


def test_the_recorder_comes_back_in_a_new_bag_beside_the_killed_one(running: tuple[Graph, Probe]) -> None:
    graph, probe = running
    bag = graph.log_dir.parent / "bag"
    flushed(bag, probe)
    old_pid, _ = kill(graph, "recorder")
    before = sorted((p.name, p.stat().st_size) for p in bag.iterdir())
    counts, checks = bag_info(bag)
    assert counts.get("/rig/samples", 0) >= 100 and counts.get("/rig/speed_command", 0) >= 20, counts
    assert checks and all(line.endswith("lost 0") for line in checks), checks

    come_back(graph, probe, "recorder", old_pid)
    assert probe.spin_until(lambda: recorder_log(graph).count("Recording /") == 4, START_TIMEOUT), recorder_log(graph)
    assert f"Recording into {bag}.1 (mcap): {bag} holds a recording that stopped" in recorder_log(graph)
    counts, checks = flushed(Path(f"{bag}.1"), probe)  # while it records: what it has flushed
    assert counts.get("/rig/samples", 0) >= 100 and counts.get("/rig/speed_command", 0) >= 20, counts
    assert checks and all(line.endswith("lost 0") for line in checks), checks
    assert sorted((p.name, p.stat().st_size) for p in bag.iterdir()) == before, "the killed bag was touched"


def test_the_rig_comes_back_with_a_new_clock(running: tuple[Graph, Probe]) -> None:
    graph, probe = running
    old_pid, killed = kill(graph, "sim_node")
    probe.spin_for(0.5)  # what was in flight
    last_old = max(s.seq for s in probe.samples if stamp_ns(s.header) <= killed)
    come_back(graph, probe, "sim_node", old_pid)
    probe.samples.clear()

    def new_rig() -> list:
        return [s for s in probe.samples if stamp_ns(s.header) > killed]
    assert probe.spin_until(lambda: len(new_rig()) >= 2000, START_TIMEOUT), (
        f"{len(new_rig())} samples of the new rig; logs in {graph.log_dir}")
    samples = new_rig()
    assert samples[0].seq < last_old, f"seq {last_old} before the kill, {samples[0].seq} after: not a new rig clock"
    seqs = [s.seq for s in samples]
    assert seqs == sorted(set(seqs)), "the new rig's samples repeated or out of order"
    steps = [(stamp_ns(b.header) - stamp_ns(a.header), b.seq - a.seq) for a, b in zip(samples, samples[1:])]
    assert all(dt >= n * SAMPLE_PERIOD_NS for dt, n in steps), "stamps closer than the rig's sample period"


def test_a_process_of_two_nodes_comes_back_and_drives_again(running: tuple[Graph, Probe]) -> None:
    graph, probe = running
    old_pid, killed = kill(graph, GROUP)
    come_back(graph, probe, GROUP, old_pid)

    def new_commands() -> list:
        return [c for c in probe.commands if stamp_ns(c.header) > killed]
    assert probe.spin_until(lambda: len(new_commands()) >= 50, START_TIMEOUT), (
        f"{len(new_commands())} speed commands from the new controller; logs in {graph.log_dir}")
    # the rig takes them: its samples say which command drove each period (command_seq: the command's sample_seq)
    def taken() -> set[int]:
        return {c.sample_seq for c in new_commands()} & {s.command_seq for s in probe.samples}
    assert probe.spin_until(lambda: len(taken()) >= 20, START_TIMEOUT), (
        f"the rig took {len(taken())} of the new controller's {len(new_commands())} commands; "
        f"logs in {graph.log_dir}")
