"""Bags of RigSample to and from rig data (the ``worm_rig_data`` CSV schema of worm_model.rig_data.schema).

The schema, :class:`~worm_model.rig_data.schema.MeasuredData`, the CSV reader and writer and
:class:`~worm_model.errors.RigDataError` are worm_model.rig_data.schema's; this module only
converts between them and rosbag2 bags.

:func:`bag_to_measured` reads a sample stream (``worm_msgs/msg/RigSamples`` batches or
``worm_msgs/msg/RigSample``, see :mod:`worm_model.rig_data.samples`), ``t`` counted
from the first sample's ``header.stamp``, ``current_load`` the sum of the two load
motors; :func:`measured_to_bag` writes one, ``header.stamp = start + t``, ``seq`` the
row index, ``current_load`` split equally over the two load motors, and channels
the data lacks set to NaN (counts to 0). :func:`bag_to_csv` and :func:`csv_to_bag`
are ``bag export`` and ``bag import``: as the CSV writer keeps every float exactly,
export -> import -> export gives the same file.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, Final

import numpy as np

from worm_model.rig_data.schema import REQUIRED_COLUMNS, MeasuredData, is_rig_csv, read_rig_csv, write_rig_csv
from worm_model.errors import RigDataError
from worm_model.rig_data.samples import SAMPLE_TOPICS, SAMPLE_TYPES, iter_samples, recorded_name
from worm_model.bags.reader import BagReader
from worm_model.files.writing import Output, atomic_dir, atomic_file
from worm_model.rig_data.plausibility import check_rig_data
from worm_model.bags.writer import BagWriter
from worm_model.bags.typestore import MessageTypes

__all__ = [
    'DEFAULT_TOPIC',
    'RIG_SAMPLE_TYPE',
    'bag_to_csv',
    'bag_to_measured',
    'csv_to_bag',
    'find_sample_topic',
    'measured_to_bag',
    'read_samples',
    'rig_samples',
    'samples_to_measured',
]

RIG_SAMPLE_TYPE: Final[str] = 'worm_msgs/msg/RigSample'
DEFAULT_TOPIC: Final[str] = '/rig/sample'
NS_PER_S: Final[int] = 1_000_000_000
#: the optional columns a RigSample carries (it has no temperature)
SAMPLE_OPTIONAL: Final[tuple[str, ...]] = ('voltage_drive', 'theta_gear', 'current_load')


def find_sample_topic(reader: BagReader, topic: str | None = None) -> str:
    """The sample stream to use: ``topic`` if given, else the only one (or /rig/samples, then /rig/sample).

    A stream is a ``worm_msgs/msg/RigSamples`` (batches) or ``worm_msgs/msg/RigSample`` topic
    (see :mod:`worm_model.rig_data.samples`).

    Raises:
        RigDataError: No such topic, not a sample stream, or several to choose from.

    """
    source = str(reader.path)
    if topic is not None:
        info = reader.topics.get(topic)
        if info is None:
            raise RigDataError(source, f'no topic {topic!r}; it has {sorted(reader.topics)}')
        if info.type not in SAMPLE_TYPES:
            raise RigDataError(source, f'topic {topic!r} is {info.type}, not one of {list(SAMPLE_TYPES)}')
        return topic
    candidates = sorted(n for n, i in reader.topics.items() if i.type in SAMPLE_TYPES)
    if not candidates:
        raise RigDataError(source, f'no sample stream ({" or ".join(SAMPLE_TYPES)}); it has {sorted(reader.topics)}')
    if len(candidates) > 1:
        for preferred in map(recorded_name, SAMPLE_TOPICS):  # a graph recorded without a namespace
            if preferred in candidates:
                return preferred
        raise RigDataError(source, f'several sample streams {candidates}; choose one')
    return candidates[0]


def read_samples(reader: BagReader, topic: str) -> Iterator[Any]:
    """Every sample of the stream ``topic`` (RigSample-like records, batches unpacked), in order."""
    return iter_samples((m.decoded for m in reader.messages([topic])), reader.topics[topic].type)


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * NS_PER_S + int(header.stamp.nanosec)


def samples_to_measured(samples: Iterable[Any], source: str = '<samples>') -> MeasuredData:
    """RigSample messages (any object with their fields) -> rig data, ``t`` from the first stamp.

    Samples with a non-finite required channel, or a stamp not after the
    previous one, are left out and counted in :attr:`MeasuredData.skipped`.

    Raises:
        RigDataError: No usable sample.

    """
    rows: dict[str, list[float]] = {c: [] for c in (*REQUIRED_COLUMNS, *SAMPLE_OPTIONAL)}
    skipped = {'non-finite': 0, 'not after the previous stamp': 0}
    first: int | None = None
    last: int | None = None
    for sample in samples:
        stamp = _stamp_ns(sample.header)
        required = (sample.current_drive, sample.omega_worm, sample.theta_worm, sample.tau_load)
        if not all(math.isfinite(v) for v in required):
            skipped['non-finite'] += 1
            continue
        if last is not None and stamp <= last:
            skipped['not after the previous stamp'] += 1
            continue
        first = stamp if first is None else first
        last = stamp
        rows['t'].append((stamp - first) / NS_PER_S)
        rows['current_drive'].append(sample.current_drive)
        rows['omega_worm'].append(sample.omega_worm)
        rows['theta_worm'].append(sample.theta_worm)
        rows['tau_load'].append(sample.tau_load)
        rows['voltage_drive'].append(sample.voltage_drive)
        rows['theta_gear'].append(sample.theta_gear)
        rows['current_load'].append(sample.current_load_1 + sample.current_load_2)
    if first is None:
        raise RigDataError(source, 'no usable RigSample (all non-finite or none at all)')
    columns = {c: np.asarray(v, dtype=float) for c, v in rows.items()}
    for name in SAMPLE_OPTIONAL:
        if np.all(np.isnan(columns[name])):
            del columns[name]  # all-NaN optional channel = absent, as an all-empty CSV column
    return MeasuredData(**columns, source=source, skipped={k: v for k, v in skipped.items() if v})


def bag_to_measured(path: Path | str, topic: str | None = None,
                    types: MessageTypes | None = None, allow_truncated: bool = False) -> MeasuredData:
    """Read the RigSample stream of a bag (see :func:`find_sample_topic`) as rig data.

    Args:
        allow_truncated: read storage files cut inside a record as far as they go
            (listed in :attr:`MeasuredData.damage`) instead of refusing them.

    Raises:
        RigDataError: No usable RigSample topic or sample.
        BagRecordingError: The bag cannot be read (or is truncated and allow_truncated is False).

    """
    with BagReader(path, types, allow_truncated=allow_truncated) as reader:
        name = find_sample_topic(reader, topic)
        data = samples_to_measured(read_samples(reader, name), f'{path}:{name}')
        data.damage = tuple(reader.damage)
        return data


def check_stamps(data: MeasuredData, start_ns: int) -> None:
    """Every ``start + t`` a time a bag can hold: 0 <= stamp < 2**31 s (int32 seconds, unsigned log time).

    Raises:
        RigDataError: the first sample outside, naming its line (CSV) or index and column ``t``.
    """
    if not len(data):
        return
    for i in (0, len(data) - 1):  # t increases strictly: the ends decide
        stamp = start_ns + round(float(data.t[i]) * NS_PER_S)
        if 0 <= stamp < 2**31 * NS_PER_S:
            continue
        when = f't = {float(data.t[i]):g} s with start {start_ns / NS_PER_S:g} s'
        why = ('is before 1970 (a bag stamp cannot be negative): give --start >= '
               f'{-float(data.t[0]):g} s' if stamp < 0 else 'is beyond 2038 (int32 seconds of builtin_interfaces/Time)')
        if data.lines is not None:
            raise RigDataError(data.source, f'{when} {why}', int(data.lines[i]), 't')
        raise RigDataError(data.source, f'sample {i}: {when} {why}', column='t')


def rig_samples(data: MeasuredData, types: MessageTypes, start_ns: int = 0,
                frame_id: str = 'rig') -> Iterator[tuple[int, bytes]]:
    """``(stamp_ns, cdr)`` of one RigSample per row (see the module docstring).

    Raises:
        RigDataError: A stamp does not fit ``builtin_interfaces/Time``.

    """
    store = types.typestore
    types.ensure(RIG_SAMPLE_TYPE)
    sample_cls = store.types[RIG_SAMPLE_TYPE]
    header_cls = store.types['std_msgs/msg/Header']
    time_cls = store.types['builtin_interfaces/msg/Time']
    nan = np.full(len(data), math.nan)
    optional = {c: nan if getattr(data, c) is None else getattr(data, c) for c in SAMPLE_OPTIONAL}
    check_stamps(data, start_ns)
    for i in range(len(data)):
        stamp = start_ns + round(float(data.t[i]) * NS_PER_S)
        sec, nanosec = divmod(stamp, NS_PER_S)
        half = float(optional['current_load'][i]) / 2.0
        sample = sample_cls(
            header=header_cls(stamp=time_cls(sec=sec, nanosec=nanosec), frame_id=frame_id),
            seq=i,
            current_drive=float(data.current_drive[i]),
            current_load_1=half,
            current_load_2=half,
            omega_worm=float(data.omega_worm[i]),
            omega_gear=math.nan,
            theta_worm=float(data.theta_worm[i]),
            theta_gear=float(optional['theta_gear'][i]),
            count_drive=0,
            count_load_1=0,
            count_load_2=0,
            voltage_drive=float(optional['voltage_drive'][i]),
            tau_load=float(data.tau_load[i]),
            status=0,
        )
        yield stamp, bytes(store.serialize_cdr(sample, RIG_SAMPLE_TYPE))


def measured_to_bag(data: MeasuredData, out: Path | str, storage: str = 'mcap',
                    topic: str = DEFAULT_TOPIC, start_ns: int = 0,
                    types: MessageTypes | None = None) -> int:
    """Write ``data`` as a bag of RigSample on ``topic``; returns the message count.

    Raises:
        RigDataError: A stamp does not fit ``builtin_interfaces/Time``.
        BagRecordingError: The bag cannot be created (e.g. ``out`` exists).

    """
    types = MessageTypes() if types is None else types
    with BagWriter(out, storage, types=types) as writer:
        handle = writer.add_topic(topic, RIG_SAMPLE_TYPE)
        for stamp, cdr in rig_samples(data, types, start_ns):
            writer.write(handle, stamp, cdr)
        return writer.counts[topic]


#: what ``bag export`` writes, and recognises as its own (a CSV in the worm_rig_data schema) for --force
EXPORT_OUTPUT: Final = Output("bag export", recognise=is_rig_csv)
#: what ``bag import`` writes: a bag folder with the marker naming it (what --force may replace)
IMPORT_OUTPUT: Final = Output("bag import")


def bag_to_csv(bag: Path | str, csv_path: Path | str, topic: str | None = None,
               allow_truncated: bool = False, force: bool = False) -> MeasuredData:
    """``bag export``: the bag's RigSample stream as a ``worm_rig_data`` CSV; returns what was written.

    The CSV is written to a temporary file beside ``csv_path`` and renamed at the end, under the output
    policy of worm_model.files.writing (``force``: an existing worm_rig_data CSV may be replaced; never the
    bag itself nor a file inside it).

    Raises:
        RigDataError: No usable RigSample topic or sample, or the CSV cannot be written.
        BagRecordingError: The bag cannot be read.

    """
    data = bag_to_measured(bag, topic, allow_truncated=allow_truncated)
    with atomic_file(csv_path, force, inputs=[bag], output=EXPORT_OUTPUT) as tmp:
        write_rig_csv(tmp, data)
    return data


def csv_to_bag(csv_path: Path | str, bag: Path | str, storage: str = 'mcap',
               topic: str = DEFAULT_TOPIC, start_ns: int = 0, rig: Any = None, force: bool = False) -> int:
    """``bag import``: a ``worm_rig_data`` CSV as a bag of RigSample; returns the message count.

    The CSV is read and checked whole first (every stamp a bag can hold; with ``rig``, its units against
    the rig as every reader of rig data checks them, worm_model.rig_data.plausibility), and the bag is
    written in a temporary folder beside
    ``bag`` and renamed at the end, so a bad file or a failed write leaves no bag (worm_model.files.writing:
    ``force`` replaces only a bag ``bag import`` wrote).

    Raises:
        RigDataError: A bad CSV (named by file, line and column), a stamp out of range, or a value
            outside the envelope.
        BagRecordingError: The bag cannot be created (e.g. ``bag`` exists).

    """
    data = read_rig_csv(csv_path)
    if rig is not None:
        check_rig_data(data, rig)
    check_stamps(data, start_ns)
    target = Path(bag)
    with atomic_dir(target, force, inputs=[csv_path], output=IMPORT_OUTPUT) as work:
        inner = work / target.name  # the writer names the storage files after the bag's folder
        n = measured_to_bag(data, inner, storage, topic, start_ns)
        for part in inner.iterdir():
            os.replace(part, work / part.name)
        inner.rmdir()
    return n
