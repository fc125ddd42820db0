"""Record topics into a rosbag2 bag: the rclpy shell over :mod:`worm_rig_driver.recording.recorder` (which
topics, their classes and offered QoS, the loss report), :mod:`~worm_rig_driver.recording.bag_folder` (which
folder) and :mod:`worm_model.bags.writer` (the bag).

Node ``recorder``. It subscribes with ``raw=True`` and writes the CDR bytes as
received, stamped with their receive time (ns), like ``ros2 bag record``: when
DDS received them (the message info's ``received_timestamp``, system time),
rising per topic, or the node clock's time when written under simulated time.
Each callback writes what its subscription has queued, and the main loop
pauses :data:`GATHER_S` after each callback, so that one executor pass takes
several messages of each topic: the pass costs more CPU than writing, and a
recorder that needs less CPU is left behind its streams (losing messages, and
holding the backlog's memory in its DDS queues afterwards) on a busier machine
only.

On SIGINT or SIGTERM it writes the messages already queued, closes the bag
(``metadata.yaml`` written), logs the message count of every topic and exits
with code 0 (1 on a bag error while recording). Bad parameters (an invalid
topic name, an output that exists) are refused before the bag is created: one
line, exit code 2, nothing left behind.

Parameters:
    output (string): bag directory to create; must not exist, unless it holds
        a bag whose recorder was killed (no metadata.yaml): then the recording
        goes into a new folder beside it, ``<output>.1`` (the first free
        number), and the cut-off bag is left as it is
        (:mod:`worm_rig_driver.recording.bag_folder`). Empty: a
        ``rosbag2_YYYY_MM_DD-HH_MM_SS`` directory in the working directory.
    storage (string): ``mcap`` (default) or ``sqlite3``.
    compression (string): ``none`` (default) or ``zstd``: MCAP chunk compression, as
        ``ros2 bag record --storage-preset-profile zstd_fast`` writes it (Foxglove and
        PlotJuggler open such files as they are); mcap only.
    topics (string array): topics to record (a relative name is resolved in the
        recorder's namespace, ``--ros-args -r __ns:=/arm/joint2``). Unset or empty:
        every topic of the graph, hidden ones (a ``_``-prefixed name part) and
        ``exclude`` excepted.
    exclude (string array): topics left out when recording every topic
        (default ``[rig/sample]``: a rig publishes that per-sample copy of its
        rig/samples only while someone subscribes, and recording it would
        double what the rig publishes for nothing; ``[]`` records it too). An
        absolute name is that topic; a relative one, that topic in any
        namespace (every rig of a graph of namespaced drives).
    discovery_period (double, s): how often the graph is searched for the
        topics' publishers (and, when recording all, for new topics); every
        0.1 s for the first 3 s.
    queue_depth (integer): KEEP_LAST depth of each subscription (default
        10000): a 1 kHz stream survives a 10 s stall of the recorder's
        executor (a starved CPU) before DDS overwrites unread messages. At
        1000 a 5-minute bench run on a loaded 2-core machine lost 2983
        messages in one 2.8 s stall, even from a RELIABLE publisher: reliability
        does not protect a reader's KEEP_LAST queue.

Loss: the recorder follows, per topic and publisher, the DDS publication
sequence numbers of what it receives (a gap = a message published and never
received) and, for the streams that carry every sample (the rig's RigSamples and
RigSample, the simulator's SimTruths), the ``seq`` field (a gap there may also be
a sample the rig itself lost; the nodes' answers, one per batch or chunk, and the
decimated SimTruth skip seqs by design and are not checked so). When it stops it
logs both per topic, then one verdict from the DDS numbers: ``recorder: lost
nothing ...`` or ``recorder: LOST <n> messages ...`` (see
:mod:`worm_model.bags.seq_check`).

QoS: a subscription matches its publishers, as rosbag2 does: RELIABLE unless a
publisher is BEST_EFFORT, TRANSIENT_LOCAL if all publishers are (to receive
latched messages), else VOLATILE. The publishers' profiles are stored as the
topic's ``offered_qos_profiles``.

:class:`TopicRecorder` is the same machinery for embedding in another
process's node (the demo does).
"""

from __future__ import annotations

import functools
import os
import shutil
import signal
import sys
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from types import FrameType
from typing import Any, Final

import rclpy
from rclpy.exceptions import InvalidHandle, ParameterException
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription
from rclpy.timer import Timer
from rclpy.topic_endpoint_info import TopicEndpointInfo

from worm_model.cli.errors import one_line
from worm_model.files.writing import check_output
from worm_model.ros.lifecycle import freeze_built_objects, init_rclpy, parameter_problem, start_problem
from worm_model.ros.teardown import deadline
from worm_model.ros.parameters import check_undeclared, help_text, wants_help, wildcard_names
from worm_model.bags.writer import (
    COMPRESSIONS,
    STORAGES,
    BagClosedError,
    BagRecordingError,
    BagWriter,
    TopicHandle,
    normalize_type_name,
)
from worm_model.bags.seq_check import DeliveryCheck, StreamCheck
from worm_model.rig_data.samples import EVERY_SAMPLE_TYPES
from worm_rig_driver.recording.bag_folder import bag_folder, hold
from worm_rig_driver.recording.recorder import (
    DEFAULT_EXCLUDE,
    bag_qos,
    check_topic_name,
    is_excluded,
    is_hidden,
    loss_report,
    message_class,
)

DEFAULT_QUEUE_DEPTH: Final[int] = 10000
SPIN_TIMEOUT_S: Final[float] = 0.1
"""Longest wait of the main loop before it checks for a stop signal."""
GATHER_S: Final[float] = 0.005
"""Pause of the main loop after each callback: messages gather in the subscriptions' queues, and one executor
pass (whose wait set costs more than writing a message) then takes several of each (:data:`TAKE_BATCH`). The
stamps are DDS's receive times, not the write's, so they do not move by it."""
TAKE_BATCH: Final[int] = 100
"""Most messages one subscription's callback takes from its queue (the others' turn comes after)."""
FIRST_DISCOVERY_PERIOD_S: Final[float] = 0.1
FIRST_DISCOVERY_S: Final[float] = 3.0
"""For its first FIRST_DISCOVERY_S the recorder searches the graph every FIRST_DISCOVERY_PERIOD_S (as ``ros2 bag
record``'s 100 ms polling), then every ``discovery_period``: a recorder started beside a running graph (a restart)
records from a tenth of a second after DDS discovery has found the publishers, not up to a period later."""
DRAIN_QUIET_S: Final[float] = 0.2
"""On stop, keep writing queued messages until none arrived for this long ..."""
DRAIN_LIMIT_S: Final[float] = 2.0
"""... or for at most this long."""
STOP_SIGNALS: Final[tuple[signal.Signals, ...]] = (signal.SIGINT, signal.SIGTERM)


def subscription_qos(publishers: Sequence[TopicEndpointInfo], depth: int) -> QoSProfile:
    """Return a KEEP_LAST(``depth``) profile compatible with all ``publishers``."""
    profiles = [p.qos_profile for p in publishers]
    best_effort = any(p.reliability == ReliabilityPolicy.BEST_EFFORT for p in profiles)
    latched = bool(profiles) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles
    )
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


class TopicRecorder:
    """Subscribes a node to topics and writes what arrives into a :class:`BagWriter`.

    Usable in any node; the caller keeps spinning the node. Topics whose
    publishers are not known yet are retried by :meth:`discover`, which the
    caller (or a timer, see :meth:`start_discovery`) calls periodically.
    """

    def __init__(
        self,
        node: Node,
        writer: BagWriter,
        *,
        queue_depth: int = DEFAULT_QUEUE_DEPTH,
        message_info: bool = True,
    ) -> None:
        """Bind ``node`` to ``writer``; subscribes to nothing yet.

        Args:
            node: Node to create the subscriptions on.
            writer: Open bag to write into; :meth:`close` closes it.
            queue_depth: KEEP_LAST depth of every subscription.
            message_info: Take each message's info (DDS publication sequence
                numbers, the loss verdict's evidence). rclpy's experimental
                EventsExecutor cannot deliver it (its callbacks then raise
                ``SystemError: null argument to internal routine``): pass False
                when spinning with it; losses are then judged from ``seq``
                fields only.

        """
        self.node = node
        self.writer = writer
        self.queue_depth = queue_depth
        self.message_info = message_info
        self.wanted: dict[str, str | None] = {}
        """Topics to record -> type name (None: take it from the graph)."""
        self.record_all = False
        self.excluded: set[str] = set()
        """Topics :meth:`subscribe_all` leaves out."""
        self.dropped_after_close = 0
        self.sequences = StreamCheck()
        """``seq`` fields of the recorded streams that carry one."""
        self.deliveries = DeliveryCheck()
        """DDS publication sequence numbers, per topic and publisher."""
        self._subscriptions: dict[str, Subscription[Any]] = {}
        self._failed: set[str] = set()
        self._discovery_timer: Timer | None = None
        self._flush_timer: Timer | None = None
        self._lock = threading.Lock()
        self._clock = node.get_clock()  # one object for the node's life; use_sim_time switches its time source
        self._last_stamp: dict[str, int] = {}
        """Topic -> the last stamp written [ns]."""

    @property
    def counts(self) -> Mapping[str, int]:
        """Messages written so far, per subscribed topic."""
        return dict(self.writer.counts)

    def subscribe(self, topic: str, type_name: str | None = None) -> bool:
        """Record ``topic``; now if its publishers are known, else on discovery.

        Args:
            topic: Topic name.
            type_name: ``pkg/msg/Name``; None takes the type from the graph.

        Returns:
            Whether the subscription exists now.

        Raises:
            BagRecordingError: No definition or Python class for the type.

        """
        with self._lock:
            self.wanted.setdefault(topic, type_name)
            return self._try_subscribe(topic)

    def want(self, topic: str, type_name: str | None = None) -> None:
        """Record ``topic`` from the next :meth:`discover` on (``type_name`` as for :meth:`subscribe`)."""
        with self._lock:
            self.wanted.setdefault(topic, type_name)

    def subscribe_all(self, exclude: Sequence[str] = DEFAULT_EXCLUDE) -> None:
        """Record every (non-hidden) topic of the graph but ``exclude``, from the next :meth:`discover` on
        (the discovery timer's first tick): subscribing to a graph's topics can take seconds on a loaded
        machine, and the caller may want it done where a stop request is heard."""
        self.record_all = True
        self.excluded = set(exclude)

    def discover(self) -> None:
        """Subscribe to wanted topics whose publishers have appeared.

        Failures (unknown type, type conflict) are logged once per topic and
        that topic is skipped from then on.
        """
        with self._lock:
            if self.record_all:
                for topic, _types in self.node.get_topic_names_and_types():
                    if not is_hidden(topic) and not is_excluded(topic, self.excluded):
                        self.wanted.setdefault(topic, None)
            for topic in self._subscriptions:  # only needed where rclpy does not name publishers (Jazzy)
                self.deliveries.publishers_seen(topic, self.node.count_publishers(topic))
            for topic in self.wanted.keys() - self._subscriptions.keys() - self._failed:
                try:
                    self._try_subscribe(topic)
                except BagRecordingError as err:
                    self._failed.add(topic)
                    self.node.get_logger().error(f'Not recording {topic}: {err}')

    def start_discovery(self, period_s: float, flush_period_s: float = 1.0) -> None:
        """Call :meth:`discover` every ``period_s`` seconds on the node's executor (every
        FIRST_DISCOVERY_PERIOD_S for the first FIRST_DISCOVERY_S, where that is shorter), and put what was
        recorded on disk every ``flush_period_s`` (a recorder killed loses at most that much)."""
        if self._discovery_timer is None:
            fast_until = time.monotonic() + FIRST_DISCOVERY_S
            fast = period_s > FIRST_DISCOVERY_PERIOD_S

            def tick() -> None:
                nonlocal fast
                self.discover()
                if fast and time.monotonic() >= fast_until and self._discovery_timer is not None:
                    fast = False
                    self._discovery_timer.timer_period_ns = int(period_s * 1e9)

            self._discovery_timer = self.node.create_timer(min(period_s, FIRST_DISCOVERY_PERIOD_S), tick)
            self._flush_timer = self.node.create_timer(flush_period_s, self.writer.flush)

    def close(self) -> None:
        """Stop discovery, destroy the subscriptions, then close the bag (idempotent)."""
        with self._lock:
            if self._discovery_timer is not None:
                self.node.destroy_timer(self._discovery_timer)
                self.node.destroy_timer(self._flush_timer)
                self._discovery_timer = None
            for subscription in self._subscriptions.values():
                self.node.destroy_subscription(subscription)
            self._subscriptions.clear()
        self.writer.close()

    def _try_subscribe(self, topic: str) -> bool:
        """Subscribe to ``topic`` if its publishers are known (caller holds the lock)."""
        if topic in self._subscriptions:
            return True
        publishers = self.node.get_publishers_info_by_topic(topic)
        if not publishers:
            return False
        published = sorted({p.topic_type for p in publishers})
        wanted = self.wanted.get(topic)
        type_name = normalize_type_name(wanted) if wanted else published[0]
        if published != [type_name]:
            msg = f'topic {topic!r} is published as {published}, expected only {type_name!r}'
            raise BagRecordingError(msg)
        message_type = message_class(type_name)
        handle = self.writer.add_topic(
            topic, type_name, offered_qos=[bag_qos(p.qos_profile) for p in publishers]
        )
        self._check_type_hash(handle, publishers)
        if type_name in EVERY_SAMPLE_TYPES:  # every seq is sent; the nodes' answers skip by design
            self.sequences.watch(topic, self.writer.types.typestore, type_name)
        self._subscriptions[topic] = self.node.create_subscription(
            message_type,
            topic,
            (functools.partial(self._on_message, handle) if self.message_info
             else functools.partial(self._on_message_without_info, handle)),
            subscription_qos(publishers, self.queue_depth),
            raw=True,
        )
        self.deliveries.publishers_seen(topic, len(publishers))
        self.node.get_logger().info(f'Recording {topic} [{type_name}]')
        return True

    def _check_type_hash(
        self, handle: TopicHandle, publishers: Iterable[TopicEndpointInfo]
    ) -> None:
        """Warn if a publisher's type hash differs from the embedded definition's."""
        announced = {str(p.topic_type_hash) for p in publishers}
        differing = {h for h in announced if h.startswith('RIHS01_') and h != handle.type_hash}
        if differing:
            self.node.get_logger().warning(
                f'{handle.topic}: publishers announce type hash {sorted(differing)} but the '
                f'definition embedded for {handle.type_name} hashes to {handle.type_hash}; '
                'readers may decode it wrongly'
            )

    def _on_message(self, handle: TopicHandle, data: bytes, info: Mapping[str, Any] | None) -> None:
        """Write one raw message and then what else its subscription holds (:meth:`_take_queued`).

        ``info`` has no default on purpose: rclpy passes the message info only
        to a callback that cannot be called with the message alone.
        """
        if self._record(handle, data, info):
            self._take_queued(handle)

    def _take_queued(self, handle: TopicHandle) -> None:
        """Write up to :data:`TAKE_BATCH` more messages queued on ``handle``'s subscription, taken here.

        Why: an executor pass (rclpy rebuilds and waits on the wait set of every subscription, timer,
        service and event) costs more than writing a message, and it hands over one message per
        subscription; with :data:`GATHER_S` this takes the messages that gathered meanwhile. Only with
        message info (the standard executors): the EventsExecutor counts the messages it was told of
        and would look for these.
        """
        subscription = self._subscriptions.get(handle.topic)
        if subscription is None:
            return
        try:
            with subscription.handle:
                for _ in range(TAKE_BATCH):
                    taken = subscription.handle.take_message(subscription.msg_type, subscription.raw)
                    if taken is None or not self._record(handle, *taken):
                        return
        except InvalidHandle:  # destroyed by close() in another thread (a multi-threaded executor)
            return

    def _record(self, handle: TopicHandle, data: bytes, info: Mapping[str, Any] | None) -> bool:
        """Write one raw message, stamped with the receive time; account for its sequence numbers.

        Returns:
            Whether the bag took it (False: the bag is closed, the message counted as dropped).
        """
        try:
            self.writer.write(handle, self._receive_time(handle.topic, info), data)
        except BagClosedError:
            self.dropped_after_close += 1
            return False
        self.sequences.add(handle.topic, data)
        self.deliveries.add(handle.topic, info)
        return True

    def _receive_time(self, topic: str, info: Mapping[str, Any] | None) -> int:
        """The message's receive time [ns]: while the node's clock is system time, when DDS received it (its
        info's ``received_timestamp``), or 1 ns after the topic's previous stamp where that is later (DDS
        hands over the messages of several publishers of one topic, /rosout, in an order their receive
        times can contradict by a fraction of a millisecond, and a bag's stamps rise in its storage
        order); else (simulated time, or no receive time from the middleware) the node clock's time now."""
        clock = self._clock
        received = info.get('received_timestamp') if info else None
        if not (isinstance(received, int) and received > 0) or getattr(clock, 'ros_time_is_active', False):
            return clock.now().nanoseconds
        stamp = self._last_stamp[topic] = max(received, self._last_stamp.get(topic, -1) + 1)
        return stamp

    def _on_message_without_info(self, handle: TopicHandle, data: bytes) -> None:
        self._record(handle, data, None)

    def loss_report(self) -> tuple[int, list[str]]:
        """Messages the recorder lost (DDS numbers), one line per topic and check, and a verdict
        (:func:`~worm_rig_driver.recording.recorder.loss_report`)."""
        return loss_report(self.deliveries, self.sequences, self.dropped_after_close)


class RecorderNode(Node):
    """Node ``recorder``: a :class:`TopicRecorder` configured from parameters."""

    def __init__(self) -> None:
        """Declare parameters, open the bag and start discovery.

        Raises:
            BagRecordingError: Bad parameters or the bag cannot be created.

        """
        super().__init__('recorder')
        output: str = self._parameter(
            'output', '', 'Bag directory to create (must not exist; a bag left by a killed recorder: beside it, '
            '<output>.1, .2, ...); empty: rosbag2_<date-time>'
        )
        storage: str = self._parameter(
            'storage', 'mcap', 'Storage plugin of the bag',
            additional_constraints=f'one of {sorted(STORAGES)}',
        )
        compression: str = self._parameter(
            'compression', 'none', 'Chunk compression of an MCAP bag',
            additional_constraints=f'one of {list(COMPRESSIONS)}; zstd with storage mcap only',
        )
        topics: list[str] | None = self._parameter(
            'topics', Parameter.Type.STRING_ARRAY,
            'Topics to record; unset or empty: all non-hidden ones, as they appear',
        )
        exclude: list[str] = self._parameter(
            'exclude', list(DEFAULT_EXCLUDE),
            'Topics left out when recording every topic (relative: in any namespace; rig/sample: a rig\'s '
            'per-sample copy of its rig/samples)',
        )
        period: float = self._parameter(
            'discovery_period', 1.0, f'[s] period of the graph search for publishers and new topics (every '
            f'{FIRST_DISCOVERY_PERIOD_S:g} s for the first {FIRST_DISCOVERY_S:g} s)',
            floating_point_range=[FloatingPointRange(from_value=0.05, to_value=60.0)],
        )
        depth: int = self._parameter(
            'queue_depth', DEFAULT_QUEUE_DEPTH, '[messages] KEEP_LAST depth of every subscription',
            integer_range=[IntegerRange(from_value=1, to_value=1_000_000, step=1)],
        )
        for topic in [*(topics or []), *exclude]:  # before the bag exists: a refusal leaves nothing behind
            check_topic_name(topic)
        for name, value, known in (('storage', storage, sorted(STORAGES)), ('compression', compression,
                                                                            list(COMPRESSIONS))):
            if value not in known:
                raise ValueError(f'parameter {name}: {value!r} is not one of {", ".join(known)}')
        path, moved = bag_folder(output)  # beside a bag this recorder was writing when it was killed
        check_output(path, folder=True, option='parameter output')  # a new folder: never over anything
        writer = BagWriter(path, storage, compression=compression)
        try:
            self._held: int | None = hold(path)  # while it records: not taken for a cut-off bag
        except OSError as err:
            writer.close()
            raise BagRecordingError(f'Cannot lock bag {path}: {err}') from err
        self.recorder = TopicRecorder(self, writer, queue_depth=depth)
        zstd = ', zstd chunks' if compression == 'zstd' else ''
        self.get_logger().info(f'Recording into {path} ({storage}{zstd})' + (f': {moved}' if moved else ''))
        # Subscribed on the executor by discovery, not here: with twenty topics on a loaded machine that took
        # 13 s, and a stop signal during start ends the process at once, leaving the bag unclosed.
        if topics:
            for topic in topics:
                self.recorder.want(self.resolve_topic_name(topic))  # a bag holds full names
        else:
            self.recorder.subscribe_all(exclude)
        self.recorder.start_discovery(period)

    def _parameter(
        self, name: str, default: Any, description: str, **constraints: Any
    ) -> Any:
        """Declare a read-only parameter and return its value (None if unset).

        Args:
            name: Parameter name.
            default: Default value, or a ``Parameter.Type`` for "unset".
            description: Meaning, with the unit in brackets.
            constraints: Further ``ParameterDescriptor`` fields (ranges, ...).

        """
        descriptor = ParameterDescriptor(description=description, read_only=True, **constraints)
        return self.declare_parameter(name, default, descriptor).value

    def close(self) -> None:
        """Close the bag, let go of its folder and log what the bag holds."""
        try:
            self.recorder.close()
        finally:
            if self._held is not None:
                os.close(self._held)
                self._held = None
        counts = self.recorder.counts
        summary = ', '.join(f'{topic}: {n}' for topic, n in sorted(counts.items())) or 'no topics'
        self.get_logger().info(
            f'Closed bag {self.recorder.writer.path}: {sum(counts.values())} messages ({summary})'
        )
        lost, lines = self.recorder.loss_report()
        for line in lines:
            (self.get_logger().warning if lost else self.get_logger().info)(line)


def drain(executor: Executor, recorder: TopicRecorder) -> None:
    """Spin until the subscriptions' queues are written out.

    Messages DDS has delivered before the stop signal sit in the
    subscriptions' queues (up to ``queue_depth`` each); write them rather
    than lose them. Stops after :data:`DRAIN_QUIET_S` without a new message,
    or after :data:`DRAIN_LIMIT_S` if the topics keep streaming.
    """
    deadline = time.monotonic() + DRAIN_LIMIT_S
    written = sum(recorder.counts.values())
    last_change = time.monotonic()
    while (now := time.monotonic()) < deadline and now - last_change < DRAIN_QUIET_S:
        executor.spin_once(timeout_sec=DRAIN_QUIET_S / 4)
        if (total := sum(recorder.counts.values())) != written:
            written, last_change = total, time.monotonic()


def main(args: list[str] | None = None) -> int:
    """Run the recorder until SIGINT/SIGTERM; return the exit code.

    The executor spins in this (the main) thread and rclpy's own signal
    handlers are off, so a signal only sets a flag: the loop ends, the queued
    messages are written (:func:`drain`), the bag is closed, the node
    destroyed and rclpy shut down, with no executor thread alive at exit
    (which would abort the process). Exit codes: 0 recorded, 2 bad parameters
    or a bag that may not be created (nothing is left behind), 1 the bag failed
    while recording, 130 interrupted while starting.
    """
    given = sys.argv if args is None else list(args)
    if wants_help(given[1:]):  # before rclpy.init: no context, no DDS, no bag
        print(help_text([RecorderNode], 'recorder'))
        return 0
    refused = start_problem('recorder', given[1:], [RecorderNode])
    if refused is not None:
        return refused
    stop = threading.Event()

    def interrupt(signum: int, _frame: FrameType | None) -> None:
        raise KeyboardInterrupt(f'signal {signum}')

    def request_stop(signum: int, _frame: FrameType | None) -> None:
        stop.set()

    for signum in STOP_SIGNALS:  # while starting, a signal ends it at once
        signal.signal(signum, interrupt)
    refused = init_rclpy('recorder', args)
    if refused is not None:
        return refused
    executor = SingleThreadedExecutor()
    node: RecorderNode | None = None
    code, recording = 0, False
    try:
        node = RecorderNode()
        executor.add_node(node)
        check_undeclared([node], wildcard_names(given[1:]))
        for signum in STOP_SIGNALS:
            signal.signal(signum, request_stop)
        freeze_built_objects()  # a full collection would stall the 1 kHz reader for tens of ms
        recording = True
        while not stop.is_set():
            executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
            time.sleep(GATHER_S)  # messages gather meanwhile: the next pass takes several per subscription
        drain(executor, node.recorder)
    except KeyboardInterrupt:
        print('recorder: interrupted', file=sys.stderr)
        code = 130
    except ParameterException as err:
        print(f'recorder: {parameter_problem(err)}', file=sys.stderr)
        code = 2
    except (BagRecordingError, ValueError) as err:  # refused at start (a bag error later is exit 1, below)
        print(f'recorder: {one_line(err)}', file=sys.stderr)
        code = 1 if recording else 2
    finally:
        for signum in STOP_SIGNALS:
            signal.signal(signum, request_stop)
        executor.shutdown()
        if node is not None:
            try:
                node.close()
            except BagRecordingError as err:
                print(f'recorder: {err}', file=sys.stderr)
                code = 1
            if code == 2:  # refused: the bag it had opened holds nothing of the user's
                shutil.rmtree(node.recorder.writer.path, ignore_errors=True)
        with deadline(code):  # the bag is closed: a middleware hang must not keep the process alive
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
