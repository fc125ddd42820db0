"""The rig's sample streams as recorded: one sample per message, or batches of consecutive samples.

A rig publishes the same samples two ways (worm_rig_driver.nodes.rig_topics):
``worm_msgs/msg/RigSamples`` on rig/samples (``batch_size`` consecutive samples
per message, arrays per field, the graph's stream) and ``worm_msgs/msg/RigSample``
on rig/sample (one by one, while someone subscribes): names relative to the rig
node's namespace, /rig/samples and /rig/sample in a recording of a graph without one. Readers of recordings
(``bag export``, ``replay``, ``residuals``) take either through :func:`samples_of`,
which turns a message of either type into RigSample-like records in sample order.
No rclpy: works on the dataclasses the bag reader decodes and on rclpy messages alike.

The simulator's ground truth comes batched the same way: ``worm_msgs/msg/SimTruths`` on
/sim/truth_samples (every sample, aligned with /rig/samples' batches; :func:`batch_stamps_ns`
gives its samples' stamps) beside ``worm_msgs/msg/SimTruth`` on /sim/truth (every
``channel_decimation``-th sample).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Final, NamedTuple

RIG_SAMPLE_TYPE: Final[str] = "worm_msgs/msg/RigSample"
RIG_SAMPLES_TYPE: Final[str] = "worm_msgs/msg/RigSamples"
#: the types a sample stream may have, preferred first
SAMPLE_TYPES: Final[tuple[str, ...]] = (RIG_SAMPLES_TYPE, RIG_SAMPLE_TYPE)
#: where the rigs publish them, preferred first: relative names, resolved in the rig node's namespace
#: (``recorded_name`` gives what a recording of a graph in a namespace holds)
SAMPLE_TOPICS: Final[tuple[str, ...]] = ("rig/samples", "rig/sample")
SIM_TRUTHS_TYPE: Final[str] = "worm_msgs/msg/SimTruths"
#: where sim_node publishes every sample's ground truth (SimTruths batches), relative like SAMPLE_TOPICS
SIM_TRUTHS_TOPIC: Final[str] = "sim/truth_samples"
#: the streams that carry every sample's seq (a gap is a loss): the rig's samples and the simulator's truth
EVERY_SAMPLE_TYPES: Final[tuple[str, ...]] = (*SAMPLE_TYPES, SIM_TRUTHS_TYPE)
#: SimTruths' per-sample fields, in message order (SimTruth's fields of the same names)
TRUTH_FIELDS: Final[tuple[str, ...]] = (
    "tau_load", "tau_in", "omega_worm", "current_drive", "normal_force", "friction_force", "mu", "mode", "flank")
#: the per-sample fields of both types (RigSample's, header and seq aside)
FIELDS: Final[tuple[str, ...]] = (
    "current_drive", "current_load_1", "current_load_2", "omega_worm", "omega_gear", "theta_worm", "theta_gear",
    "count_drive", "count_load_1", "count_load_2", "voltage_drive", "tau_load", "status")
NS_PER_S: Final[int] = 1_000_000_000


def recorded_name(topic: str, namespace: str = "/") -> str:
    """The full name of a node's ``topic`` (relative, e.g. "rig/samples") in ``namespace`` ("/": none), as a
    recording of the graph names it: ``recorded_name("rig/samples")`` is "/rig/samples",
    ``recorded_name("rig/samples", "/arm/joint2")`` "/arm/joint2/rig/samples". An absolute topic stays as it is."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


@dataclass(frozen=True)
class Stamp:
    """builtin_interfaces/Time."""

    sec: int
    nanosec: int


@dataclass(frozen=True)
class Header:
    """std_msgs/Header."""

    stamp: Stamp
    frame_id: str


class RigSample(NamedTuple):
    """One rig sample in SI units, the one record of a sample on its way through the product: the rig's
    link and the simulator make it, :func:`unbatch` reads it out of a RigSamples message, the rig's topics
    publish it. Its fields are worm_msgs/RigSample's (``header`` is built from ``stamp_ns`` and
    ``frame_id`` when asked for), with the speed command in force (``command_seq``, 0 when unknown).

    Signs: speeds and angles positive in the worm's positive rotation, ``tau_load`` [N m] positive where
    it opposes positive rotation of the gear (worm_msgs/RigSample).
    """

    seq: int  #: sample number (the firmware's tick: consecutive samples differ by the stream's period in ticks)
    stamp_ns: int  #: [ns] host time of the sampling instant
    current_drive: float  #: [A]
    current_load_1: float  #: [A]
    current_load_2: float  #: [A]
    omega_worm: float  #: [rad/s]
    omega_gear: float  #: [rad/s]
    theta_worm: float  #: [rad]
    theta_gear: float  #: [rad]
    count_drive: int  #: [count] raw int32
    count_load_1: int  #: [count]
    count_load_2: int  #: [count]
    voltage_drive: float  #: [V]
    tau_load: float  #: [N m]
    status: int  #: RigSample.STATUS_* bits
    command_seq: int = 0  #: source seq of the speed command in force (0: unknown)
    frame_id: str = ""

    @property
    def header(self) -> Header:
        """std_msgs/Header of this sample, as worm_msgs/RigSample carries it."""
        return Header(Stamp(self.stamp_ns // NS_PER_S, self.stamp_ns % NS_PER_S), self.frame_id)


def stamp_ns(stamp: Any) -> int:
    """A builtin_interfaces/Time as integer nanoseconds."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def batch_problem(batch: Any, fields: tuple[str, ...] = FIELDS) -> str:
    """Why a RigSamples message cannot be used ('' if it can): ``fields`` (and ``command_seq``,
    if present and not empty) must all hold one value per sample."""
    lengths = {name: len(getattr(batch, name)) for name in fields}
    commands = len(getattr(batch, "command_seq", ()))
    if commands:
        lengths["command_seq"] = commands
    if len(set(lengths.values())) > 1:
        return "fields of unequal length: " + ", ".join(f"{name}[{n}]" for name, n in lengths.items())
    if not (batch.sample_period > 0):
        return f"sample_period={batch.sample_period} is not > 0"
    return ""


def batch_stamps_ns(batch: Any, n: int) -> list[int]:
    """Stamps [ns] of the ``n`` samples of a batch (RigSamples, SimTruths): sample k is stamped
    header.stamp + k * sample_period."""
    first = stamp_ns(batch.header.stamp)
    period_ns = batch.sample_period * NS_PER_S
    return [first + int(round(k * period_ns)) for k in range(n)]


def unbatch(batch: Any) -> list[RigSample]:
    """The samples of one RigSamples message, in order; sample k is stamped first + k * sample_period."""
    columns = [list(getattr(batch, name)) for name in FIELDS]
    commands = list(getattr(batch, "command_seq", ())) or [0] * len(columns[0])
    stamps = batch_stamps_ns(batch, len(columns[0]))
    frame_id, first = batch.header.frame_id, int(batch.first_seq)
    return [RigSample(first + k, stamps[k], *values, frame_id) for k, values in enumerate(zip(*columns, commands))]


def samples_of(message: Any, type_name: str) -> list[Any]:
    """The samples a message of ``type_name`` (RigSample or RigSamples) carries, in order."""
    if type_name == RIG_SAMPLES_TYPE:
        return unbatch(message)
    if type_name == RIG_SAMPLE_TYPE:
        return [message]
    raise ValueError(f"{type_name} is not a sample stream (expected one of {SAMPLE_TYPES})")


def iter_samples(messages: Any, type_name: str) -> Iterator[Any]:
    """Every sample of a stream of messages of ``type_name``, in order."""
    for message in messages:
        yield from samples_of(message, type_name)


def command_latencies(samples: Iterator[Any]) -> list[int]:
    """Per speed command, the sample periods from the sample it was computed from to its effect.

    Read from the stream's own clock (``seq`` and ``command_seq`` of each sample,
    RigSamples' definition): a command computed from sample ``s`` first drives the
    period of sample ``k``; its latency is ``k - 1 - s`` periods (0: it drove the very
    next period). Commands are told apart by their source ``s``; samples without one
    (``command_seq`` 0) are skipped, and so is the command in force at the first sample:
    it may have driven periods before it (a window cut out of a longer run).
    """
    first_seen: dict[int, int] = {}
    in_force = None
    for sample in samples:
        source = int(sample.command_seq)
        if in_force is None:
            in_force = source
        if source and source != in_force and source not in first_seen:
            first_seen[source] = int(sample.seq)
    return [k - 1 - s for s, k in first_seen.items()]


def missing_seqs(seqs: Iterator[int]) -> int:
    """Samples missing between consecutive seqs of a stream (its gaps), in receive order."""
    lost, last = 0, None
    for seq in seqs:
        if last is not None and seq > last + 1:
            lost += seq - last - 1
        last = seq if last is None else max(last, seq)
    return lost


__all__ = ["EVERY_SAMPLE_TYPES", "FIELDS", "RIG_SAMPLES_TYPE", "RIG_SAMPLE_TYPE", "SAMPLE_TOPICS",
           "SAMPLE_TYPES", "SIM_TRUTHS_TOPIC", "recorded_name", "SIM_TRUTHS_TYPE", "TRUTH_FIELDS", "Header",
           "batch_problem", "batch_stamps_ns", "command_latencies", "missing_seqs",
           "RigSample", "Stamp", "iter_samples", "samples_of", "stamp_ns", "unbatch"]
