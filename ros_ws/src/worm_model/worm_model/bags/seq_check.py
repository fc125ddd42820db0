"""Sequence numbers of recorded streams: what was lost, told from the ``seq`` field (no rclpy).

Our streams (``RigSample``, ``GearboxForces``, ``TorqueEstimate``,
``SimTruth``) start with ``std_msgs/Header header`` followed by ``uint64
seq``, the rig's sample counter; the batches (``RigSamples``, ``SimTruths``)
with ``Header header; uint64 first_seq; float64 sample_period`` and one array
per field (seqs ``first_seq`` on, one per element). A recorder (or a bag
check) reads ``seq`` straight out of the CDR bytes, without decoding the
message, and counts:

* lost: the seqs missing between the first and the last one seen (a gap);
* repeated: a seq not above the previous one (duplicate or reordered).

A gap in ``seq`` of a stream a node derives from samples (estimates,
forces) may also be a sample that node never got. What the *recorder* lost
is told by :class:`DeliveryCheck` instead: the DDS publication sequence
number each publisher (DataWriter) stamps on every message it writes, which
rclpy hands to a subscription callback taking a message info.

Messages published after the last one received cannot show as a gap; the
publisher's own count (the bench compares it) closes that hole.
"""

from __future__ import annotations

import struct
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Final, cast

from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

__all__ = ['DeliveryCheck', 'SequenceTracker', 'StreamCheck', 'check_messages', 'header_seq', 'header_seq_run',
           'seq_reader']

SEQ_FIELD: Final = ('seq', (Nodetype.BASE, ('uint64', 0)))
FIRST_SEQ_FIELD: Final = ('first_seq', (Nodetype.BASE, ('uint64', 0)))
PERIOD_FIELD: Final = ('sample_period', (Nodetype.BASE, ('float64', 0)))
HEADER_FIELD: Final = ('header', (Nodetype.NAME, 'std_msgs/msg/Header'))
MAX_GAPS_KEPT: Final[int] = 20
#: Gaps (by the step known when they came) remembered, to be re-judged by the final step.
MAX_GAP_CANDIDATES: Final[int] = 10000
UNNAMED: Final[bytes] = b'<unnamed>'
"""DeliveryCheck's key for a topic's only publisher when rclpy does not name it (no ``publisher_gid``)."""


def header_seq(data: bytes | memoryview) -> int:
    """``seq`` of a CDR message laid out ``Header header; uint64 seq; ...``.

    CDR: 4-byte encapsulation header (byte 1: 1 = little endian), then
    ``int32 sec``, ``uint32 nanosec``, ``uint32`` length of ``frame_id``
    (with its NUL) and its bytes, then ``seq`` aligned to 8 bytes from the
    start of the payload.

    Raises:
        struct.error: The bytes are too short for this layout.

    """
    order = '<' if data[1] == 1 else '>'
    (length,) = struct.unpack_from(f'{order}I', data, 12)
    offset = (12 + length + 7) & ~7
    (seq,) = struct.unpack_from(f'{order}Q', data, 4 + offset)
    return int(seq)


def header_seq_run(data: bytes | memoryview) -> tuple[int, int]:
    """(first seq, sample count) of a CDR batch laid out ``Header header; uint64 first_seq;
    float64 sample_period; <T>[] first_field; ...`` (worm_msgs/RigSamples, SimTruths).

    The count is the length of the first sequence field, a uint32 right after
    ``sample_period`` (aligned to 4, which it already is).

    Raises:
        struct.error: The bytes are too short for this layout.

    """
    order = '<' if data[1] == 1 else '>'
    (length,) = struct.unpack_from(f'{order}I', data, 12)
    offset = (12 + length + 7) & ~7
    first, _period, count = struct.unpack_from(f'{order}QdI', data, 4 + offset)
    return int(first), int(count)


def _single(data: bytes | memoryview) -> tuple[int, int]:
    return header_seq(data), 1


def seq_reader(typestore: Typestore, type_name: str) -> Callable[[bytes | memoryview], tuple[int, int]] | None:
    """A reader of (first seq, count) if ``type_name`` carries sample seqs, else None.

    ``Header header; uint64 seq; ...``: one seq per message (count 1); ``Header header;
    uint64 first_seq; float64 sample_period; <T>[] ...``: a batch of consecutive seqs.
    """
    fields = typestore.fielddefs.get(type_name, ((), []))[1]
    if len(fields) >= 2 and tuple(fields[0]) == HEADER_FIELD and tuple(fields[1]) == SEQ_FIELD:
        return _single
    if (len(fields) >= 4 and tuple(fields[0]) == HEADER_FIELD and tuple(fields[1]) == FIRST_SEQ_FIELD
            and tuple(fields[2]) == PERIOD_FIELD and fields[3][1][0] == Nodetype.SEQUENCE):
        return header_seq_run
    return None


@dataclass
class SequenceTracker:
    """Counts of one stream's sequence numbers, fed in receive order.

    A stream need not carry every seq: estimator_node publishes one estimate per batch of 5
    samples, model_node one force per 20 ms. The stream's step is the most common increment
    between successive messages (ties: the smaller), and a message is lost where an increment
    spans more than one step (rounded: timer jitter, 15 or 25 in a stream of 20s, is no loss).
    """

    count: int = 0
    first: int | None = None
    last: int | None = None
    repeated: int = 0
    increments: Counter[int] = field(default_factory=Counter)
    """How often each increment between successive messages occurred."""
    _candidates: list[tuple[int, int]] = field(default_factory=list)
    _mode: tuple[int, int] = (0, 0)  # (count, -increment) of the most common increment so far

    def add(self, seq: int, count: int = 1) -> None:
        """Account for ``count`` received consecutive seqs from ``seq`` on (a message, or a batch)."""
        if count < 1:
            return
        self.count += count
        last = seq + count - 1
        if self.last is None:
            self.first, self.last = seq, last
            return
        if seq <= self.last:
            self.repeated += count
            return
        step = seq - self.last
        self.increments[step] += 1
        self._mode = max(self._mode, (self.increments[step], -step))
        # a gap by the step known so far (re-judged by the final step in gaps)
        if step > 1 and 2 * step > 3 * -self._mode[1] and len(self._candidates) < MAX_GAP_CANDIDATES:
            self._candidates.append((self.last, seq))
        self.last = last

    @property
    def step(self) -> int:
        """The stream's seq step (1 until two messages were seen)."""
        return -self._mode[1] if self.increments else 1

    def _missing(self, increment: int, step: int) -> int:
        return max(round(increment / step) - 1, 0)

    @property
    def lost(self) -> int:
        """Messages missing between the first and the last one seen, in steps of :attr:`step`."""
        step = self.step
        return sum(n * self._missing(d, step) for d, n in self.increments.items())

    @property
    def gaps(self) -> list[tuple[int, int]]:
        """The first :data:`MAX_GAPS_KEPT` gaps as (first missing, last missing) seq."""
        step = self.step
        return [(a + step, b - step) if step > 1 else (a + 1, b - 1)
                for a, b in self._candidates if self._missing(b - a, step)][:MAX_GAPS_KEPT]

    def summary(self) -> str:
        """One line: range (and step), lost, repeated."""
        if self.first is None:
            return 'no messages'
        step = self.step
        every = f' (every {step})' if step > 1 else ''
        lost = self.lost
        text = f'seq {self.first}..{self.last}{every}: {self.count} received, lost {lost}'
        if self.repeated:
            text += f', {self.repeated} repeated or out of order'
        if gaps := self.gaps:
            text += ', gaps ' + ', '.join(f'{a}' if a == b else f'{a}-{b}' for a, b in gaps)
            if len(gaps) == MAX_GAPS_KEPT:
                text += ', ...'
        return text


class StreamCheck:
    """Trackers for every topic whose type carries a ``seq`` (others are skipped)."""

    def __init__(self) -> None:
        self.trackers: dict[str, SequenceTracker] = {}
        self._readers: dict[str, Callable[[bytes | memoryview], tuple[int, int]] | None] = {}
        self.unreadable: dict[str, int] = {}
        """Messages per topic too short for the layout (counted, not tracked)."""

    def watch(self, topic: str, typestore: Typestore, type_name: str) -> bool:
        """Track ``topic`` if its type has a ``seq``; returns whether it is tracked."""
        reader = seq_reader(typestore, type_name)
        self._readers[topic] = reader
        if reader is not None:
            self.trackers.setdefault(topic, SequenceTracker())
        return reader is not None

    def add(self, topic: str, data: bytes | memoryview) -> None:
        """Account for one raw message of ``topic`` (no-op for untracked topics)."""
        reader = self._readers.get(topic)
        if reader is None:
            return
        try:
            seq, count = reader(data)
        except (struct.error, IndexError):
            self.unreadable[topic] = self.unreadable.get(topic, 0) + 1
            return
        self.trackers[topic].add(seq, count)

    @property
    def lost(self) -> int:
        """Messages lost over all tracked topics."""
        return sum(t.lost for t in self.trackers.values())

    def report(self) -> list[str]:
        """One line per tracked topic, sorted by topic."""
        lines = [f'{topic}: {tracker.summary()}' for topic, tracker in sorted(self.trackers.items())]
        lines += [f'{topic}: {n} messages too short to hold a seq'
                  for topic, n in sorted(self.unreadable.items())]
        return lines


def check_messages(messages: Iterable[tuple[str, bytes]], types: Mapping[str, tuple[Typestore, str]]
                   ) -> StreamCheck:
    """Run a :class:`StreamCheck` over ``(topic, cdr)`` pairs; ``types``: topic -> (store, type)."""
    check = StreamCheck()
    for topic, (store, type_name) in types.items():
        check.watch(topic, store, type_name)
    for topic, data in messages:
        check.add(topic, data)
    return check


class DeliveryCheck:
    """Gaps in the DDS publication sequence numbers, per topic and publisher.

    Fed with rclpy's message info (``publication_sequence_number``,
    ``publisher_gid``); a message without them (an RMW that does not report
    them) is counted as untracked.

    rclpy before Kilted (Jazzy's 7.x) hands over the number but no
    ``publisher_gid``. Such a message is tracked as from the topic's only
    publisher while :meth:`publishers_seen` has never been told of more than one
    on that topic; once it is, the topic's unnamed numbers (interleaved from
    several publishers, so their gaps mean nothing) become untracked.
    """

    def __init__(self) -> None:
        self.trackers: dict[str, dict[bytes, SequenceTracker]] = {}
        self.untracked: dict[str, int] = {}
        self.most_publishers: dict[str, int] = {}
        """Topic -> most publishers the caller has seen on it at once."""

    def publishers_seen(self, topic: str, count: int) -> None:
        """Tell how many publishers ``topic`` has now (for messages whose publisher is not named)."""
        self.most_publishers[topic] = most = max(count, self.most_publishers.get(topic, 0))
        unnamed = self.trackers.get(topic, {}).get(UNNAMED)
        if most > 1 and unnamed is not None:
            del self.trackers[topic][UNNAMED]
            if not self.trackers[topic]:
                del self.trackers[topic]
            self.untracked[topic] = self.untracked.get(topic, 0) + unnamed.count

    def add(self, topic: str, info: Mapping[str, object] | None) -> None:
        """Account for one message of ``topic`` with its message info."""
        number = info.get('publication_sequence_number') if info else None
        gid = info.get('publisher_gid') if info else None
        if isinstance(number, int) and gid is None and self.most_publishers.get(topic) == 1:
            key = UNNAMED  # rclpy < Kilted: the topic's only publisher
        elif not isinstance(number, int) or not isinstance(gid, Mapping):
            self.untracked[topic] = self.untracked.get(topic, 0) + 1
            return
        else:
            key = bytes(cast('bytes', gid.get('data', b'')))
        self.trackers.setdefault(topic, {}).setdefault(key, SequenceTracker()).add(number)

    @property
    def lost(self) -> int:
        """Messages missing between the first and last received of every publisher."""
        return sum(t.lost for per_topic in self.trackers.values() for t in per_topic.values())

    def report(self) -> list[str]:
        """One line per topic: publishers, received, lost; and one per topic whose publishers were seen but
        sent nothing (a publisher that has nothing to say, or a subscription the middleware matched and never
        fed: the report says which topics, the reader judges which)."""
        lines = []
        for topic, publishers in sorted(self.trackers.items()):
            received = sum(t.count for t in publishers.values())
            lost = sum(t.lost for t in publishers.values())
            unnamed = ' (not named by this rclpy: the only one the topic had)' if UNNAMED in publishers else ''
            lines.append(f'{topic}: {received} received from {len(publishers)} publisher(s), '
                         f'{lost} missing in their DDS sequence numbers{unnamed}')
        lines += [f'{topic}: {n} messages without DDS sequence numbers (not checked)'
                  for topic, n in sorted(self.untracked.items())]
        lines += [f'{topic}: nothing received from its {n} publisher(s)' for topic, n in sorted(
            self.most_publishers.items()) if n > 0 and topic not in self.trackers and topic not in self.untracked]
        return lines
