"""System test: the recorder node, as its own process, records a 1 kHz stream over DDS.

This process publishes RigSample messages with consecutive ``seq``; the
recorder process records them; after SIGINT/SIGTERM the bag must hold every
one of them, in order, the recorder must say it lost nothing (from the
sequence numbers), and it must have exited with code 0 (not SIGABRT). The
5-minute run at 1 kHz is bench/recorder_bench.py. Each run uses its own ROS_DOMAIN_ID, with discovery kept on this host.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from worm_msgs.msg import RigSample

from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from worm_model.bags.writer import BagWriter, read_bag_counts, read_messages
from worm_rig_driver.nodes import recorder_node
from worm_rig_driver.nodes.recorder_node import FIRST_DISCOVERY_PERIOD_S, TAKE_BATCH, TopicRecorder

TOPIC = '/rig/sample'
DISCOVERED = '/probe/rig_sample'  # recorded by discovery (not excluded)
RATE_HZ = 1000.0
DOMAIN_ID = random.randint(100, 200)
DISCOVERY_TIMEOUT_S = 30.0
ACK_TIMEOUT_S = 20.0
EXIT_TIMEOUT_S = 20.0


@pytest.fixture
def ros_env(monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """Environment of this run for both processes (this one and the recorder)."""
    monkeypatch.setenv('ROS_DOMAIN_ID', str(DOMAIN_ID))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return dict(os.environ)


@pytest.fixture
def publisher_node(ros_env: dict[str, str]) -> Iterator[Node]:
    """A node of this process, in its own context, torn down cleanly."""
    context = Context()
    rclpy.init(context=context)
    node = Node('rig_sample_source', context=context)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


class RecorderProcess:
    """``python -m worm_rig_driver.nodes.recorder_node`` with its output in files."""

    def __init__(self, tmp_path: Path, env: dict[str, str], *ros_params: str) -> None:
        self.bag = tmp_path / 'bag'
        self.log = tmp_path / 'recorder.log'
        params = [arg for p in (f'output:={self.bag}', 'discovery_period:=0.2', *ros_params)
                  for arg in ('-p', p)]
        with self.log.open('wb') as log:
            self.process = subprocess.Popen(
                [sys.executable, '-m', 'worm_rig_driver.nodes.recorder_node', '--ros-args', *params],
                env=env, stdout=log, stderr=subprocess.STDOUT,
            )

    def output(self) -> str:
        """What the recorder printed so far."""
        return self.log.read_text(errors='replace')

    def stop(self, signum: signal.Signals) -> int:
        """Send ``signum`` and return the exit code."""
        self.process.send_signal(signum)
        try:
            return self.process.wait(timeout=EXIT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            pytest.fail(f'recorder ignored {signum.name}:\n{self.output()}')

    def kill(self) -> None:
        """Make sure the process is gone (test teardown)."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()


@pytest.fixture
def start_recorder(tmp_path: Path, ros_env: dict[str, str]) -> Iterator[type[RecorderProcess]]:
    """Factory starting one recorder process; kills it if the test did not stop it."""
    started: list[RecorderProcess] = []

    def start(*ros_params: str) -> RecorderProcess:
        recorder = RecorderProcess(tmp_path, ros_env, *ros_params)
        started.append(recorder)
        return recorder

    yield start  # type: ignore[misc]
    for recorder in started:
        recorder.kill()


def publish_stream(node: Node, recorder: RecorderProcess, n: int, topic: str = TOPIC) -> None:
    """Publish RigSamples seq 0..n-1 at RATE_HZ once the recorder has subscribed.

    The publisher keeps all n samples (KEEP_LAST depth n, RELIABLE), so a
    slow acknowledgement never overwrites one, and waits until all are acked.
    """
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=n,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)
    publisher = node.create_publisher(RigSample, topic, qos)
    deadline = time.monotonic() + DISCOVERY_TIMEOUT_S
    while publisher.get_subscription_count() == 0:
        if recorder.process.poll() is not None:
            pytest.fail(f'recorder exited with {recorder.process.returncode}:\n{recorder.output()}')
        if time.monotonic() > deadline:
            pytest.fail(f'recorder did not subscribe to {topic}:\n{recorder.output()}')
        time.sleep(0.05)

    period = 1.0 / RATE_HZ
    start = time.perf_counter()
    for seq in range(n):
        msg = RigSample(seq=seq, omega_worm=0.01 * seq, status=RigSample.STATUS_SIMULATED)
        msg.header.stamp = node.get_clock().now().to_msg()
        publisher.publish(msg)
        if (delay := start + (seq + 1) * period - time.perf_counter()) > 0:
            time.sleep(delay)
    assert publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S)), 'recorder did not ack'


def assert_bag_holds_stream(recorder: RecorderProcess, n: int, topic: str = TOPIC) -> None:
    """The bag holds seq 0..n-1 on ``topic`` exactly once each, in receive order."""
    TOPIC = topic  # noqa: N806 (the checks below read as for the default topic)
    counts = read_bag_counts(recorder.bag)
    assert counts.get(TOPIC) == n, (counts, recorder.output())
    received = list(read_messages(recorder.bag, TOPIC))
    assert [m.seq for _, m in received] == list(range(n)), 'gap, duplicate or reordering'
    stamps = [t for t, _ in received]
    assert stamps == sorted(stamps)
    assert f'{TOPIC}: {n}' in recorder.output()
    # The recorder's own end-of-run verdict, from the sequence numbers it saw.
    assert f'{TOPIC}: seq 0..{n - 1}: {n} received, lost 0' in recorder.output()
    assert f'{TOPIC}: {n} received from 1 publisher(s), 0 missing in their DDS sequence numbers' \
        in recorder.output()
    assert 'recorder: lost nothing' in recorder.output()


def test_records_1khz_stream_without_loss(
    publisher_node: Node, start_recorder: type[RecorderProcess]
) -> None:
    n = 2000
    recorder = start_recorder(f'topics:=[{TOPIC}]')
    publish_stream(publisher_node, recorder, n)

    assert recorder.stop(signal.SIGINT) == 0, recorder.output()
    assert_bag_holds_stream(recorder, n)
    assert set(read_bag_counts(recorder.bag)) == {TOPIC}


def test_records_discovered_topics_and_stops_on_sigterm(
    publisher_node: Node, start_recorder: type[RecorderProcess]
) -> None:
    """Recording every topic finds a new one; /rig/sample, the rig's per-sample copy of /rig/samples,
    is left out by default (a publisher on it is there, and not recorded)."""
    n = 300
    recorder = start_recorder('storage:=sqlite3')  # no topics: record all
    excluded = publisher_node.create_publisher(RigSample, TOPIC, 10)
    publish_stream(publisher_node, recorder, n, DISCOVERED)
    excluded.publish(RigSample(seq=1))

    assert recorder.stop(signal.SIGTERM) == 0, recorder.output()
    assert_bag_holds_stream(recorder, n, DISCOVERED)
    assert TOPIC not in read_bag_counts(recorder.bag)
    assert f'Recording {TOPIC} ' not in recorder.output()


def test_a_stop_signal_while_it_subscribes_closes_the_bag(ros_env: dict[str, str], tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A recorder stopped while it subscribes to the topics it found (twenty took 13 s on a loaded CI host)
    stops as on any stop, its bag closed with what it has: the subscribing runs on the executor, where a
    signal asks the loop to end, not during start, where a signal ends the process at once (exit 130, the
    bag left unclosed). Here the SIGINT comes from inside the first subscription (the recorder's own
    /parameter_events), in this process, through recorder_node.main."""
    subscribe = TopicRecorder._try_subscribe
    interrupted: list[str] = []

    def subscribe_and_interrupt(recorder: TopicRecorder, topic: str) -> bool:
        if not interrupted:
            interrupted.append(topic)
            os.kill(os.getpid(), signal.SIGINT)
        return subscribe(recorder, topic)
    monkeypatch.setattr(TopicRecorder, '_try_subscribe', subscribe_and_interrupt)
    handlers = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGTERM)}
    try:
        code = recorder_node.main(['recorder', '--ros-args', '-p', f'output:={tmp_path / "bag"}'])
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
    assert interrupted and code == 0, (interrupted, code)
    assert (tmp_path / 'bag' / 'metadata.yaml').exists(), 'the bag was not closed'
    assert interrupted[0] in read_bag_counts(tmp_path / 'bag')


def test_topic_recorder_records_under_the_events_executor(publisher_node: Node, tmp_path: Path) -> None:
    """The demo records with a TopicRecorder spun by rclpy's EventsExecutor, which cannot deliver
    message info: with message_info=False every message still reaches the bag."""
    executor = EventsExecutor(context=publisher_node.context)
    executor.add_node(publisher_node)
    recorder = TopicRecorder(publisher_node, BagWriter(tmp_path / 'bag', 'mcap'), message_info=False)
    publisher = publisher_node.create_publisher(RigSample, TOPIC, QoSProfile(
        history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))
    try:
        recorder.subscribe(TOPIC)
        deadline = time.monotonic() + DISCOVERY_TIMEOUT_S
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            recorder.discover()
            executor.spin_once(timeout_sec=0.05)
        assert publisher.get_subscription_count() == 1, 'the recorder did not subscribe'
        for seq in range(200):
            publisher.publish(RigSample(seq=seq))
            executor.spin_once(timeout_sec=0.01)
        deadline = time.monotonic() + ACK_TIMEOUT_S
        while recorder.counts.get(TOPIC, 0) < 200 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    finally:
        recorder.close()
        executor.shutdown()
    assert [m.seq for _, m in read_messages(tmp_path / 'bag', TOPIC)] == list(range(200))


def test_topic_recorder_takes_the_queue_and_stamps_dds_receive_times(publisher_node: Node, tmp_path: Path) -> None:
    """A callback writes what its subscription holds, up to TAKE_BATCH more messages, and every message is
    stamped with the time DDS received it (the message info's), not the time it was written: messages all
    acknowledged by the recorder's reader before the executor ran carry stamps from before it ran, between
    their publication stamp and that moment."""
    n = 2 * TAKE_BATCH + 50
    executor = SingleThreadedExecutor(context=publisher_node.context)
    executor.add_node(publisher_node)
    recorder = TopicRecorder(publisher_node, BagWriter(tmp_path / 'bag', 'mcap'))
    publisher = publisher_node.create_publisher(RigSample, TOPIC, QoSProfile(
        history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))
    written_per_pass = []
    try:
        recorder.subscribe(TOPIC)
        deadline = time.monotonic() + DISCOVERY_TIMEOUT_S
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            recorder.discover()
            time.sleep(0.05)
        assert publisher.get_subscription_count() == 1, 'the recorder did not subscribe'
        for seq in range(n):
            msg = RigSample(seq=seq)
            msg.header.stamp = publisher_node.get_clock().now().to_msg()
            publisher.publish(msg)
        assert publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S)), 'the reader did not ack'
        before_spin = time.time_ns()  # every message is in the subscription's queue now
        deadline = time.monotonic() + ACK_TIMEOUT_S
        while (done := recorder.counts.get(TOPIC, 0)) < n and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            if (now := recorder.counts.get(TOPIC, 0)) > done:
                written_per_pass.append(now - done)
    finally:
        recorder.close()
        executor.remove_node(publisher_node)
        executor.shutdown()
    received = list(read_messages(tmp_path / 'bag', TOPIC))
    assert [m.seq for _, m in received] == list(range(n))
    assert written_per_pass == [1 + TAKE_BATCH, 1 + TAKE_BATCH, n - 2 * (1 + TAKE_BATCH)]
    published = [m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec for _, m in received]
    assert all(p <= t <= before_spin for p, (t, _) in zip(published, received)), 'stamp not the receive time'
    assert 'recorder: lost nothing' in recorder.loss_report()[1][-1]


def test_discovery_is_fast_at_first_then_at_its_period(publisher_node: Node, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A recorder searches the graph every FIRST_DISCOVERY_PERIOD_S at first (a restarted recorder records
    as soon as DDS has found the publishers), then at its discovery_period; each search subscribes to what
    it finds. Judged by the timer's period and the searches counted, not by how long they took."""
    monkeypatch.setattr(recorder_node, 'FIRST_DISCOVERY_S', 0.5)
    executor = SingleThreadedExecutor(context=publisher_node.context)
    executor.add_node(publisher_node)
    recorder = TopicRecorder(publisher_node, BagWriter(tmp_path / 'bag', 'mcap'))
    searches = []
    monkeypatch.setattr(recorder, 'discover', lambda: searches.append(time.monotonic()))
    try:
        recorder.start_discovery(5.0)
        timer = recorder._discovery_timer
        assert timer.timer_period_ns == int(FIRST_DISCOVERY_PERIOD_S * 1e9)
        first = time.monotonic()
        while timer.timer_period_ns != int(5.0 * 1e9) and time.monotonic() < first + DISCOVERY_TIMEOUT_S:
            executor.spin_once(timeout_sec=0.05)
        assert timer.timer_period_ns == int(5.0 * 1e9), 'still searching fast'
        assert searches and searches[-1] >= first + 0.45  # searching fast until FIRST_DISCOVERY_S had passed
    finally:
        recorder.close()
        executor.remove_node(publisher_node)
        executor.shutdown()
