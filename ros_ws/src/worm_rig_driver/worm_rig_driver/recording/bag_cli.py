"""bag: look into rosbag2 bags and convert rig data, without ROS 2 running.

    ros2 run worm_rig_driver bag info   <bag>
    ros2 run worm_rig_driver bag echo   <bag> <topic> [-n N]
    ros2 run worm_rig_driver bag export <bag> --out run.csv [--topic /rig/sample]
    ros2 run worm_rig_driver bag import run.csv --out <bag> [--storage mcap|sqlite3]

Reads every bag layout rosbag2 writes (sqlite3 and MCAP, metadata versions
4 to 9, split, zstd-compressed per file or per message, with or without
metadata.yaml); see worm_model.bags.reader. Counts are messages read from
storage, not copied from metadata.yaml. Exit code 2 on a bad bag or CSV, the
message naming the file and the key, line or column.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Final, TextIO

from tqdm import tqdm

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, existing_file, existing_bag, integer, number, output_path
from worm_model.files.writing import check_output
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.schema import OPTIONAL_COLUMNS, REQUIRED_COLUMNS
from worm_model.bags.reader import BagMessage, BagReader
from worm_model.bags.topic_names import topic_name_problem
from worm_model.errors import BagRecordingError, InputError
from worm_model.bags.message_yaml import message_to_yaml
from worm_model.rig_data.bags import DEFAULT_TOPIC, EXPORT_OUTPUT, IMPORT_OUTPUT, bag_to_csv, csv_to_bag
from worm_model.bags.seq_check import StreamCheck

EXIT_BAD_INPUT: Final[int] = 2
TRUNCATED_HELP: Final[str] = ('read a storage file cut inside a record (messages lost) as far as it goes, '
                              'instead of refusing it')
LABEL_WIDTH: Final[int] = 19


def _progress(messages: Iterator[BagMessage], total: int | None, what: str) -> Iterator[BagMessage]:
    """Pass ``messages`` through a progress bar on a terminal's stderr."""
    with tqdm(total=total, desc=what, unit='msg', file=sys.stderr, leave=False,
              disable=not sys.stderr.isatty()) as bar:
        for message in messages:
            bar.update()
            yield message


def _size(path: Path) -> str:
    files = [path] if path.is_file() else [p for p in path.rglob('*') if p.is_file()]
    size = float(sum(p.stat().st_size for p in files))
    for unit in ('B', 'KiB', 'MiB', 'GiB'):
        if size < 1024 or unit == 'GiB':
            return f'{size:.1f} {unit}' if unit != 'B' else f'{int(size)} B'
        size /= 1024
    return f'{size:.1f} GiB'


def _time(ns: int) -> str:
    stamp = datetime.fromtimestamp(ns / 1e9, tz=UTC)
    return f'{stamp:%b %d %Y %H:%M:%S}.{stamp.microsecond // 1000:03d} UTC ({ns / 1e9:.9f})'


def _line(out: TextIO, label: str, value: object) -> None:
    """``Label:`` padded to a column, then the value (a blank label continues a list)."""
    out.write(f'{label + ":" if label else "":<{LABEL_WIDTH}}{value}\n')


def info(path: Path, out: TextIO) -> int:
    """``bag info``: files, times and, per topic, the type and the messages read from storage.

    A storage file cut inside a record is described as far as it goes; the cut is among the warnings.
    """
    with BagReader(path, allow_truncated=True) as reader:
        counts = dict.fromkeys(sorted(reader.topics), 0)
        first, last = math.inf, -math.inf
        check = StreamCheck()
        for name, topic in reader.topics.items():
            try:
                check.watch(name, reader.typestore_for(topic.type), topic.type)
            except BagRecordingError:
                pass  # no definition: no seq check for it, counting still works
        total = reader.metadata.message_count if reader.metadata else None
        for message in _progress(reader.raw_messages(), total, 'reading'):
            counts[message.topic] += 1
            first, last = min(first, message.timestamp), max(last, message.timestamp)
            check.add(message.topic, message.data)
        for name, count in counts.items():
            claimed = reader.topics[name].metadata_count
            if claimed is not None and claimed != count:
                reader.warnings.append(f'{name}: metadata.yaml claims {claimed} messages, '
                                       f'storage holds {count}')
        meta = reader.metadata
        _line(out, 'Files', ', '.join(reader.file_names()))
        _line(out, 'Bag size', _size(path))
        _line(out, 'Storage id', reader.storage_identifier)
        _line(out, 'ROS Distro', (meta.ros_distro if meta else '') or 'unknown')
        _line(out, 'Metadata version', meta.version if meta and meta.version is not None else
              'none (no metadata.yaml)')
        if reader.compression_mode:
            _line(out, 'Compression', f'{meta.compression_format if meta else "zstd"} '
                                      f'{reader.compression_mode}')
        n = sum(counts.values())
        if n:
            _line(out, 'Duration', f'{(last - first) / 1e9:.9f}s')
            _line(out, 'Start', _time(int(first)))
            _line(out, 'End', _time(int(last)))
        _line(out, 'Messages', n)
        label = 'Topic information'
        for name, count in counts.items():
            topic = reader.topics[name]
            _line(out, label, f'Topic: {name} | Type: {topic.type} | Count: {count} | '
                              f'Serialization Format: {topic.serialization_format or "cdr"}')
            label = ''
        label = 'Sequence check'
        for line in check.report():
            _line(out, label, line)
            label = ''
        label = 'Warnings'
        for warning in reader.warnings:
            _line(out, label, warning)
            label = ''
    return 0


def echo(path: Path, topic: str, count: int | None, out: TextIO, allow_truncated: bool = False) -> int:
    """``bag echo``: messages of one topic as YAML, ``---`` after each, like ``ros2 topic echo``."""
    with BagReader(path, allow_truncated=allow_truncated) as reader:
        for shown, message in enumerate(reader.messages([topic])):
            if count is not None and shown >= count:
                break
            out.write(message_to_yaml(message.decoded))
            out.write('---\n')
    return 0


def export(path: Path, csv_path: Path, topic: str | None, err: TextIO, allow_truncated: bool = False,
           force: bool = False) -> int:
    """``bag export``: the RigSample stream as a ``worm_rig_data`` CSV."""
    check_output(csv_path, force, inputs=[path], output=EXPORT_OUTPUT)
    data = bag_to_csv(path, csv_path, topic, allow_truncated, force)
    skipped = [f'{n} {why}' for why, n in data.skipped.items()]
    skipped += [f'an unknown number after the cut of a truncated file ({d})' for d in data.damage]
    err.write(f'bag export: {len(data)} rows from {data.source} to {csv_path} '
              f'(columns {", ".join(data.names)}; samples left out: {", ".join(skipped) or "none"})\n')
    return 0


def import_csv(csv_path: Path, bag: Path, storage: str, topic: str, start: float,
               err: TextIO, rig: Path | None = None, force: bool = False) -> int:
    """``bag import``: a ``worm_rig_data`` CSV as a bag of RigSample (its units checked against the rig)."""
    if (problem := topic_name_problem(topic)) is not None:  # a bag no ROS tool could play or subscribe to
        raise InputError("--topic", f"{topic!r} is not a valid topic name ({problem})")
    check_output(bag, force, folder=True, inputs=[csv_path, rig], output=IMPORT_OUTPUT)
    n = csv_to_bag(csv_path, bag, storage, topic, round(start * 1e9), rig=load_rig(rig), force=force)
    err.write(f'bag import: {n} RigSample messages on {topic} from {csv_path} to {bag} ({storage})\n')
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog='bag', description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog='Exit codes: 0 done, 2 bad bag or CSV (the message names file and key/line/column).')
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    p = commands.add_parser('info',  help='files, times, and per topic its type and message count',
                            description='Print the bag\'s files, size, storage, ROS distro, '
                            'metadata version, compression, duration, start and end, then per '
                            'topic its type and the number of messages actually read from '
                            'storage (not the count metadata.yaml claims), a sequence-number '
                            'check of every stream with a seq field, and warnings (e.g. '
                            'metadata.yaml and storage disagreeing).')
    p.add_argument('bag', type=existing_bag, help='bag directory, or one .db3/.mcap(.zstd) file')

    p = commands.add_parser('echo', help='print a topic\'s messages as YAML',
                            description='Print the messages of one topic decoded, as YAML, each '
                            'followed by a "---" line (the format of ros2 topic echo).')
    p.add_argument('bag', type=existing_bag, help='bag directory, or one .db3/.mcap(.zstd) file')
    p.add_argument('topic', help='topic to print, e.g. /rig/sample')
    p.add_argument('-n', '--count', type=integer(0), default=None, metavar='N',
                   help='print only the first N messages (default: all)')
    p.add_argument('--allow-truncated', action='store_true', help=TRUNCATED_HELP)

    columns = ', '.join([*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS])
    p = commands.add_parser('export', help='RigSample stream -> worm_rig_data CSV',
                            description='Write the bag\'s worm_msgs/msg/RigSample stream as a CSV '
                            f'with the columns {columns} (units in docs/bags-and-tools.md). t [s] counts from '
                            'the first sample\'s header.stamp; current_load is the sum of the two '
                            'load-motor currents; tau_load is RigSample.tau_load. Samples with a '
                            'NaN/inf required channel, or a stamp not after the previous one, are '
                            'left out and counted on stderr.')
    p.add_argument('bag', type=existing_bag, help='bag directory, or one .db3/.mcap(.zstd) file')
    p.add_argument('--out', type=output_path, required=True, metavar='FILE.csv',
                   help='CSV file to write (an existing one is replaced only with --force, and only if it is a '
                        'worm_rig_data CSV; never the bag or a file inside it)')
    p.add_argument('--force', action='store_true', help='replace an existing --out file')
    p.add_argument('--allow-truncated', action='store_true', help=TRUNCATED_HELP)
    p.add_argument('--topic', default=None,
                   help='RigSample topic to export (default: the only one, or /rig/sample)')

    p = commands.add_parser('import', help='worm_rig_data CSV -> bag of RigSample',
                            description='Write a worm_rig_data CSV as a bag of worm_msgs/msg/'
                            'RigSample, one message per row: header.stamp = start + t, seq = row '
                            'index, current_load split equally over the two load motors, channels '
                            'the CSV lacks NaN (encoder counts 0). Message definitions are '
                            'embedded, so ros2 bag, Foxglove and PlotJuggler decode it.')
    p.add_argument('csv', type=existing_file, help='CSV file in the worm_rig_data schema')
    p.add_argument('--out', type=output_path, required=True, metavar='BAG',
                   help='bag directory to create (an existing one is replaced only with --force, and only if '
                        'bag import wrote it)')
    p.add_argument('--force', action='store_true', help='replace an existing --out bag that bag import wrote')
    p.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap',
                   help='storage of the new bag (default: mcap, as rosbag2)')
    p.add_argument('--topic', default=DEFAULT_TOPIC, help=f'topic to write (default: {DEFAULT_TOPIC})')
    p.add_argument('--start', type=number('s', 0, 2**31 - 1), default=0.0, metavar='SECONDS',
                   help='ROS time [s since the epoch] of t = 0 (default: 0); start + t must be >= 0')
    p.add_argument('--rig', type=existing_file, default=None,
                   help='rig parameter YAML the values are checked against (default: the bundled NMRV030 rig)')
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one ``bag`` command; returns the exit code."""
    args = _parser().parse_args(argv)
    out, err = sys.stdout, sys.stderr

    def run() -> int:
        if args.command == 'info':
            return info(args.bag, out)
        if args.command == 'echo':
            return echo(args.bag, args.topic, args.count, out, args.allow_truncated)
        if args.command == 'export':
            return export(args.bag, args.out, args.topic, err, args.allow_truncated, args.force)
        return import_csv(args.csv, args.out, args.storage, args.topic, args.start, err, args.rig, args.force)

    return run_tool(f'bag {args.command}', run)


if __name__ == '__main__':
    sys.exit(main())
