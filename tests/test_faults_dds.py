"""Faults of the live graph over DDS: each node killed (SIGKILL, no clean-up) during a run at speed, then
started again, as the README's fault table states.

The graph of sim_graph.yaml runs one process per node (run_graph's default), at 150 rad/s against
+0.1 N m; a probe records the rig's samples, the estimates (the rig's: its load observer feeds forward
and publishes them) and the speed commands. Outcomes are judged on the streams' own stamps and seqs:

* model_node killed: the rig, the estimate and the feedforward go on; restarted, its forces come back;
* sim_node killed (the rig and its estimate): the controller goes on commanding and drops its
  feedforward torque within its estimate_timeout (0.05 s) of the last estimate (never a stale one);
  restarted, samples flow again (a new rig clock), the estimate and the feedforward come back;
* the recorder killed: the bag it leaves is read by `bag info` up to the kill.
(controller_node killed: the rig stops driving within 0.1 s: tests/test_controller_node_dds.py.)
"""
from __future__ import annotations

import re
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from worm_msgs.msg import GearboxForces, LoadCommand, RigSamples, SpeedCommand, TorqueEstimate

from torque_estimator.graph.runner import Graph, batch_rate, parse_overrides
from worm_model.rig_data.samples import unbatch
from worm_model.ros.ament import find_executable
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.ros.testing import probe_node, spin_until

REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
START_TIMEOUT = 45.0  # [s]
ESTIMATE_TIMEOUT = 0.05  # [s] controller_node's estimate_timeout (sim_graph.yaml)


def stamp_s(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


class Streams:
    """The probe: records what the graph publishes, with receive times."""

    def __init__(self, node, executor) -> None:
        self.executor = executor
        self.samples: list = []
        self.estimates: list = []
        self.commands: list = []
        self.forces: list = []
        node.create_subscription(RigSamples, "/rig/samples", lambda m: self.samples.extend(unbatch(m)), STREAM)
        node.create_subscription(TorqueEstimate, "/torque_estimate", self.estimates.append, STREAM)
        node.create_subscription(SpeedCommand, "/rig/speed_command", self.commands.append, STREAM)
        node.create_subscription(GearboxForces, "/gearbox/forces", self.forces.append, STREAM)
        self.load = node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)

    def spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        return spin_until(self.executor, done, timeout, step=0.02)

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def clear(self) -> None:
        for stream in (self.samples, self.estimates, self.commands, self.forces):
            stream.clear()


@pytest.fixture(scope="module")
def graph(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Graph, Streams]]:
    log_dir = tmp_path_factory.mktemp("faults")
    g = Graph(GRAPH_FILE, parse_overrides(["controller_node.speed_setpoint=150.0"]), log_dir)
    with probe_node("faults_probe") as (node, executor):
        streams = Streams(node, executor)
        g.start()
        try:
            assert streams.spin_until(lambda: len(streams.estimates) > 20 and len(streams.commands) > 20
                                      and streams.load.get_subscription_count(),
                                      START_TIMEOUT), f"the graph did not start; logs in {log_dir}"
            streams.load.publish(LoadCommand(torque=0.1))
            streams.spin_for(1.5)
            yield g, streams
        finally:
            g.stop()


def restart(g: Graph, name: str) -> None:
    """Start node ``name`` again, as it was started (its log appended)."""
    log = open(g.log_dir / f"{name}.log", "ab")
    g.processes[name] = subprocess.Popen(g.command(name), stdout=log, stderr=subprocess.STDOUT)


def kill(g: Graph, name: str) -> float:
    """SIGKILL node ``name``; returns the time [s, system clock, as the stamps] just before."""
    at = time.time()
    g.processes[name].send_signal(signal.SIGKILL)
    g.processes[name].wait(10)
    return at


def test_killed_model_node_leaves_the_control_path_alone_then_rejoins(graph) -> None:
    g, s = graph
    s.clear()
    killed = kill(g, "model_node")
    # counted, not timed: a probe starved by a busy machine receives fewer messages per second
    assert s.spin_until(lambda: len(s.estimates) > 100 and len(s.commands) >= 20, START_TIMEOUT), (
        f"the estimate or the commands stopped with model_node; logs in {g.log_dir}")
    # forces are stamped with their sample's stamp: none of a sample taken after the kill
    assert max((stamp_s(f.header) for f in s.forces), default=0.0) < killed, "forces after model_node died"
    # the feedforward goes on: an estimate that reaches the controller later than estimate_timeout is not fed
    # forward (a loaded CI host held some back: 1 or more of 20 commands), so most, not all, carry it
    fed = [c.feedforward_torque > 0 for c in s.commands if stamp_s(c.header) > killed]
    assert len(fed) >= 20 and sum(fed) >= 0.8 * len(fed), f"{sum(fed)} of {len(fed)} commands fed forward"
    restart(g, "model_node")
    s.clear()
    assert s.spin_until(lambda: len(s.forces) > 10, START_TIMEOUT), f"model_node did not rejoin; logs in {g.log_dir}"


def test_killed_rig_restarts_and_the_graph_follows(graph) -> None:
    g, s = graph
    s.clear()
    assert s.spin_until(lambda: len(s.samples) > 100, START_TIMEOUT), "no samples before the kill"
    assert s.spin_until(lambda: len(s.commands) >= 20 and all(c.feedforward_torque > 0 for c in s.commands[-20:]),
                        START_TIMEOUT), "no feedforward before"
    killed = kill(g, "sim_node")
    s.spin_for(1.0)  # keeps what was in flight: the last estimate stamp is the last one that got out
    assert max(stamp_s(x.header) for x in s.samples) < killed, "samples after the rig died"
    last = max(stamp_s(e.header) for e in s.estimates)

    def commands_after_the_rig() -> list:
        return [c for c in s.commands if stamp_s(c.header) > last + ESTIMATE_TIMEOUT + 0.005]
    assert s.spin_until(lambda: len(commands_after_the_rig()) > 10, START_TIMEOUT), (
        f"the controller stopped sending commands ({len(commands_after_the_rig())} after the rig died)")
    late = commands_after_the_rig()
    assert all(c.feedforward_torque == 0.0 for c in late), "a stale estimate was fed forward"
    restart(g, "sim_node")
    assert s.spin_until(lambda: len(s.samples) > 2000, START_TIMEOUT), f"no samples after the restart ({g.log_dir})"
    s.load.publish(LoadCommand(torque=0.1))  # the restarted rig also got the latched one, if its publisher lives
    s.clear()
    # 1.5 s of rig time (its samples), however long the probe takes to receive them
    assert s.spin_until(lambda: len(s.samples) >= 1500 and len(s.estimates) > 100, START_TIMEOUT), (
        f"{len(s.samples)} samples, {len(s.estimates)} estimates after the restart; logs in {g.log_dir}")

    def held() -> float:  # the mean speed of the last 200 samples
        return sum(x.omega_worm for x in s.samples[-200:]) / 200

    # then the speed held at the set-point over 200 samples: on a machine whose load starves the controller
    # for longer than the rig's watchdog allows, the rig stops itself for a while (its fault behaviour, not
    # this one); the controller takes it back within the timeout, or never has
    assert s.spin_until(lambda: abs(held() - 150.0) < 3.0, START_TIMEOUT), (
        f"the controller did not take it: {held():.1f} rad/s over the last 200 samples; logs in {g.log_dir}")
    assert len(s.estimates) > 100 and s.commands[-1].feedforward_torque > 0


def test_killed_recorder_leaves_a_readable_bag(graph, ros_env: dict[str, str], tmp_path: Path) -> None:
    """The recorder flushes its bag every second (flush_period): SIGKILL loses at most the last second."""
    _g, s = graph
    bag, log_path = tmp_path / "bag", tmp_path / "recorder.log"
    with log_path.open("wb") as log:
        recorder = subprocess.Popen([str(find_executable("recorder")), "--ros-args", "-p", f"output:={bag}",
                                     "-p", "topics:=[/rig/samples,/torque_estimate]", "-p", "discovery_period:=0.1"],
                                    env=ros_env, stdout=log, stderr=subprocess.STDOUT)
    try:
        assert s.spin_until(lambda: log_path.read_text(errors="replace").count("Recording /") == 2,
                            START_TIMEOUT), log_path.read_text(errors="replace")
        s.spin_for(3.0)
    finally:
        recorder.send_signal(signal.SIGKILL)
        recorder.wait(10)
    done = subprocess.run([str(find_executable("bag")), "info", str(bag)], env=ros_env, capture_output=True,
                          text=True, timeout=60)
    print(done.stdout, done.stderr)
    assert done.returncode == 0, done.stderr
    counts = {m[1]: int(m[2]) for m in re.finditer(r"Topic: (/\S+) \| Type: \S+ \| Count: (\d+)", done.stdout)}
    # 3 s of batches, less the last second at most: >= 2 s flushed
    flushed = 1.5 * batch_rate(GRAPH_FILE)
    assert counts.get("/rig/samples", 0) > flushed and counts.get("/torque_estimate", 0) > flushed, done.stdout
    assert "lost 0" in done.stdout.split("Sequence check:")[1], done.stdout
