"""Rig data as CSV (the residual analysis' schema), and bags of RigSample to and from it.

Schema ``worm_rig_data``: one header row of column names, then one row per
sample, comma separated, in any column order.

==================  =======  ====================================================
column              unit     meaning
==================  =======  ====================================================
``t``               s        sample time, strictly increasing (required)
``current_drive``   A        drive-motor armature current (required)
``omega_worm``      rad/s    worm speed, + is the reference rotation (required)
``theta_worm``      rad      worm angle, unwrapped (required)
``tau_load``        N m      known load torque on the gear shaft, + opposes +
                             rotation (required)
``voltage_drive``   V        mean drive-motor voltage (optional)
``theta_gear``      rad      gear angle, unwrapped, + with + worm rotation (optional)
``current_load``    A        load-motor current, both load motors summed (optional)
``temperature``     degC     oil or housing temperature (optional)
==================  =======  ====================================================

Required cells must be finite numbers; an optional cell may be empty (NaN).
Unknown columns are ignored. The same schema is read by
``worm_model.residuals.data``. Every problem raises :class:`RigCsvError`,
whose message names the file, the line (1 = the header) and the column:
``run.csv: line 17, column 'omega_worm': 'abc' is not a number``.

Bags: :func:`bag_to_trace` reads a ``worm_msgs/msg/RigSample`` stream,
``t`` counted from the first sample's ``header.stamp``;
:func:`trace_to_bag` writes one, ``header.stamp = start + t``, ``seq`` the
row index, ``current_load`` split equally over the two load motors, and
channels the CSV lacks set to NaN (counts to 0). Floats are written with
Python's shortest round-trip repr, so export -> import -> export gives the
same file.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from worm_rig_driver.bag_reader import BagReader
from worm_rig_driver.bag_recording import BagWriter
from worm_rig_driver.bag_types import MessageTypes

__all__ = [
    'OPTIONAL_COLUMNS',
    'REQUIRED_COLUMNS',
    'RIG_SAMPLE_TYPE',
    'RigCsvError',
    'RigTrace',
    'bag_to_measured',
    'bag_to_trace',
    'find_sample_topic',
    'read_rig_csv',
    'trace_to_bag',
    'write_rig_csv',
]

REQUIRED_COLUMNS: Final[dict[str, str]] = {
    't': 's',
    'current_drive': 'A',
    'omega_worm': 'rad/s',
    'theta_worm': 'rad',
    'tau_load': 'N m',
}
"""Required column -> unit, in the order written."""
OPTIONAL_COLUMNS: Final[dict[str, str]] = {
    'voltage_drive': 'V',
    'theta_gear': 'rad',
    'current_load': 'A',
    'temperature': 'degC',
}
"""Optional column -> unit, in the order written."""
RIG_SAMPLE_TYPE: Final[str] = 'worm_msgs/msg/RigSample'
DEFAULT_TOPIC: Final[str] = '/rig/sample'
NS_PER_S: Final[int] = 1_000_000_000


class RigCsvError(ValueError):
    """Bad rig data; the message names the file, line (1 = header) and column."""

    def __init__(self, source: str, problem: str, line: int = 0, column: str = '') -> None:
        """Record where the problem is and compose the message."""
        self.source = str(source)
        self.line = line
        self.column = column
        where = [f'line {line}'] if line else []
        where += [f'column {column!r}'] if column else []
        prefix = f'{self.source}: {", ".join(where)}' if where else self.source
        super().__init__(f'{prefix}: {problem}')


@dataclass
class RigTrace:
    """Rig data in SI units: every column an array of the same length; absent optionals None."""

    columns: dict[str, NDArray[np.float64]]
    source: str = '<memory>'
    skipped: dict[str, int] = field(default_factory=dict)
    """Samples left out on conversion from a bag, by reason."""

    def __post_init__(self) -> None:
        """Check the required columns are present and all lengths agree."""
        missing = [c for c in REQUIRED_COLUMNS if c not in self.columns]
        if missing:
            raise RigCsvError(self.source, f'missing required column(s) {missing}')
        n = len(self.columns['t'])
        for name, values in self.columns.items():
            if len(values) != n:
                raise RigCsvError(self.source, f'{len(values)} values, t has {n}', column=name)

    def __len__(self) -> int:
        """Number of samples."""
        return len(self.columns['t'])

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        """One column."""
        return self.columns[name]

    @property
    def names(self) -> list[str]:
        """Columns present, in schema order."""
        return [c for c in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if c in self.columns]


# --- CSV -----------------------------------------------------------------------------------------


def _parse(cell: str, source: str, line: int, column: str, required: bool) -> float:
    text = cell.strip()
    if not text:
        if required:
            raise RigCsvError(source, 'empty cell in a required column', line, column)
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise RigCsvError(source, f'{text!r} is not a number', line, column) from None
    if required and not math.isfinite(value):
        raise RigCsvError(source, f'{text!r} is not finite (required columns must be)', line, column)
    return value


def read_rig_csv(path: Path | str) -> RigTrace:
    """Read a ``worm_rig_data`` CSV file (schema in the module docstring).

    Raises:
        RigCsvError: Unreadable file, no header, a required column missing or
            duplicated, a row of the wrong length, a cell that is not a
            number (or not finite in a required column), ``t`` not strictly
            increasing, or no data row; named by file, line and column.

    """
    source = str(path)
    try:
        handle = Path(path).open(newline='', encoding='utf-8')
    except OSError as err:
        raise RigCsvError(source, f'cannot read: {err.strerror or err}') from err
    with handle:
        reader = csv.reader(handle)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise RigCsvError(source, 'empty file (expected a header row)', 1) from None
        except (csv.Error, UnicodeDecodeError) as err:
            raise RigCsvError(source, f'not CSV: {err}', 1) from None
        seen: set[str] = set()
        for name in header:
            if name in seen:
                raise RigCsvError(source, 'duplicate column in the header', 1, name)
            seen.add(name)
        missing = [c for c in REQUIRED_COLUMNS if c not in seen]
        if missing:
            raise RigCsvError(source, f'missing required column(s) {missing} (required: '
                                      f'{", ".join(REQUIRED_COLUMNS)})', 1, missing[0])
        index = {c: header.index(c) for c in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if c in seen}
        values: dict[str, list[float]] = {c: [] for c in index}
        try:
            for row in reader:
                line = reader.line_num
                if not row or all(not cell.strip() for cell in row):
                    continue
                if len(row) != len(header):
                    raise RigCsvError(source, f'{len(row)} cells, the header has {len(header)}', line)
                for name, i in index.items():
                    values[name].append(_parse(row[i], source, line, name, name in REQUIRED_COLUMNS))
                t = values['t']
                if len(t) > 1 and not t[-1] > t[-2]:
                    raise RigCsvError(source, f'time {t[-1]!r} is not after the previous row\'s '
                                              f'{t[-2]!r} (t must increase strictly)', line, 't')
        except (csv.Error, UnicodeDecodeError) as err:
            raise RigCsvError(source, f'not CSV: {err}', reader.line_num) from None
    if not values['t']:
        raise RigCsvError(source, 'no data rows after the header')
    return RigTrace({c: np.asarray(v, dtype=float) for c, v in values.items()}, source)


def _cell(value: float) -> str:
    return '' if math.isnan(value) else repr(float(value))


def write_rig_csv(path: Path | str, trace: RigTrace) -> None:
    """Write ``trace`` in the ``worm_rig_data`` schema (shortest round-trip floats).

    Raises:
        RigCsvError: The file cannot be written.

    """
    names = trace.names
    try:
        with Path(path).open('w', newline='', encoding='utf-8') as handle:
            handle.write(','.join(names) + '\n')
            columns = [trace[c].tolist() for c in names]
            for row in zip(*columns, strict=True):
                handle.write(','.join(_cell(v) for v in row) + '\n')
    except OSError as err:
        raise RigCsvError(str(path), f'cannot write: {err.strerror or err}') from err


# --- bags ----------------------------------------------------------------------------------------


def find_sample_topic(reader: BagReader, topic: str | None = None) -> str:
    """The RigSample topic to use: ``topic`` if given, else the only one (or ``/rig/sample``).

    Raises:
        RigCsvError: No such topic, not a RigSample topic, or several to choose from.

    """
    source = str(reader.path)
    if topic is not None:
        info = reader.topics.get(topic)
        if info is None:
            raise RigCsvError(source, f'no topic {topic!r}; it has {sorted(reader.topics)}')
        if info.type != RIG_SAMPLE_TYPE:
            raise RigCsvError(source, f'topic {topic!r} is {info.type}, not {RIG_SAMPLE_TYPE}')
        return topic
    candidates = sorted(n for n, i in reader.topics.items() if i.type == RIG_SAMPLE_TYPE)
    if not candidates:
        raise RigCsvError(source, f'no {RIG_SAMPLE_TYPE} topic; it has {sorted(reader.topics)}')
    if len(candidates) > 1:
        if DEFAULT_TOPIC in candidates:
            return DEFAULT_TOPIC
        raise RigCsvError(source, f'several {RIG_SAMPLE_TYPE} topics {candidates}; choose one')
    return candidates[0]


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * NS_PER_S + int(header.stamp.nanosec)


def samples_to_trace(samples: Iterable[Any], source: str = '<samples>') -> RigTrace:
    """RigSample messages (any object with their fields) -> trace, ``t`` from the first stamp.

    Samples with a non-finite required channel, or a stamp not after the
    previous one, are left out and counted in :attr:`RigTrace.skipped`.
    """
    rows: dict[str, list[float]] = {c: [] for c in (*REQUIRED_COLUMNS, 'voltage_drive',
                                                     'theta_gear', 'current_load')}
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
        raise RigCsvError(source, 'no usable RigSample (all non-finite or none at all)')
    columns = {c: np.asarray(v, dtype=float) for c, v in rows.items()}
    for name in ('voltage_drive', 'theta_gear', 'current_load'):
        if np.all(np.isnan(columns[name])):
            del columns[name]  # all-NaN optional channel = absent
    return RigTrace(columns, source, {k: v for k, v in skipped.items() if v})


def bag_to_trace(path: Path | str, topic: str | None = None,
                 types: MessageTypes | None = None) -> RigTrace:
    """Read the RigSample stream of a bag (see :func:`find_sample_topic`) as a trace.

    Raises:
        RigCsvError: No usable RigSample topic.
        BagReadError: The bag cannot be read.

    """
    with BagReader(path, types) as reader:
        name = find_sample_topic(reader, topic)
        return samples_to_trace((m.decoded for m in reader.messages([name])), f'{path}:{name}')


def trace_samples(trace: RigTrace, types: MessageTypes, start_ns: int = 0,
                  frame_id: str = 'rig') -> Iterator[tuple[int, bytes]]:
    """``(stamp_ns, cdr)`` of one RigSample per row (see the module docstring)."""
    store = types.typestore
    types.ensure(RIG_SAMPLE_TYPE)
    sample_cls = store.types[RIG_SAMPLE_TYPE]
    header_cls = store.types['std_msgs/msg/Header']
    time_cls = store.types['builtin_interfaces/msg/Time']
    n = len(trace)
    nan = np.full(n, math.nan)
    current_load = trace.columns.get('current_load', nan)
    voltage = trace.columns.get('voltage_drive', nan)
    theta_gear = trace.columns.get('theta_gear', nan)
    for i in range(n):
        stamp = start_ns + round(float(trace['t'][i]) * NS_PER_S)
        sec, nanosec = divmod(stamp, NS_PER_S)
        if not -(2**31) <= sec < 2**31:
            raise RigCsvError(trace.source, f'stamp {stamp} ns does not fit builtin_interfaces/Time '
                                            '(int32 seconds)', column='t')
        half = float(current_load[i]) / 2.0
        sample = sample_cls(
            header=header_cls(stamp=time_cls(sec=sec, nanosec=nanosec), frame_id=frame_id),
            seq=i,
            current_drive=float(trace['current_drive'][i]),
            current_load_1=half,
            current_load_2=half,
            omega_worm=float(trace['omega_worm'][i]),
            omega_gear=math.nan,
            theta_worm=float(trace['theta_worm'][i]),
            theta_gear=float(theta_gear[i]),
            count_drive=0,
            count_load_1=0,
            count_load_2=0,
            voltage_drive=float(voltage[i]),
            tau_load=float(trace['tau_load'][i]),
            status=0,
        )
        yield stamp, bytes(store.serialize_cdr(sample, RIG_SAMPLE_TYPE))


def trace_to_bag(trace: RigTrace, out: Path | str, storage: str = 'mcap',
                 topic: str = DEFAULT_TOPIC, start_ns: int = 0,
                 types: MessageTypes | None = None) -> int:
    """Write ``trace`` as a bag of RigSample on ``topic``; returns the message count.

    Raises:
        BagRecordingError: The bag cannot be created (e.g. ``out`` exists).

    """
    types = MessageTypes() if types is None else types
    with BagWriter(out, storage, types=types) as writer:
        handle = writer.add_topic(topic, RIG_SAMPLE_TYPE)
        for stamp, data in trace_samples(trace, types, start_ns):
            writer.write(handle, stamp, data)
        return writer.counts[topic]


def bag_to_measured(path: Path | str, topic: str | None = None) -> Any:
    """A bag's RigSample stream as ``worm_model.residuals.data.MeasuredData``.

    Raises:
        RigCsvError: No usable RigSample topic.
        BagRecordingError: The bag cannot be read.
        ImportError: worm_model has no residuals package.

    """
    from worm_model.residuals.data import MeasuredData  # only for this conversion

    trace = bag_to_trace(path, topic)
    return MeasuredData(**trace.columns, source=trace.source)

