"""Read rosbag2 bags as the real rosbag2 writes them, without rclpy.

:class:`BagReader` opens a bag directory (or one ``.db3`` / ``.mcap`` file,
compressed or not) and yields its messages raw or decoded. It reads every
layout rosbag2 has written since Foxy:

====  ===========================  ============================================
meta  rosbag2 release (ROS distro)  what changed
====  ===========================  ============================================
4     0.3 Foxy, 0.9 Galactic       ``offered_qos_profiles`` (YAML text)
5     0.15 Humble                  per-file ``files`` list; sqlite3 ``schema``
                                   and ``metadata`` tables (sqlite schema 3)
6     0.17-0.21 (Rolling 2022/23)  ``custom_data``
7     0.22 Iron                    ``type_description_hash``; sqlite3
                                   ``message_definitions`` (sqlite schema 4)
8     0.24 (Rolling 2023)          ``ros_distro``
9     0.26 Jazzy and later         QoS as YAML nodes with policy names
====  ===========================  ============================================

Storage: sqlite3 (``.db3``) or MCAP (``.mcap``), split into several files,
compressed with zstd per file (``<file>.zstd``, compression mode ``FILE``) or
per message (sqlite3 only, mode ``MESSAGE``).

Where it differs from ``rosbags``' directory reader, on purpose:

* Topics are matched between ``metadata.yaml`` and the storage files by name
  only. rosbags also compares the offered-QoS profiles, and yields zero
  messages when the two disagree, which real bags do: ``ros2 bag reindex``
  (and ``convert``) of Jazzy rewrite ``metadata.yaml`` with QoS decoded from
  storage, translating Foxy-era "infinite" durations, and the reindexer keeps
  one file's profiles for all files of a split bag. A disagreement is a
  warning here (:attr:`BagReader.warnings`), not an empty bag.
* Message counts come from storage (:meth:`BagReader.count_messages`), never
  from ``metadata.yaml``; a disagreement is a warning.
* A missing ``metadata.yaml`` (a recorder killed before it wrote it) is not an
  error: the storage files of the directory are read in split order
  (``<name>_0``, ``<name>_1``, ..., ``<name>_10``), and the compression mode
  is taken from the metadata rosbag2 keeps inside sqlite3 (Humble on) and
  MCAP (Jazzy on) files, or recognised from the zstd magic number.
* zstd frames without a content size (rosbag2 >= 0.26 compresses files as a
  stream) are decompressed as streams.
* Decoding uses the definitions embedded in the bag first and falls back to
  :class:`~worm_model.bags.typestore.MessageTypes` (the stock ROS 2 types and
  the interface files under ``AMENT_PREFIX_PATH``) for types without one,
  e.g. every bag before Iron. A type hash that does not match its definition
  is a warning, not a refusal to read.

Within one storage file messages come in timestamp order; files come in the
order ``metadata.yaml`` lists them (rosbag2's sequential reader does the
same). Timestamps are receive times, integer ns.

Raises:
    :class:`~worm_model.errors.BagReadError` for every failure, its
    message naming the file and, for a bad ``metadata.yaml``, the key.
"""

from __future__ import annotations

import io
import re
import shutil
import sqlite3
import struct
import tempfile
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Protocol
from urllib.parse import quote

import zstandard
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.records import Channel, DataEnd, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from rosbags.typesys import (
    Stores,
    TypesysError,
    get_types_from_idl,
    get_types_from_msg,
    get_typestore,
)
from rosbags.typesys.store import Typestore
from ruamel.yaml import YAML
from ruamel.yaml.error import YAMLError

from worm_model.errors import BagReadError, BagRecordingError, InputError
from worm_model.files.reading import MAX_YAML_BYTES, check_input, check_yaml, read_text
from worm_model.bags.typestore import ClosesOnExit, MessageTypes, deserialize_cdr, referenced_types

__all__ = [
    'BagMessage',
    'BagMetadata',
    'BagReader',
    'MessageDefinition',
    'StorageTopic',
    'TopicInfo',
    'parse_metadata',
    'storage_files',
]

METADATA_FILE: Final[str] = 'metadata.yaml'
METADATA_KEY: Final[str] = 'rosbag2_bagfile_information'
NEWEST_KNOWN_VERSION: Final[int] = 9
ZSTD_SUFFIX: Final[str] = '.zstd'
ZSTD_MAGIC: Final[bytes] = b'\x28\xb5\x2f\xfd'
"""First bytes of a zstd frame; a CDR message starts with 0x00 instead."""
SQLITE_MAGIC: Final[bytes] = b'SQLite format 3\x00'
MCAP_MAGIC: Final[bytes] = b'\x89MCAP0\r\n'
DEFINITION_SEPARATOR: Final[str] = '=' * 80 + '\n'
SPLIT_INDEX: Final[re.Pattern[str]] = re.compile(r'^(.*?)(?:_(\d+))?$')


@dataclass(frozen=True, slots=True)
class MessageDefinition:
    """A type's definition as embedded in a bag."""

    encoding: str
    """``ros2msg`` or ``ros2idl`` (empty or ``unknown``: none)."""
    text: str
    """The definition with its dependencies, rosbag2's concatenated format."""

    @property
    def usable(self) -> bool:
        """Whether there is a definition to parse."""
        return self.encoding in ('ros2msg', 'ros2idl') and bool(self.text.strip())


@dataclass(frozen=True, slots=True)
class StorageTopic:
    """A topic as one storage file declares it."""

    name: str
    type: str
    serialization_format: str
    offered_qos_profiles: str
    """As stored: YAML text (may be empty)."""
    type_hash: str
    definition: MessageDefinition | None


@dataclass
class TopicInfo:
    """A topic of the whole bag: storage files first, ``metadata.yaml`` second."""

    name: str
    type: str
    serialization_format: str
    type_hash: str = ''
    definition: MessageDefinition | None = None
    offered_qos_profiles: object = ''
    """From storage if any file has it, else from ``metadata.yaml`` (text or list)."""
    metadata_count: int | None = None
    """What ``metadata.yaml`` claims (None: not listed there, or no metadata)."""
    files: list[str] = field(default_factory=list)
    """Storage files (names) that declare the topic."""


@dataclass(frozen=True, slots=True)
class BagMessage:
    """One message read from storage."""

    topic: str
    timestamp: int
    """Receive time [ns]."""
    data: bytes
    """Serialized (CDR) bytes, decompressed."""
    file: str
    """Storage file (name in the bag) it came from."""


@dataclass(frozen=True, slots=True)
class DecodedMessage:
    """A message and its decoded content (a rosbags dataclass)."""

    topic: str
    timestamp: int
    decoded: Any


@dataclass
class BagMetadata:
    """What ``metadata.yaml`` (or the metadata embedded in storage) says."""

    version: int | None = None
    storage_identifier: str = ''
    relative_file_paths: list[str] = field(default_factory=list)
    compression_format: str = ''
    compression_mode: str = ''
    """``''``, ``FILE`` or ``MESSAGE`` (upper case, as rosbag2 writes it)."""
    ros_distro: str = ''
    message_count: int | None = None
    starting_time_ns: int | None = None
    duration_ns: int | None = None
    topics: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Topic name -> ``topic_metadata`` mapping, plus ``message_count``."""
    custom_data: dict[str, str] = field(default_factory=dict)
    source: str = ''
    """Where it was read from (file, or file and table)."""


def _require(mapping: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    """Return ``mapping[key]`` checked against ``kind``, or raise naming the key."""
    if key not in mapping:
        msg = f'{where}: missing key {key!r}'
        raise BagReadError(msg)
    value = mapping[key]
    if not isinstance(value, kind) or isinstance(value, bool) and kind is int:
        msg = f'{where}: key {key!r} is {type(value).__name__} {value!r}, expected {_kind_name(kind)}'
        raise BagReadError(msg)
    return value


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return ' or '.join(k.__name__ for k in kinds)


def _optional(mapping: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str,
              default: Any) -> Any:
    """Like :func:`_require` but ``default`` for an absent (or null) key."""
    if mapping.get(key) is None:
        return default
    return _require(mapping, key, kind, where)


def _nanoseconds(node: Any, key: str, inner: str, where: str) -> int | None:
    """``{key: {inner: n}}`` -> n (None if absent)."""
    if node is None:
        return None
    if not isinstance(node, Mapping):
        msg = f'{where}: key {key!r} is {node!r}, expected a mapping with {inner!r}'
        raise BagReadError(msg)
    return _require(node, inner, int, f'{where}: {key}')


#: newest metadata.yaml version this reader knows (rosbag2 of Kilted writes 9)
MAX_METADATA_VERSION: Final = 9


def parse_metadata(document: Any, source: str) -> BagMetadata:
    """Check and convert a parsed ``metadata.yaml`` (versions 1 to 9).

    Args:
        document: The YAML document; with or without the top-level
            ``rosbag2_bagfile_information`` key (rosbag2 stores it without it
            inside sqlite3 and MCAP files).
        source: Where it came from, for error messages.

    Raises:
        BagReadError: A key is missing or has the wrong type; the message
            names ``source`` and the key.

    """
    if isinstance(document, Mapping) and METADATA_KEY in document:
        info = document[METADATA_KEY]
        where = f'{source}: {METADATA_KEY}'
    else:
        info = document
        where = source
    if not isinstance(info, Mapping):
        msg = f'{source}: expected a mapping under {METADATA_KEY!r}, got {type(info).__name__}'
        raise BagReadError(msg)
    meta = BagMetadata(source=source)
    meta.version = _require(info, 'version', int, where)
    if not 1 <= meta.version <= MAX_METADATA_VERSION:
        msg = (f'{where}: key version is {meta.version}: this reader knows metadata versions 1 to '
               f'{MAX_METADATA_VERSION} (a newer rosbag2 wrote it, or the file is damaged)')
        raise BagReadError(msg)
    meta.storage_identifier = _require(info, 'storage_identifier', str, where)
    paths = _optional(info, 'relative_file_paths', list, where, [])
    for i, name in enumerate(paths):
        if not isinstance(name, str):
            msg = f'{where}: key relative_file_paths[{i}] is {name!r}, expected a file name'
            raise BagReadError(msg)
    meta.relative_file_paths = list(paths)
    meta.compression_format = _optional(info, 'compression_format', str, where, '')
    meta.compression_mode = _optional(info, 'compression_mode', str, where, '').upper()
    if meta.compression_mode == 'NONE':
        meta.compression_mode = ''
    meta.ros_distro = _optional(info, 'ros_distro', str, where, '')
    meta.message_count = _optional(info, 'message_count', int, where, None)
    meta.starting_time_ns = _nanoseconds(info.get('starting_time'), 'starting_time',
                                         'nanoseconds_since_epoch', where)
    meta.duration_ns = _nanoseconds(info.get('duration'), 'duration', 'nanoseconds', where)
    custom = info.get('custom_data') or {}
    if not isinstance(custom, Mapping):
        msg = f'{where}: key custom_data is {custom!r}, expected a mapping'
        raise BagReadError(msg)
    meta.custom_data = {str(k): str(v) for k, v in custom.items()}
    topics = _optional(info, 'topics_with_message_count', list, where, [])
    for i, entry in enumerate(topics):
        here = f'{where}: topics_with_message_count[{i}]'
        if not isinstance(entry, Mapping):
            msg = f'{here}: expected a mapping, got {entry!r}'
            raise BagReadError(msg)
        topic = _require(entry, 'topic_metadata', Mapping, here)
        here = f'{here}: topic_metadata'
        name = _require(topic, 'name', str, here)
        record = {
            'name': name,
            'type': _require(topic, 'type', str, here),
            'serialization_format': _optional(topic, 'serialization_format', str, here, 'cdr'),
            'offered_qos_profiles': topic.get('offered_qos_profiles') or '',
            'type_description_hash': _optional(topic, 'type_description_hash', str, here, ''),
            'message_count': _optional(entry, 'message_count', int, here, None),
        }
        meta.topics[name] = record
    return meta


def read_metadata_file(path: Path) -> BagMetadata:
    """Read and check ``<bag>/metadata.yaml``.

    Raises:
        BagReadError: Unreadable file, not YAML, or a bad key (named).

    """
    try:
        text = read_text(path, 'bag metadata file', MAX_YAML_BYTES)
    except InputError as err:
        msg = f'Cannot read bag metadata {err}'
        raise BagReadError(msg) from None
    try:
        check_yaml(text, str(path))  # depth, size, alias expansion: the limits of every YAML file read
        document = YAML(typ='safe', pure=True).load(text)
    except InputError as err:
        place = err.where.removeprefix(str(path)).lstrip(': ')
        msg = f'Bag metadata {path} is not YAML{" (" + place + ")" if place else ""}: ' \
              f'{err.what.removeprefix("not valid YAML: ")}'
        raise BagReadError(msg) from None
    except YAMLError as err:
        msg = f'Bag metadata {path} is not YAML: {err}'
        raise BagReadError(msg) from err
    if not isinstance(document, Mapping) or METADATA_KEY not in document:
        msg = f'{path}: missing key {METADATA_KEY!r}'
        raise BagReadError(msg)
    return parse_metadata(document, str(path))


def _parse_embedded_metadata(text: str, source: str) -> BagMetadata | None:
    """Metadata rosbag2 serialized into a storage file; None if unusable."""
    try:
        document = YAML(typ='safe', pure=True).load(text)
        return parse_metadata(document, source)
    except (YAMLError, BagReadError):
        return None


# --- storage files -----------------------------------------------------------------------------


class StorageFile(Protocol):
    """One open storage file of a bag."""

    name: str
    """Its name in the bag (the compressed name for a decompressed file)."""
    topics: list[StorageTopic]
    embedded_metadata: BagMetadata | None
    """The last metadata rosbag2 wrote into the file (Humble+ sqlite3, Jazzy+ MCAP)."""

    def messages(self, topics: Collection[str] | None) -> Iterator[tuple[str, int, bytes]]:
        """Yield ``(topic, timestamp_ns, data)`` in timestamp order."""
        ...

    def close(self) -> None:
        """Release the file."""
        ...


class Sqlite3File:
    """A rosbag2 sqlite3 storage file, any schema version (1 to 4).

    Schema history (``rosbag2_storage_sqlite3`` / ``_default_plugins``):
    Foxy/Galactic: ``topics(id, name, type, serialization_format,
    offered_qos_profiles)`` and ``messages(id, topic_id, timestamp, data)``;
    Humble adds the ``schema(schema_version, ros_distro)`` and
    ``metadata(id, metadata_version, metadata)`` tables (schema 3); Iron adds
    ``topics.type_description_hash`` and the ``message_definitions`` table
    (schema 4). Eloquent and older lack ``offered_qos_profiles``.
    """

    def __init__(self, path: Path, name: str) -> None:
        """Open ``path`` read-only.

        Raises:
            BagReadError: Not an sqlite3 database, or not a rosbag2 one.

        """
        self.name = name
        self.path = path
        # A database left in WAL mode (Foxy writes them so) would make SQLite create
        # -wal/-shm files next to it; unless a -wal file holds data (a recorder that
        # crashed), open it immutable: nothing written, works on read-only media too.
        wal = path.with_name(path.name + '-wal')
        options = 'mode=ro' if wal.exists() and wal.stat().st_size else 'mode=ro&immutable=1'
        try:
            self.db = sqlite3.connect(f'file:{quote(str(path))}?{options}', uri=True)
            tables = {row[0] for row in self.db.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
        except sqlite3.Error as err:
            msg = f'Cannot open sqlite3 storage file {path}: {err}'
            raise BagReadError(msg) from err
        missing = {'topics', 'messages'} - tables
        if missing:
            self.db.close()
            msg = f'{path} is not a rosbag2 sqlite3 file: no table {sorted(missing)[0]!r}'
            raise BagReadError(msg)
        try:
            self.topics, self._ids = self._read_topics(tables)
            self.embedded_metadata = self._read_metadata(tables)
        except sqlite3.Error as err:
            self.db.close()
            msg = f'Cannot read the topics of sqlite3 storage file {path}: {err}'
            raise BagReadError(msg) from err

    def _read_topics(self, tables: set[str]) -> tuple[list[StorageTopic], dict[int, str]]:
        columns = {row[1] for row in self.db.execute('PRAGMA table_info(topics)')}
        wanted = ['id', 'name', 'type', 'serialization_format']
        optional = ['offered_qos_profiles', 'type_description_hash']
        select = wanted + [c for c in optional if c in columns]
        definitions: dict[str, MessageDefinition] = {}
        if 'message_definitions' in tables:
            for type_name, encoding, text in self.db.execute(
                'SELECT topic_type, encoding, encoded_message_definition FROM message_definitions'
            ):
                definitions[type_name] = MessageDefinition(encoding or '', text or '')
        topics: list[StorageTopic] = []
        ids: dict[int, str] = {}
        for row in self.db.execute(f'SELECT {", ".join(select)} FROM topics ORDER BY id'):
            values = dict(zip(select, row, strict=True))
            ids[values['id']] = values['name']
            topics.append(StorageTopic(
                name=values['name'],
                type=values['type'],
                serialization_format=values['serialization_format'],
                offered_qos_profiles=values.get('offered_qos_profiles') or '',
                type_hash=values.get('type_description_hash') or '',
                definition=definitions.get(values['type']),
            ))
        return topics, ids

    def _read_metadata(self, tables: set[str]) -> BagMetadata | None:
        if 'metadata' not in tables:
            return None
        row = self.db.execute('SELECT metadata FROM metadata ORDER BY id DESC LIMIT 1').fetchone()
        return _parse_embedded_metadata(row[0], f'{self.path}: table metadata') if row else None

    def messages(self, topics: Collection[str] | None) -> Iterator[tuple[str, int, bytes]]:
        """Yield ``(topic, timestamp_ns, data)`` ordered by timestamp, then insertion.

        Raises:
            BagReadError: The database is damaged.

        """
        query = 'SELECT topic_id, timestamp, data FROM messages'
        args: list[int] = []
        if topics is not None:
            ids = [i for i, name in self._ids.items() if name in topics]
            query += f' WHERE topic_id IN ({", ".join("?" * len(ids))})'
            args = ids
        query += ' ORDER BY timestamp, id'
        try:
            for topic_id, timestamp, data in self.db.execute(query, args):
                name = self._ids.get(topic_id)
                if name is None:
                    msg = f'{self.path}: a message refers to topic id {topic_id}, not in table topics'
                    raise BagReadError(msg)
                yield name, timestamp, data
        except sqlite3.Error as err:
            msg = f'Cannot read messages of sqlite3 storage file {self.path}: {err}'
            raise BagReadError(msg) from err

    def close(self) -> None:
        """Close the database."""
        self.db.close()


class McapFile:
    """A rosbag2 MCAP storage file (profile ``ros2``), any rosbag2 version.

    Channel metadata ``offered_qos_profiles`` (all versions) and
    ``topic_type_hash`` (Iron+); schemas ``ros2msg``/``ros2idl`` with the
    full definition text; a metadata record ``rosbag2`` holding
    ``ROS_DISTRO`` (Humble to 0.24) or ``serialized_metadata`` (Jazzy+).
    A file without a summary section (recorder killed) is read by scanning.
    """

    def __init__(self, path: Path, name: str) -> None:
        """Open ``path`` and read its schemas, channels and metadata.

        Raises:
            BagReadError: Not an MCAP file or unreadable.

        """
        self.name = name
        self.path = path
        self.warnings: list[str] = []
        try:
            self.stream = path.open('rb')
        except OSError as err:
            msg = f'Cannot open MCAP storage file {path}: {err}'
            raise BagReadError(msg) from err
        self.seekable = False
        self.embedded_metadata: BagMetadata | None = None
        #: why the file is damaged (data lost), "" if it is not
        self.damage = ''
        try:
            self._read_summary()
        except (McapError, OSError, ValueError, EOFError, struct.error) as err:
            self.stream.close()
            msg = f'Cannot read MCAP storage file {path}: {err!r}'
            raise BagReadError(msg) from err

    def _read_summary(self) -> None:
        reader = SeekingReader(self.stream)
        try:
            summary = reader.get_summary()
        except (McapError, EOFError, ValueError, struct.error):
            summary = None
        if summary is not None:
            self.seekable = True
            schemas, channels = summary.schemas, summary.channels
            records = [m for m in reader.iter_metadata() if m.name == 'rosbag2']
        else:
            self.warnings.append(f'{self.path}: no MCAP summary (file not closed); scanned instead')
            schemas, channels, records = {}, {}, []
            self.stream.seek(0)
            messages = 0
            size = self.path.stat().st_size
            end = 0  # where the last complete record ends
            try:
                for record in StreamReader(self.stream, record_size_limit=None).records:
                    end = self.stream.tell()
                    if isinstance(record, Schema):
                        schemas[record.id] = record
                    elif isinstance(record, Channel):
                        channels[record.id] = record
                    elif isinstance(record, Message):
                        messages += 1
                    elif isinstance(record, Metadata) and record.name == 'rosbag2':
                        records.append(record)
                    elif isinstance(record, DataEnd):
                        break  # every message is before it: a cut in the summary loses none
            except (McapError, EOFError, ValueError, struct.error) as err:
                if end == size:  # it ends after a complete record: a writer stopped (killed) between two
                    self.warnings.append(f'{self.path}: ends after {messages} message(s) without its '
                                         'footer: the writer stopped before closing it')
                else:
                    self.damage = (f'{self.path}: truncated: it ends inside a record ({type(err).__name__}) '
                                   f'of its {size} bytes, so the messages of the cut-off part are lost; '
                                   f'{messages} message(s) before the cut can be read')
        self.topics = []
        self._channel_topics: dict[int, str] = {}
        seen: set[str] = set()
        for channel in channels.values():
            schema = schemas.get(channel.schema_id)
            self._channel_topics[channel.id] = channel.topic
            if channel.topic in seen:
                continue
            seen.add(channel.topic)
            self.topics.append(StorageTopic(
                name=channel.topic,
                type=schema.name if schema else '',
                serialization_format=channel.message_encoding,
                offered_qos_profiles=channel.metadata.get('offered_qos_profiles', ''),
                type_hash=channel.metadata.get('topic_type_hash', ''),
                definition=_schema_definition(schema),
            ))
        for record in reversed(records):
            if text := record.metadata.get('serialized_metadata'):
                self.embedded_metadata = _parse_embedded_metadata(
                    text, f'{self.path}: metadata record rosbag2')
                break
        if self.embedded_metadata is None and records:
            distro = records[-1].metadata.get('ROS_DISTRO', '')
            self.embedded_metadata = None if not distro else BagMetadata(
                ros_distro=distro, storage_identifier='mcap', source=str(self.path))

    def messages(self, topics: Collection[str] | None) -> Iterator[tuple[str, int, bytes]]:
        """Yield ``(topic, log_time_ns, data)`` in log-time order.

        Raises:
            BagReadError: The file is damaged (a truncated file without
                summary ends quietly where it ends instead).

        """
        self.stream.seek(0)
        try:
            if self.seekable:
                wanted = None if topics is None else list(topics)
                for _schema, channel, message in SeekingReader(self.stream).iter_messages(
                        topics=wanted, log_time_order=True):
                    yield channel.topic, message.log_time, message.data
                return
            found = []
            try:
                for _schema, channel, message in NonSeekingReader(
                        self.stream, record_size_limit=None).iter_messages(log_time_order=False):
                    if topics is None or channel.topic in topics:
                        found.append((message.log_time, message.sequence, channel.topic, message.data))
            except (McapError, EOFError, struct.error):
                pass  # truncated
            found.sort(key=lambda m: m[:2])
            for log_time, _sequence, topic, data in found:
                yield topic, log_time, data
        except (McapError, OSError, ValueError, struct.error) as err:
            msg = f'Cannot read messages of MCAP storage file {self.path}: {err!r}'
            raise BagReadError(msg) from err

    def close(self) -> None:
        """Close the file."""
        self.stream.close()


def _schema_definition(schema: Schema | None) -> MessageDefinition | None:
    if schema is None:
        return None
    try:
        text = schema.data.decode('utf-8')
    except UnicodeDecodeError:
        return None
    return MessageDefinition(schema.encoding, text)


STORAGE_READERS: Final[Mapping[str, Callable[[Path, str], StorageFile]]] = {
    'sqlite3': Sqlite3File,
    'mcap': McapFile,
}
"""Storage identifier (as rosbag2 spells it) -> reader of one file."""

STORAGE_SUFFIXES: Final[Mapping[str, str]] = {'.db3': 'sqlite3', '.mcap': 'mcap'}


def _storage_of(path: Path, default: str) -> str:
    """Storage identifier of a (decompressed) file: by suffix, else by magic number."""
    suffix = path.suffix
    if suffix in STORAGE_SUFFIXES:
        return STORAGE_SUFFIXES[suffix]
    try:
        with path.open('rb') as stream:
            head = stream.read(16)
    except OSError:
        return default
    if head.startswith(SQLITE_MAGIC):
        return 'sqlite3'
    if head.startswith(MCAP_MAGIC):
        return 'mcap'
    return default


def _split_key(path: Path) -> tuple[str, int, str]:
    """Sort key putting ``x_2.db3`` before ``x_10.db3``."""
    stem = path.name.removesuffix(ZSTD_SUFFIX)
    base = stem.rsplit('.', 1)[0] if '.' in stem else stem
    match = SPLIT_INDEX.match(base)
    assert match is not None  # the pattern matches any string
    return match.group(1), int(match.group(2) or -1), path.name


def storage_files(directory: Path) -> list[Path]:
    """The storage files of a bag directory without ``metadata.yaml``, in split order."""
    found = [p for p in directory.iterdir() if p.is_file() and (
        p.suffix in STORAGE_SUFFIXES
        or p.suffix == ZSTD_SUFFIX and Path(p.stem).suffix in STORAGE_SUFFIXES)]
    return sorted(found, key=_split_key)


def _decompress_message(data: bytes, where: str) -> bytes:
    """zstd-decompress one message (frames with or without content size)."""
    try:
        return zstandard.ZstdDecompressor().decompress(data)
    except zstandard.ZstdError:
        pass  # no content size in the frame header: stream it
    try:
        reader = zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data), read_across_frames=True)
        return reader.read()
    except zstandard.ZstdError as err:
        msg = f'{where}: message is not valid zstd: {err}'
        raise BagReadError(msg) from err


# --- the reader ----------------------------------------------------------------------------------


class BagReader(ClosesOnExit):
    """A rosbag2 bag opened for reading (see the module docstring).

    Use as a context manager or call :meth:`close`. Nothing is decoded until
    asked for.
    """

    def __init__(self, path: Path | str, types: MessageTypes | None = None, *,
                 allow_truncated: bool = False) -> None:
        """Open the bag: read ``metadata.yaml`` and every storage file's topics.

        Args:
            path: Bag directory, or one ``.db3`` / ``.mcap`` file (optionally
                ``.zstd``-compressed).
            types: Type store for types the bag has no definition of; a new
                :class:`MessageTypes` over ``AMENT_PREFIX_PATH`` when None.
            allow_truncated: read a storage file cut inside a record (messages
                lost) as far as it goes, listing it in :attr:`damage`, instead of
                refusing it. A file that merely lacks its summary (a recorder
                killed between chunks) loses nothing and is always read.

        Raises:
            BagReadError: No such path, bad ``metadata.yaml``, a listed file
                missing, a storage file unreadable, or (unless allow_truncated)
                truncated inside a record (each named).

        """
        self.path = Path(path)
        self.types = types
        self.warnings: list[str] = []
        #: storage files cut inside a record, and what was lost (read with allow_truncated)
        self.damage: list[str] = []
        self.allow_truncated = allow_truncated
        self.metadata: BagMetadata | None = None
        self.files: list[StorageFile] = []
        self._tmpdir: tempfile.TemporaryDirectory[str] | None = None
        self._typestore: Typestore | None = None
        self._local: Typestore | None = None
        self._local_only: set[str] = set()
        try:
            self._open()
        except BaseException:
            self.close()
            raise

    # -- opening --

    def _open(self) -> None:
        if not self.path.exists():
            msg = f'No bag at {self.path}'
            raise BagReadError(msg)
        if self.path.is_dir():
            metapath = self.path / METADATA_FILE
            if metapath.is_file():
                self.metadata = read_metadata_file(metapath)
                paths = self._listed_files(self.metadata)
            else:
                paths = storage_files(self.path)
                if not paths:
                    msg = f'No bag at {self.path}: no {METADATA_FILE} and no .db3/.mcap files'
                    raise BagReadError(msg)
                self.warnings.append(
                    f'{self.path}: no {METADATA_FILE}; read {len(paths)} storage file(s) found there')
        else:
            paths = [self.path]
        default = self.metadata.storage_identifier if self.metadata else 'sqlite3'
        for path in paths:
            self.files.append(self._open_file(path, default))
        if self.metadata is None:
            embedded = [f.embedded_metadata for f in self.files if f.embedded_metadata]
            self.metadata = embedded[-1] if embedded else None
        self._check_mode()
        self.topics = self._merge_topics()

    def _listed_files(self, meta: BagMetadata) -> list[Path]:
        paths = []
        for name in meta.relative_file_paths:
            candidates = [self.path / name, self.path / Path(name).name]
            if name.endswith(ZSTD_SUFFIX):  # crashed before compressing it
                candidates.append(self.path / Path(name).name.removesuffix(ZSTD_SUFFIX))
            found = next((c for c in candidates if c.is_file()), None)
            if found is None:
                msg = (f'{self.path / METADATA_FILE}: key relative_file_paths lists {name!r}, '
                       f'which is not in {self.path}')
                raise BagReadError(msg)
            paths.append(found)
        if not paths:
            self.warnings.append(f'{self.path / METADATA_FILE}: relative_file_paths is empty')
        unlisted = {p.name for p in storage_files(self.path)} - {p.name for p in paths}
        if unlisted:
            self.warnings.append(f'{self.path}: storage files not listed in {METADATA_FILE} '
                                 f'(not read): {sorted(unlisted)}')
        return paths

    def _open_file(self, path: Path, default: str) -> StorageFile:
        try:
            check_input(path, 'bag storage file')  # a FIFO or a device is refused, never opened (that would wait)
        except InputError as err:
            raise BagReadError(str(err)) from None
        opened = path
        if path.suffix == ZSTD_SUFFIX:
            opened = self._decompress_file(path)
        storage = _storage_of(opened, default)
        reader = STORAGE_READERS.get(storage)
        if reader is None:
            msg = f'{path}: unknown storage {storage!r}; known: {sorted(STORAGE_READERS)}'
            raise BagReadError(msg)
        opened_file = reader(opened, path.name)
        self.warnings.extend(getattr(opened_file, 'warnings', []))
        if damage := getattr(opened_file, 'damage', ''):
            if not self.allow_truncated:
                opened_file.close()
                msg = f'{damage} (--allow-truncated reads them)'
                raise BagReadError(msg)
            self.damage.append(damage)
            self.warnings.append(damage)
        return opened_file

    def _decompress_file(self, path: Path) -> Path:
        """Decompress a FILE-mode storage file into a private temporary directory."""
        if self._tmpdir is None:
            self._tmpdir = tempfile.TemporaryDirectory(prefix='bag_reader_')
        target = Path(self._tmpdir.name) / path.name.removesuffix(ZSTD_SUFFIX)
        try:
            with path.open('rb') as source, target.open('wb') as sink:
                reader = zstandard.ZstdDecompressor().stream_reader(source, read_across_frames=True)
                shutil.copyfileobj(reader, sink, 1 << 20)
        except (OSError, zstandard.ZstdError) as err:
            msg = f'Cannot decompress storage file {path}: {err}'
            raise BagReadError(msg) from err
        return target

    def _check_mode(self) -> None:
        meta = self.metadata
        if meta is None or not meta.compression_mode:
            return
        if meta.compression_format and meta.compression_format != 'zstd':
            msg = (f'{meta.source}: key compression_format is {meta.compression_format!r}; '
                   'only zstd is known')
            raise BagReadError(msg)
        if meta.compression_mode not in ('FILE', 'MESSAGE'):
            msg = f'{meta.source}: key compression_mode is {meta.compression_mode!r}'
            raise BagReadError(msg)

    def _merge_topics(self) -> dict[str, TopicInfo]:
        topics: dict[str, TopicInfo] = {}
        for storage in self.files:
            for st in storage.topics:
                have = topics.get(st.name)
                if have is None:
                    topics[st.name] = TopicInfo(
                        st.name, st.type, st.serialization_format, st.type_hash, st.definition,
                        st.offered_qos_profiles, files=[storage.name])
                    continue
                have.files.append(storage.name)
                if st.type != have.type:
                    self.warnings.append(f'{storage.name}: topic {st.name} has type {st.type}, '
                                         f'earlier files {have.type}')
                if have.definition is None or not have.definition.usable:
                    have.definition = st.definition
                have.type_hash = have.type_hash or st.type_hash
                if _qos_differs(have.offered_qos_profiles, st.offered_qos_profiles):
                    self.warnings.append(f'{st.name}: offered QoS differs between storage files '
                                         f'(ignored)')
        listed = self.metadata.topics if self.metadata and self.metadata.source.endswith(
            METADATA_FILE) else {}
        for name, record in listed.items():
            have = topics.get(name)
            if have is None:
                topics[name] = TopicInfo(name, record['type'], record['serialization_format'],
                                         record['type_description_hash'],
                                         offered_qos_profiles=record['offered_qos_profiles'],
                                         metadata_count=record['message_count'])
                if self.files:
                    self.warnings.append(f'{name}: listed in {METADATA_FILE} but in no storage file')
                continue
            have.metadata_count = record['message_count']
            if record['type'] != have.type:
                self.warnings.append(f'{name}: {METADATA_FILE} says type {record["type"]}, '
                                     f'storage says {have.type} (storage used)')
            if _qos_differs(have.offered_qos_profiles, record['offered_qos_profiles']):
                self.warnings.append(f'{name}: offered QoS in {METADATA_FILE} differs from the '
                                     'storage file (ignored: topics are matched by name)')
        return topics

    # -- reading --

    @property
    def compression_mode(self) -> str:
        """``''``, ``FILE`` or ``MESSAGE``."""
        return self.metadata.compression_mode if self.metadata else ''

    def raw_messages(self, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
        """Yield the messages of ``topics`` (all when None), decompressed, in storage order.

        Raises:
            BagReadError: A topic not in the bag, or a damaged file.

        """
        wanted = self._wanted(topics)
        for storage in self.files:
            for topic, timestamp, data in storage.messages(wanted):
                if data[:4] == ZSTD_MAGIC:  # MESSAGE mode; CDR starts with 0x00
                    data = _decompress_message(data, f'{storage.name}: {topic} at {timestamp} ns')
                yield BagMessage(topic, timestamp, data, storage.name)

    def count_messages(self, topics: Iterable[str] | None = None) -> dict[str, int]:
        """Messages per topic as read from storage (every listed topic, 0 if none).

        Also records a warning for each topic whose ``metadata.yaml`` count differs.
        """
        wanted = self._wanted(topics)
        counts = dict.fromkeys(sorted(wanted if wanted is not None else self.topics), 0)
        for storage in self.files:
            for topic, _timestamp, _data in storage.messages(wanted):
                counts[topic] = counts.get(topic, 0) + 1
        for name, count in counts.items():
            claimed = self.topics[name].metadata_count if name in self.topics else None
            if claimed is not None and claimed != count:
                note = (f'{name}: {METADATA_FILE} claims {claimed} messages, storage holds {count}')
                if note not in self.warnings:
                    self.warnings.append(note)
        return counts

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[DecodedMessage]:
        """Yield decoded messages of ``topics`` (all when None) in storage order.

        Raises:
            BagReadError: Unknown topic, no definition of its type, or bytes
                that do not decode (named with file, topic and time).

        """
        for message in self.raw_messages(topics):
            yield DecodedMessage(message.topic, message.timestamp,
                                 self.decode(message.topic, message.data, message.file,
                                             message.timestamp))

    def decode(self, topic: str, data: bytes, file: str = '', timestamp: int | None = None) -> Any:
        """Decode one message of ``topic`` from CDR.

        Raises:
            BagReadError: No definition of the topic's type, or undecodable bytes.

        """
        info = self.topics.get(topic)
        if info is None:
            msg = f'Bag {self.path} has no topic {topic!r}'
            raise BagReadError(msg)
        if info.serialization_format not in ('cdr', ''):
            msg = f'{topic}: serialization format {info.serialization_format!r} is not CDR'
            raise BagReadError(msg)
        if info.type in self._local_only:
            typestore = self._local_store(info.type)
        else:
            typestore = self.typestore_for(info.type)
        try:
            return deserialize_cdr(typestore, data, info.type)
        except BagReadError as err:
            where = f'{file or self.path}: {topic}' + (f' at {timestamp} ns' if timestamp is not None else '')
            if info.type in self._local_only or not self._embedded(info.type):
                msg = f'{where}: {err}'
                raise BagReadError(msg) from err
            first_error = err
        # The embedded definition does not fit the bytes (a bag doctored or written by a
        # buggy tool): try the local definition before giving up.
        try:
            decoded = deserialize_cdr(self._local_store(info.type), data, info.type)
        except BagRecordingError:
            msg = f'{where}: {first_error} (and the local definition does not fit either)'
            raise BagReadError(msg) from first_error
        self._local_only.add(info.type)
        self.warnings.append(f'{topic}: the embedded definition of {info.type} does not fit its '
                             f'messages ({first_error}); decoded with the local definition')
        return decoded

    def typestore_for(self, type_name: str) -> Typestore:
        """The bag's type store, made to know ``type_name``.

        Definitions embedded in the bag come first; types without one come
        from :class:`MessageTypes`. Built once, extended on demand.

        Raises:
            BagReadError: No definition of ``type_name`` anywhere.

        """
        store = self._typestore
        if store is None:
            store = self._typestore = self._embedded_store()
        if type_name not in store.fielddefs:
            self._add_local_type(store, type_name)
        return store

    def _embedded_store(self) -> Typestore:
        store = get_typestore(Stores.EMPTY)
        for info in self.topics.values():
            definition = info.definition
            if definition is None or not definition.usable or info.type in store.fielddefs:
                continue
            try:
                parsed = _parse_definition(definition, info.type)
                store.register({k: v for k, v in parsed.items() if k not in store.fielddefs})
            except (TypesysError, ValueError, AssertionError) as err:
                self.warnings.append(f'{info.name}: embedded definition of {info.type} does not '
                                     f'parse ({err}); using the local one')
                continue
            if info.type_hash.startswith('RIHS01_'):
                try:
                    computed = store.hash_rihs01(info.type)
                except (TypesysError, KeyError):
                    computed = ''
                if computed and computed != info.type_hash:
                    self.warnings.append(f'{info.name}: type hash {info.type_hash} in the bag, '
                                         f'{computed} from its embedded definition')
        return store

    def _embedded(self, type_name: str) -> bool:
        """Whether the bag's store holds ``type_name`` from an embedded definition."""
        return any(i.type == type_name and i.definition is not None and i.definition.usable
                   for i in self.topics.values())

    def _local_store(self, type_name: str) -> Typestore:
        """A store with only local definitions (stock + ament), made to know ``type_name``."""
        if self._local is None:
            self._local = get_typestore(Stores.EMPTY)
        if type_name not in self._local.fielddefs:
            self._add_local_type(self._local, type_name)
        return self._local

    def _add_local_type(self, store: Typestore, type_name: str) -> None:
        types = self.types if self.types is not None else MessageTypes()
        self.types = types
        try:
            name = types.ensure(type_name)
        except BagRecordingError as err:
            msg = f'Bag {self.path} has no definition of {type_name!r}, and: {err}'
            raise BagReadError(msg) from err
        needed: dict[str, Any] = {}
        pending = [name]
        while pending:
            current = pending.pop()
            if current in needed or current in store.fielddefs:
                continue
            needed[current] = types.typestore.fielddefs[current]
            _consts, fields = needed[current]
            pending.extend(ref for _field, desc in fields for ref in referenced_types(desc))
        try:
            store.register(needed)
        except TypesysError as err:
            msg = f'Cannot add the local definition of {type_name!r} for bag {self.path}: {err}'
            raise BagReadError(msg) from err

    def _wanted(self, topics: Iterable[str] | None) -> set[str] | None:
        if topics is None:
            return None
        wanted = set(topics)
        if unknown := sorted(wanted - self.topics.keys()):
            msg = f'Bag {self.path} has no topic {unknown[0]!r}; it has {sorted(self.topics)}'
            raise BagReadError(msg)
        return wanted

    # -- summary --

    @property
    def storage_identifier(self) -> str:
        """``sqlite3`` or ``mcap`` (of the first file)."""
        if self.files:
            return 'mcap' if isinstance(self.files[0], McapFile) else 'sqlite3'
        return self.metadata.storage_identifier if self.metadata else ''

    def file_names(self) -> list[str]:
        """The storage files read, in order (names in the bag)."""
        return [f.name for f in self.files]

    # -- lifetime --

    def close(self) -> None:
        """Close every file and remove decompressed copies (idempotent)."""
        for storage in self.files:
            storage.close()
        self.files = []
        if self._tmpdir is not None:
            self._tmpdir.cleanup()
            self._tmpdir = None


def _parse_definition(definition: MessageDefinition, type_name: str) -> dict[str, Any]:
    """Types of an embedded definition (rosbag2's concatenated ``ros2msg``/``ros2idl``)."""
    if definition.encoding == 'ros2msg':
        return dict(get_types_from_msg(definition.text, type_name))
    parsed: dict[str, Any] = {}
    if definition.text.startswith(f'{DEFINITION_SEPARATOR}IDL: '):
        for section in definition.text.split(DEFINITION_SEPARATOR)[1:]:
            _header, idl = section.split('\n', 1)
            parsed.update(get_types_from_idl(idl))
    else:
        parsed.update(get_types_from_idl(definition.text))
    return parsed


# --- QoS comparison (for warnings only) ----------------------------------------------------------

_POLICY_NAMES: Final[Mapping[str, Mapping[int, str]]] = {
    'history': {0: 'system_default', 1: 'keep_last', 2: 'keep_all', 3: 'unknown'},
    'reliability': {0: 'system_default', 1: 'reliable', 2: 'best_effort', 3: 'unknown',
                    4: 'best_available'},
    'durability': {0: 'system_default', 1: 'transient_local', 2: 'volatile', 3: 'unknown',
                   4: 'best_available'},
    'liveliness': {0: 'system_default', 1: 'automatic', 2: 'manual_by_node', 3: 'manual_by_topic',
                   4: 'unknown', 5: 'best_available'},
}


def normalize_qos(profiles: object) -> list[dict[str, Any]] | None:
    """Offered-QoS profiles (YAML text or parsed list) as comparable dicts; None if unparsable."""
    if isinstance(profiles, str):
        if not profiles.strip():
            return []
        try:
            profiles = YAML(typ='safe', pure=True).load(profiles)
        except YAMLError:
            return None
    if profiles is None:
        return []
    if not isinstance(profiles, list):
        return None
    out = []
    for profile in profiles:
        if not isinstance(profile, Mapping):
            return None
        item = dict(profile)
        for policy, names in _POLICY_NAMES.items():
            value = item.get(policy)
            if isinstance(value, int):
                item[policy] = names.get(value, str(value))
            elif isinstance(value, str):
                item[policy] = value.lower()
        out.append(item)
    return out


def _qos_differs(a: object, b: object) -> bool:
    """Whether two offered-QoS texts describe different profiles (empty matches anything)."""
    qa, qb = normalize_qos(a), normalize_qos(b)
    if not qa or not qb:
        return False
    return qa != qb
