"""System tests of the whole node graph over real DDS, every node its own process.

The graph of ros_ws/src/torque_estimator/config/sim_graph.yaml (sim_node, whose load
observer feeds forward and publishes the graph's /torque_estimate, model_node,
controller_node) is started once for this module with torque_estimator.graph.runner.Graph,
on a calibration database written by `python -m torque_estimator.calibration.calibrate`
(the rig's feedforward_calibration), with the speed set-point at 150 rad/s.
A probe node in this process (EventsExecutor, spun in the main thread only
while a test measures) subscribes, publishes load commands and bad samples.

Each run has its own ROS_DOMAIN_ID (the environment's if set, else a random one in
100..230) and discovery stays on this host (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST),
so parallel runs never cross-talk: the ros_env fixture of tests/conftest.py.
At teardown every node must exit with code 0 on SIGINT (not SIGABRT/-6, not
SIGKILL/-9).
"""
from __future__ import annotations

import math
import random
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from worm_msgs.msg import (DriveCommand, EncoderCounts, GearboxForces, LoadCommand, MotorCurrents, RigSample,
                           RigSamples, SimTruth, SimTruths, SpeedCommand, TorqueEstimate)

from torque_estimator.estimation.database import load_database
from torque_estimator.graph.runner import Graph, batch_rate, batch_size, parse_overrides
from worm_model.rig_data.samples import TRUTH_FIELDS, command_latencies, stamp_ns, unbatch
from worm_model.ros.qos import COMMAND
from worm_model.ros.testing import probe_node, spin_until

REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
SPEED_SETPOINT = 150.0  # [rad/s]

#: The rig's stream (sim_graph.yaml's batch_size at 1 kHz), what the nodes answer per batch, and the
#: decimated channels (channel_decimation 10). Rates are judged on the stream's own clock (seq and
#: stamps), never on the probe's wall clock: a starved probe receives late, not fewer.
BATCH = batch_size(GRAPH_FILE)
SAMPLE_PERIOD = 1e-3  # [s]
DECIMATION = 10
PER_BATCH_TOPICS = {"/torque_estimate": TorqueEstimate}
FORCES_EVERY = 20  # model_node's publish_period (20 ms) in samples: it answers the newest of each chunk
SLOW_TOPICS = {"/rig/currents": MotorCurrents, "/rig/joint_states": JointState,
               "/rig/encoders": EncoderCounts, "/sim/truth": SimTruth}
#: batched like /rig/samples (every sample, BATCH per message, same first_seq and stamp)
SAMPLE_BATCH_TOPICS = {"/sim/truth_samples": SimTruths}
#: Best effort on a loaded 2-core machine: at least this share of what was sent must arrive.
DELIVERED = 0.9
RATE_WINDOW = 3.0  # [s]
STEADY_WINDOW = 1.0  # [s] the graph answers at pace over this long before the tests measure

START_TIMEOUT = 45.0  # [s] for the graph's first sample to reach the probe
MATCH_TIMEOUT = 15.0  # [s] for a new subscription's first message

#: The probe reads with a deep queue: a momentarily late probe must not lose
#: messages (best effort, so it still matches the graph's sensor-data publishers).
PROBE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500, reliability=ReliabilityPolicy.BEST_EFFORT)


# --- the probe -----------------------------------------------------------------------------------

@dataclass
class Recording:
    """Messages of several topics with their receive times (time.monotonic())."""

    messages: dict[str, list] = field(default_factory=dict)
    times: dict[str, list[float]] = field(default_factory=dict)

    def clear(self) -> None:
        for topic in self.messages:
            self.messages[topic].clear()
            self.times[topic].clear()

    def count_between(self, topic: str, t0: float, t1: float) -> int:
        return sum(1 for t in self.times[topic] if t0 <= t < t1)


class Probe:
    """This process's node: spins in the main thread only inside spin_for / spin_until."""

    def __init__(self, node: Node, executor: EventsExecutor) -> None:
        self.node = node
        self.executor = executor

    def spin_until(self, done: Callable[[], bool], timeout: float, step: float = 0.05) -> bool:
        """Spin until done() (checked every `step` s) or timeout; returns done()."""
        deadline = time.monotonic() + timeout
        while not done():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            never = Future(executor=self.executor)
            self.executor.spin_until_future_complete(never, timeout_sec=min(step, left))
        return True

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds, step=seconds)

    def record(self, topics: dict[str, type], raw: bool = False) -> tuple[Recording, list]:
        """Subscribe to topics; returns the recording and the subscriptions (destroy them after).

        raw: keep the serialized bytes (no deserialization: several times cheaper at 1 kHz)."""
        rec = Recording()
        subs = []
        for topic, msg_type in topics.items():
            rec.messages[topic] = []
            rec.times[topic] = []

            def on_message(msg, _m=rec.messages[topic], _t=rec.times[topic]) -> None:
                _t.append(time.monotonic())
                _m.append(msg)
            subs.append(self.node.create_subscription(msg_type, topic, on_message, PROBE_QOS, raw=raw))
        return rec, subs

    def wait_all_flowing(self, rec: Recording, timeout: float = MATCH_TIMEOUT) -> bool:
        return self.spin_until(lambda: all(rec.messages.values()), timeout)

    def wait_steady(self, timeout: float) -> bool:
        """Spin until the estimator answers the rig's batches at pace: in one STEADY_WINDOW, estimates
        for at least DELIVERED of the batches, counted on the stream's seqs. The graph's processes
        start on a machine that may be busy (imports, discovery, a CPU hog): the tests measure the
        graph once it runs, start-up has its own tests (the fault tests' restarts)."""
        rec, subs = self.record({"/rig/samples": RigSamples, "/torque_estimate": TorqueEstimate})
        try:
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                rec.clear()
                self.spin_for(STEADY_WINDOW)
                ends = batch_ends(rec.messages["/rig/samples"])
                answered = {m.seq for m in rec.messages["/torque_estimate"]} & ends
                if ends and len(answered) >= DELIVERED * len(ends):
                    return True
            return False
        finally:
            self.unsubscribe(subs)

    def unsubscribe(self, subs: list) -> None:
        for sub in subs:
            self.node.destroy_subscription(sub)


def batch_ends(batches: list) -> set[int]:
    """The seqs of the batches' newest samples: the samples the estimator answers."""
    return {b.first_seq + BATCH - 1 for b in batches}


def node_logs(log_dir: Path) -> str:
    parts = []
    for log in sorted(log_dir.glob("*.log")):
        text = log.read_text(errors="replace")
        parts.append(f"----- {log.name} -----\n{text[-4000:]}")
    return "\n".join(parts) or f"(no logs in {log_dir})"


# --- fixtures ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def probe(ros_env: dict[str, str]) -> Iterator[Probe]:
    """The probe node, in this run's DDS domain (ros_env: tests/conftest.py)."""
    with probe_node("graph_test_probe", EventsExecutor) as (node, executor):
        yield Probe(node, executor)


@pytest.fixture(scope="module")
def calibration_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("calibration") / "calibration.json"
    done = subprocess.run([sys.executable, "-m", "torque_estimator.calibration.calibrate", "--out", str(out),
                           "--quiet"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and out.exists(), f"calibrate failed:\n{done.stdout}\n{done.stderr}"
    return out


@dataclass
class RunningGraph:
    graph: Graph
    log_dir: Path
    calibration_file: Path

    def logs(self) -> str:
        return node_logs(self.log_dir)

    def assert_alive(self) -> None:
        failed = self.graph.failed()
        assert not failed, f"nodes exited: {failed}\n{self.logs()}"


@pytest.fixture(scope="module")
def graph(ros_env: dict[str, str], probe: Probe, calibration_file: Path,
          tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningGraph]:
    log_dir = tmp_path_factory.mktemp("graph_logs")
    # command_timeout 0.5 s: a busy CI host holds controller_node off the cores for over the shipped 0.1 s, and the
    # watchdog stopping the drive then is the rule (test_faults_dds judges it), not what these tests judge
    overrides = parse_overrides([f"sim_node.feedforward_calibration={calibration_file}",
                                 f"controller_node.speed_setpoint={SPEED_SETPOINT}", "sim_node.command_timeout=0.5"])
    g = Graph(GRAPH_FILE, overrides, log_dir)
    running = RunningGraph(g, log_dir, calibration_file)
    try:
        g.start()
        rec, subs = probe.record({"/rig/samples": RigSamples})
        flowing = probe.spin_until(lambda: bool(rec.messages["/rig/samples"]) or bool(g.failed()), START_TIMEOUT)
        probe.unsubscribe(subs)
        if not flowing or g.failed():
            pytest.fail(f"/rig/samples did not flow within {START_TIMEOUT:g} s "
                        f"(exited nodes: {g.failed()}):\n{running.logs()}")
        if not probe.wait_steady(START_TIMEOUT):
            pytest.fail(f"the estimator did not answer {DELIVERED:.0%} of the rig's batches over any "
                        f"{STEADY_WINDOW:g} s within {START_TIMEOUT:g} s of the first sample:\n{running.logs()}")
        yield running
    finally:
        codes = g.stop()
    bad = {node: code for node, code in codes.items() if code != 0}
    assert not bad, f"nodes did not exit cleanly on SIGINT: {bad} (-6 = SIGABRT, -9 = killed)\n{running.logs()}"


# --- tests ---------------------------------------------------------------------------------------

def stamp_s(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def test_every_topic_flows_at_its_configured_rate(graph: RunningGraph, probe: Probe) -> None:
    """The rig's clock: consecutive seqs, stamps exactly one sample period apart, batches of BATCH; one
    estimate and one forces message per batch (for its newest sample); the decimated channels every
    10th sample; a speed command every command_period (20 ms: the feedforward is the rig's, so the
    commands carry only the set-point), each answering an estimate. Counted on the stream's own seqs
    and stamps."""
    topics = {"/rig/samples": RigSamples, "/rig/speed_command": SpeedCommand, "/gearbox/forces": GearboxForces,
              **PER_BATCH_TOPICS, **SLOW_TOPICS, **SAMPLE_BATCH_TOPICS}
    rec, subs = probe.record(topics)
    try:
        assert probe.wait_all_flowing(rec), (
            f"silent topics: {[t for t, m in rec.messages.items() if not m]}\n{graph.logs()}")
        probe.spin_for(0.5)
        rec.clear()
        probe.spin_for(RATE_WINDOW)
    finally:
        probe.unsubscribe(subs)
    batches = rec.messages["/rig/samples"]
    samples = [s for b in batches for s in unbatch(b)]
    assert all(len(b.omega_worm) == BATCH and b.sample_period == SAMPLE_PERIOD for b in batches)
    seqs = [s.seq for s in samples]
    span = seqs[-1] - seqs[0] + 1
    assert seqs == sorted(set(seqs)), "samples repeated or out of order"
    assert len(seqs) >= DELIVERED * span, f"{span - len(seqs)} of {span} samples missing"
    # the rig's clock: consecutive samples one period apart, to the nanosecond (or whole periods more
    # where sim_node fell behind real time and dilated its clock: it reports those in its diagnostics)
    t0 = stamp_s(samples[0].header)
    period_ns = round(SAMPLE_PERIOD * 1e9)
    steps = [(stamp_ns(b.header.stamp) - stamp_ns(a.header.stamp), b.seq - a.seq) for a, b in zip(samples, samples[1:])]
    assert all(dt >= n * period_ns and abs(dt - round(dt / period_ns) * period_ns) <= 1 for dt, n in steps), \
        "stamps off the rig's clock"
    dilated = sum(dt - n * period_ns for dt, n in steps) // period_ns
    assert dilated <= 0.1 * span, f"the rig's clock was dilated by {dilated} periods in {span}"
    ends = batch_ends(batches)
    report = [f"/rig/samples {len(batches)} batches, {len(seqs)} of {span} samples"]
    for topic in PER_BATCH_TOPICS:
        answered = {m.seq for m in rec.messages[topic]} & ends
        report.append(f"{topic} {len(answered)}")
        assert len(answered) >= DELIVERED * len(ends), f"{topic}: answers for {len(answered)} of {len(ends)} batches"
        assert {m.seq for m in rec.messages[topic]} <= ends | set(range(seqs[0] - 100, seqs[0])) | \
            set(range(seqs[-1], seqs[-1] + 100)), f"{topic}: answers for samples that end no batch"
    forces = [m.seq for m in rec.messages["/gearbox/forces"] if seqs[0] <= m.seq <= seqs[-1]]
    report.append(f"/gearbox/forces {len(forces)}")
    assert set(forces) <= ends, "/gearbox/forces: answers for samples that end no batch"
    # a timer publishes them (every 20 ms of the node's clock, not the rig's): they keep coming (134 and 135 of
    # 150 seen in loaded CI runs), each chunk within half a second of the last (one gap of 335 samples once,
    # with a CPU hog on one core: a wall-clock timer of a Python node waits when the machine does)
    gaps = [b - a for a, b in zip(forces, forces[1:])]
    assert len(forces) >= 0.6 * span / FORCES_EVERY and max(gaps) <= 25 * FORCES_EVERY, (len(forces), max(gaps))
    commands = rec.messages["/rig/speed_command"]
    # a command with the first estimate at least command_period (20 ms) after the last one, each answering
    # an estimate (its sample_seq ends a batch): 50 a second, counted on the estimates' stamps; the
    # probe, best effort, may miss some (0.82 of a stream seen with four other jobs on the machine)
    answering = [c for c in commands if c.sample_seq in ends]
    assert len(answering) >= 0.75 * (span * SAMPLE_PERIOD) / 0.025, f"{len(answering)} speed commands in {span} samples"
    assert len(commands) <= 1.1 * (span * SAMPLE_PERIOD) / 0.02 + 5, f"{len(commands)} speed commands in {span} samples"
    truth = [m.seq for m in rec.messages["/sim/truth"]]
    assert all(s % DECIMATION == 0 for s in truth)
    firsts = {b.first_seq for b in batches}
    for topic in SAMPLE_BATCH_TOPICS:
        in_span = [b for b in rec.messages[topic] if seqs[0] <= b.first_seq <= seqs[-1]]
        report.append(f"{topic} {len(in_span)} batches")
        assert all(len(b.tau_load) == BATCH and b.sample_period == SAMPLE_PERIOD for b in in_span), topic
        assert len(in_span) * BATCH >= DELIVERED * span, f"{topic}: {len(in_span) * BATCH} samples of {span}"
        assert {b.first_seq % BATCH for b in in_span} == {f % BATCH for f in firsts}, \
            f"{topic}: batches not aligned with /rig/samples'"
    for topic in SLOW_TOPICS:
        in_span = [m for m in rec.messages[topic] if t0 <= stamp_s(m.header) <= stamp_s(samples[-1].header)]
        report.append(f"{topic} {len(in_span)}")
        assert len(in_span) >= DELIVERED * span / DECIMATION, f"{topic}: {len(in_span)} in {span} samples"
    print(", ".join(report))
    graph.assert_alive()


#: /sim/truth_samples' test: how long a stretch of the rig's stream it judges, how often the load steps in it
TRUTH_SPAN = 3000  # [samples]
LOAD_EVERY = 250  # [samples]
LOAD_STEP = 0.2  # [N m] load applied every other LOAD_EVERY samples
#: [N m] how far a sample's measured tau_load may lie outside the true load over its period: K_t,load (0.055 N m/A)
#: x the two load currents, each with 0.02 A of noise (sigma 0.0016 N m) and rounded to 0.026 A (at most 0.0015 N m
#: together). Over 8 sigma; a truth off by one sample misses by 0.03 N m or more on a LOAD_STEP step.
TAU_LOAD_TOLERANCE = 0.015


def test_sim_truth_samples_carry_every_sample_once_in_the_rig_batches(graph: RunningGraph) -> None:
    """/sim/truth_samples (SimTruths): every sample's truth exactly once, in batches aligned with /rig/samples'
    (same first_seq, stamp, sample period and length), the truth of the very sample of that seq: each sample's
    measured tau_load lies between the true load at its period's start and end (within the sensor noise), through
    load steps. Judged on the streams' own numbers, the samples' seqs and the DDS publication sequence numbers
    (which tell a message this best-effort probe missed from one the rig never sent), never on the wall clock.
    The probe is its own node on a SingleThreadedExecutor: the module's EventsExecutor cannot deliver message info."""
    truths: list[tuple[int, SimTruths]] = []
    batches: dict[int, RigSamples] = {}

    def on_truth(msg: SimTruths, info) -> None:
        truths.append((info["publication_sequence_number"], msg))

    with probe_node("truth_samples_probe", SingleThreadedExecutor) as (node, executor):
        node.create_subscription(SimTruths, "/sim/truth_samples", on_truth, PROBE_QOS)
        node.create_subscription(RigSamples, "/rig/samples", lambda m: batches.setdefault(m.first_seq, m), PROBE_QOS)
        load = node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)

        assert spin_until(executor, lambda: bool(truths and batches) and load.get_subscription_count() >= 1,
                          START_TIMEOUT), \
            f"/sim/truth_samples: {len(truths)} messages, /rig/samples: {len(batches)}\n{graph.logs()}"
        first, phase = truths[0][1].first_seq, None

        def stepping() -> bool:  # the load steps every LOAD_EVERY samples of the rig's clock
            nonlocal phase
            newest = truths[-1][1].first_seq
            if (now := (newest - first) // LOAD_EVERY % 2) != phase:
                phase = now
                load.publish(LoadCommand(torque=LOAD_STEP * now))
            return newest - first >= TRUTH_SPAN

        try:
            assert spin_until(executor, stepping, 60.0), (
                f"/sim/truth_samples: {truths[-1][1].first_seq - first} samples of {TRUTH_SPAN} in 60 s\n"
                f"{graph.logs()}")
        finally:
            load.publish(LoadCommand(torque=0.0))  # no load for the tests after this one: wait till the rig has it
            end = truths[-1][1].first_seq
            spin_until(executor, lambda: truths[-1][1].first_seq > end and abs(truths[-1][1].tau_load[-1]) < 0.01, 10.0)
    graph.assert_alive()

    # every batch whole; consecutive DDS numbers hold consecutive samples (a missed message: BATCH samples per number)
    assert all(len(getattr(m, name)) == BATCH for _, m in truths for name in TRUTH_FIELDS), "a batch not of BATCH"
    assert all(m.sample_period == SAMPLE_PERIOD for _, m in truths)
    published = truths[-1][0] - truths[0][0] + 1
    assert len(truths) >= DELIVERED * published, f"the probe got {len(truths)} of {published} messages"
    for (n1, a), (n2, b) in zip(truths, truths[1:]):
        assert b.first_seq == a.first_seq + BATCH * (n2 - n1), (
            f"DDS numbers {n1} -> {n2}: seqs {a.first_seq} -> {b.first_seq}: samples skipped or repeated")
    # the same batches as /rig/samples'
    paired = [(m, batches[m.first_seq]) for _, m in truths if m.first_seq in batches]
    assert len(paired) >= DELIVERED * len(truths), f"{len(paired)} of {len(truths)} truth batches with their samples"
    for m, b in paired:
        assert (m.header.stamp, m.header.frame_id, len(m.tau_load)) == (b.header.stamp, b.header.frame_id,
                                                                       len(b.tau_load)), m.first_seq
    assert {m.first_seq % BATCH for _, m in truths} == {f % BATCH for f in batches}
    # each sample's truth is that of the sample of its seq
    true_load = {m.first_seq + k: tau for _, m in truths for k, tau in enumerate(m.tau_load)}
    measured = {b.first_seq + k: tau for b in batches.values() for k, tau in enumerate(b.tau_load)}
    judged, outside = 0, []
    for seq in sorted(true_load.keys() & measured.keys()):
        if seq - 1 not in true_load:
            continue
        low, high = sorted((true_load[seq - 1], true_load[seq]))
        judged += 1
        if not low - TAU_LOAD_TOLERANCE <= measured[seq] <= high + TAU_LOAD_TOLERANCE:
            outside.append((seq, true_load[seq - 1], measured[seq], true_load[seq]))
    steps = sum(1 for seq in true_load if seq - 1 in true_load and abs(true_load[seq] - true_load[seq - 1]) > 0.05)
    print(f"/sim/truth_samples: {len(truths)} of {published} messages, {len(paired)} with their /rig/samples batch; "
          f"tau_load judged on {judged} samples, {steps} in a load step's first rise or fall")
    assert judged >= DELIVERED * TRUTH_SPAN and steps >= 4, (judged, steps)
    assert not outside, f"measured tau_load outside the true load of its period (seq, true before, measured, " \
                        f"true after): {outside[:10]}"


def test_speed_commands_act_at_the_rig_after_the_sample_they_answer(graph: RunningGraph, probe: Probe) -> None:
    """Causality on the rig's clock: every speed command (sample_seq = the newest sample its estimate
    came from) is in force from a later sample on, never earlier, and the rig runs in speed mode."""
    rec, subs = probe.record({"/rig/samples": RigSamples})
    try:
        assert probe.wait_all_flowing(rec), graph.logs()
        probe.spin_for(2.0)
    finally:
        probe.unsubscribe(subs)
    samples = [s for b in rec.messages["/rig/samples"] for s in unbatch(b)]
    latencies = command_latencies(samples)
    assert len(latencies) > 30, f"only {len(latencies)} speed commands took effect in 2 s"
    assert min(latencies) >= 0, "a command drove a period before the sample it was computed from"
    assert all(s.command_seq for s in samples[-100:]), "the rig left speed mode"
    assert not any(s.status & RigSample.STATUS_WATCHDOG_STOP for s in samples[-100:])
    graph.assert_alive()


def test_a_volatile_publisher_like_ros2_topic_pub_reaches_the_controller(graph: RunningGraph, probe: Probe) -> None:
    """`ros2 topic pub` offers reliable + volatile: the set-point subscription must accept it."""
    volatile = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE)
    pub = probe.node.create_publisher(Float64, "/controller/speed_setpoint", volatile)
    rec, subs = probe.record({"/rig/speed_command": SpeedCommand})
    try:
        assert probe.spin_until(lambda: pub.get_subscription_count() >= 1, MATCH_TIMEOUT), "no QoS match"
        pub.publish(Float64(data=120.0))
        assert probe.spin_until(lambda: any(m.speed_setpoint == 120.0 for m in rec.messages["/rig/speed_command"]),
                                MATCH_TIMEOUT), "controller_node never took the volatile set-point"
    finally:
        latched = probe.node.create_publisher(Float64, "/controller/speed_setpoint", COMMAND)
        probe.spin_until(lambda: latched.get_subscription_count() >= 1, MATCH_TIMEOUT)
        latched.publish(Float64(data=SPEED_SETPOINT))
        probe.spin_for(0.3)
        probe.unsubscribe(subs)
        probe.node.destroy_publisher(pub)
        probe.node.destroy_publisher(latched)
    graph.assert_alive()


def _steady_estimate(probe: Probe, pub, load: float, settle: float = 1.5, window: float = 1.0
                     ) -> tuple[float, float, float, int]:
    """Apply `load`, settle, average over `window` [s of the rig's clock]: (estimate, true tau_load,
    mean |omega-set-point|, n)."""
    msg = LoadCommand(torque=load)
    msg.header.stamp = probe.node.get_clock().now().to_msg()
    pub.publish(msg)
    rec, subs = probe.record({"/torque_estimate": TorqueEstimate, "/sim/truth": SimTruth})
    def applied() -> float | None:  # the rig's stamp [s] of its first sample under the load (None: not yet)
        return next((stamp_s(t.header) for t in rec.messages["/sim/truth"] if abs(t.tau_load - load) < 1e-9), None)

    def rig_time() -> float:  # [s] the newest truth's stamp
        return stamp_s(rec.messages["/sim/truth"][-1].header) if rec.messages["/sim/truth"] else -math.inf

    try:
        assert probe.wait_all_flowing(rec), "no /torque_estimate or /sim/truth"
        # settle and average on the rig's clock (its stamps), not this process's: a busy host slows the rig
        assert probe.spin_until(lambda: applied() is not None and rig_time() >= applied() + settle + window, 60.0), (
            f"the rig did not run {settle + window} s under load {load:+.3f} N m")
    finally:
        probe.unsubscribe(subs)
    start = applied() + settle
    estimates = [m.torque for m in rec.messages["/torque_estimate"]
                 if math.isfinite(m.torque) and start <= stamp_s(m.header) <= start + window]
    truth = [t for t in rec.messages["/sim/truth"] if start <= stamp_s(t.header) <= start + window]
    assert estimates and truth, f"nothing received in {window} s"
    mean = sum(estimates) / len(estimates)
    true_load = sum(t.tau_load for t in truth) / len(truth)
    speed_error = sum(abs(t.omega_worm - SPEED_SETPOINT) for t in truth) / len(truth)
    return mean, true_load, speed_error, len(estimates)


def test_estimate_follows_true_load_in_steady_state(graph: RunningGraph, probe: Probe) -> None:
    torque_range = load_database(graph.calibration_file).torque_range
    tolerance = 0.05 * torque_range
    pub = probe.node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)
    try:
        # Resistive (opposes the positive rotation), then assistive.
        for load in (+0.15, -0.15):
            estimate, true_load, speed_error, n = _steady_estimate(probe, pub, load)
            where = (f"load command {load:+.3f} N m: estimate {estimate:+.4f} N m over {n} samples, "
                     f"true tau_load {true_load:+.4f} N m, mean |omega - {SPEED_SETPOINT:g}| "
                     f"{speed_error:.2f} rad/s")
            print(where)
            assert abs(true_load - load) < tolerance, f"the sim did not apply the load: {where}"
            assert abs(estimate - true_load) <= tolerance, (
                f"{where}; tolerance 5 % of the calibrated range {torque_range:.3f} N m = {tolerance:.4f} N m")
            assert speed_error < 3.0, f"the controller does not hold the set-point: {where}"
    finally:
        # Back to no load for the tests after this one.
        pub.publish(LoadCommand(torque=0.0))
        probe.spin_for(0.2)
        probe.node.destroy_publisher(pub)
    graph.assert_alive()


def test_nan_samples_are_flagged_and_the_graph_keeps_running(graph: RunningGraph, probe: Probe) -> None:
    """Batches of NaN speed/current samples injected on /rig/samples: model_node publishes forces flagged
    INVALID_INPUT with NaN forces and counts them; it keeps its filter state, keeps running and keeps
    publishing finite forces for the rig's samples after the bad ones, and so does the rig its estimates.
    (An estimator_node fed NaN: tests/test_joint_state_dds.py; LiveEstimator: test_live_estimator.)"""
    first_bad = 10**12  # far beyond the sim's seqs: these samples are recognisable downstream
    bad_seqs = {first_bad + BATCH * i + BATCH - 1 for i in range(6)}  # the batches' newest samples
    pub = probe.node.create_publisher(RigSamples, "/rig/samples", PROBE_QOS)
    rec, subs = probe.record({"/torque_estimate": TorqueEstimate, "/gearbox/forces": GearboxForces,
                              "/diagnostics": DiagnosticArray})
    try:
        assert probe.wait_all_flowing(rec), f"no estimates or forces\n{graph.logs()}"
        assert probe.spin_until(lambda: pub.get_subscription_count() >= 1, MATCH_TIMEOUT), (
            f"model_node did not match the probe's /rig/samples publisher "
            f"({pub.get_subscription_count()} subscriptions)")
        probe.spin_for(0.3)
        for i, seq in enumerate(sorted(bad_seqs)):
            current = math.nan if i % 2 == 0 else 1.0
            values = {name: [0.0] * BATCH for name in ("current_load_1", "current_load_2", "omega_gear", "theta_worm",
                                                        "theta_gear", "voltage_drive")}
            batch = RigSamples(first_seq=seq - BATCH + 1, sample_period=SAMPLE_PERIOD, current_drive=[current] * BATCH,
                               omega_worm=[math.nan] * BATCH, tau_load=[0.1] * BATCH, count_drive=[0] * BATCH,
                               count_load_1=[0] * BATCH, count_load_2=[0] * BATCH,
                               status=[RigSample.STATUS_SIMULATED] * BATCH, command_seq=[0] * BATCH, **values)
            batch.header.stamp = probe.node.get_clock().now().to_msg()
            pub.publish(batch)
            probe.spin_for(0.02)
        # and one malformed batch (fields of unequal length): refused with a reason, nobody dies
        pub.publish(RigSamples(first_seq=first_bad + 1000, sample_period=SAMPLE_PERIOD, omega_worm=[1.0, 2.0],
                               current_drive=[0.1]))
        probe.spin_for(0.02)
        last_bad = time.monotonic()
        probe.spin_for(1.2)
    finally:
        probe.unsubscribe(subs)
        probe.node.destroy_publisher(pub)
    graph.assert_alive()

    assert "ignored a rig/samples message (first_seq 1000000001000): fields of unequal length" in graph.logs()
    forces = [m for m in rec.messages["/gearbox/forces"] if m.seq in bad_seqs]
    # model_node publishes forces for the newest sample of each 20 ms chunk: the NaN samples show in its
    # count of invalid inputs (and as flagged forces if one ended a chunk)
    invalid = [int(kv.value) for m in rec.messages["/diagnostics"] for s in m.status if s.name == "model_node"
               for kv in s.values if kv.key == "invalid_inputs"]
    assert invalid and max(invalid) >= BATCH, f"model_node counted {invalid} invalid inputs"
    for m in forces:
        assert m.flags & GearboxForces.FLAG_INVALID_INPUT, f"forces for NaN sample {m.seq}: flags {m.flags}"
        assert math.isnan(m.normal_force), f"forces for NaN sample {m.seq}: N = {m.normal_force}"

    # Still publishing for the rig's samples after the bad ones, and finite again.
    for topic, msgs in rec.messages.items():
        if topic == "/diagnostics":
            continue
        times = rec.times[topic]
        later = [m for m, t in zip(msgs, times) if t > last_bad + 0.2 and m.seq not in bad_seqs]
        span = max(m.seq for m in later) - min(m.seq for m in later) + 1 if later else 0
        every = FORCES_EVERY if topic == "/gearbox/forces" else BATCH
        # the forces come on model_node's wall-clock timer, whose periods a busy host skips (40 for 981
        # samples once on a loaded CI host): judged as the steady-state test judges them
        delivered = DELIVERED if topic != "/gearbox/forces" else 0.6
        assert span > 500 and len(later) >= delivered * span / every, (
            f"{topic}: {len(later)} messages for {span} samples after the NaN input")
        if topic == "/torque_estimate":
            assert all(math.isfinite(m.torque) and not m.flags & TorqueEstimate.FLAG_INVALID_INPUT
                       for m in later), "estimates after the NaN samples are NaN or flagged invalid"
        else:
            assert all(math.isfinite(m.normal_force) and not m.flags & GearboxForces.FLAG_INVALID_INPUT
                       for m in later), "forces after the NaN samples are NaN or flagged invalid"


def test_nan_commands_are_rejected_with_a_reason_and_nodes_keep_running(
        graph: RunningGraph, probe: Probe) -> None:
    """NaN drive, speed and load commands to sim_node and a NaN speed set-point to controller_node: each
    is refused with a logged reason (a throttled warning followed by another warning once crashed
    rclpy's logger in sim_node), and the rig keeps streaming samples in speed mode."""
    drive = probe.node.create_publisher(DriveCommand, "/rig/drive_command", PROBE_QOS)
    speed = probe.node.create_publisher(SpeedCommand, "/rig/speed_command", PROBE_QOS)
    load = probe.node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)
    setpoint = probe.node.create_publisher(Float64, "/controller/speed_setpoint", COMMAND)
    rec, subs = probe.record({"/rig/samples": RigSamples})
    try:
        assert probe.spin_until(lambda: drive.get_subscription_count() >= 1 and load.get_subscription_count() >= 1
                                and setpoint.get_subscription_count() >= 1 and speed.get_subscription_count() >= 1,
                                MATCH_TIMEOUT), "publishers unmatched"
        for _ in range(3):
            drive.publish(DriveCommand(voltage=math.nan))
            speed.publish(SpeedCommand(speed_setpoint=math.nan, kp=1e-3, ki=0.02, voltage_limit=24.0))
            probe.spin_for(0.02)
        load.publish(LoadCommand(torque=math.nan))
        probe.spin_for(0.05)
        setpoint.publish(Float64(data=math.inf))
        probe.spin_for(0.3)
        after = time.monotonic()
        probe.spin_for(1.0)
        # Leave the latched set-point valid again for the tests after this one.
        setpoint.publish(Float64(data=SPEED_SETPOINT))
        probe.spin_for(0.3)
    finally:
        probe.unsubscribe(subs)
        for pub in (drive, speed, load, setpoint):
            probe.node.destroy_publisher(pub)
    graph.assert_alive()
    later = [s for b, t in zip(rec.messages["/rig/samples"], rec.times["/rig/samples"]) if t >= after
             for s in unbatch(b)]
    assert len(later) > 500, f"/rig/samples: only {len(later)} samples after the NaN commands"
    assert all(s.command_seq for s in later[-100:]), "the rig left speed mode after the refused commands"
    logs = graph.logs()
    assert "rejected drive command: voltage=nan" in logs, logs
    assert "rejected speed command: setpoint=nan" in logs, logs
    assert "rejected load command: torque=nan" in logs, logs
    assert "ignored speed set-point inf" in logs, logs


def test_missing_calibration_stops_the_node(ros_env: dict[str, str], probe: Probe, tmp_path: Path) -> None:
    """knn with no calibration named: the node cannot do its job, so it stops at start, one line naming the
    parameter, exit 2; a calibration file named but missing: the same, naming the file."""
    params = tmp_path / "estimator_only.yaml"
    params.write_text("estimator_node:\n  ros__parameters:\n    method: knn\n", encoding="utf-8")
    unnamed = Graph(params, {}, tmp_path / "logs")
    try:
        unnamed.start()
        assert probe.spin_until(lambda: bool(unnamed.failed()), 30.0), "estimator_node kept running"
    finally:
        codes = unnamed.stop()
    assert codes == {"estimator_node": 2}, codes
    assert "parameter calibration_file:" in node_logs(tmp_path / "logs")

    missing = tmp_path / f"no_such_calibration_{random.randrange(10**9)}.json"
    named = Graph(params, parse_overrides([f"estimator_node.calibration_file={missing}"]), tmp_path / "logs_named")
    try:
        named.start()
        assert probe.spin_until(lambda: bool(named.failed()), 30.0), "estimator_node kept running"
    finally:
        codes = named.stop()
    assert codes == {"estimator_node": 2}, codes
    log = node_logs(tmp_path / "logs_named")
    assert missing.name in log and "Traceback" not in log, log


def test_a_foreign_stack_reads_the_estimate_in_standard_types(graph: RunningGraph, probe: Probe) -> None:
    """Subscribed as another robot stack would, with sensor_msgs and geometry_msgs only: the gear joint's
    effort and the wrench's torque about the output axis are the load's torque on the shaft (-tau_d)."""
    from geometry_msgs.msg import WrenchStamped

    load = probe.node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)
    rec, subs = probe.record({"/torque_estimate/joint_states": JointState, "/torque_estimate/wrench": WrenchStamped,
                              "/sim/truth": SimTruth})
    try:
        assert probe.spin_until(lambda: load.get_subscription_count() >= 1, MATCH_TIMEOUT)
        load.publish(LoadCommand(torque=0.15))
        assert probe.wait_all_flowing(rec), f"silent: {[t for t, m in rec.messages.items() if not m]}"
        probe.spin_for(1.5)
        rec.clear()
        probe.spin_for(1.0)
    finally:
        load.publish(LoadCommand(torque=0.0))
        probe.spin_for(0.2)
        probe.unsubscribe(subs)
        probe.node.destroy_publisher(load)
    joints = rec.messages["/torque_estimate/joint_states"]
    wrenches = rec.messages["/torque_estimate/wrench"]
    true_load = sum(t.tau_load for t in rec.messages["/sim/truth"]) / len(rec.messages["/sim/truth"])
    assert all(j.name == ["gear"] and len(j.effort) == 1 for j in joints)
    assert all(w.header.frame_id == "gear_output" and w.wrench.force.x == 0.0 for w in wrenches)
    # An estimate the observer flags goes out as NaN (a false step alarm's TRANSIENT samples: offline at this
    # point 0-2 alarms in 30 s, 13-20 samples each). Seen here: none in most runs; once 13 of 240 on a machine
    # busy with two other test files. What this guards: the standard outputs carry the estimate, not NaN.
    efforts = [j.effort[0] for j in joints if math.isfinite(j.effort[0])]
    torques = [w.wrench.torque.z for w in wrenches if math.isfinite(w.wrench.torque.z)]
    assert len(efforts) >= 0.8 * len(joints) and len(torques) >= 0.8 * len(wrenches), (len(efforts), len(joints))
    effort = sum(efforts) / len(efforts)
    torque = sum(torques) / len(torques)
    tolerance = 0.05 * load_database(graph.calibration_file).torque_range
    assert abs(effort + true_load) < tolerance and abs(torque + true_load) < tolerance, (effort, torque, true_load)
    rate = batch_rate(GRAPH_FILE)  # [Hz] one estimate per batch; the window is 1 s
    assert len(joints) > 0.5 * rate and len(wrenches) > 0.5 * rate, (len(joints), len(wrenches))
    graph.assert_alive()
