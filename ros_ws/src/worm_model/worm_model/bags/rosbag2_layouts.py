"""Write bags laid out exactly as the real rosbag2 writes them, for tests without rosbag2.

rosbag2 is not on PyPI, so ``ros2 bag record`` cannot run here. This module
writes, from our own messages, the files each rosbag2 release would have
written for them, so the reader (:mod:`worm_model.bags.reader`) is
tested against every layout a user may hand it. Nothing of rosbag2 is copied;
each detail below was read in the rosbag2 sources (github ros2/rosbag2, at
the release tag named in :data:`LAYOUTS`) and is re-expressed here:

``metadata.yaml`` (what :func:`yaml_cpp_dump` reproduces character for character)
    ``rosbag2_storage/src/rosbag2_storage/metadata_io.cpp`` (0.3.11,
    0.15.12) and ``rosbag2_storage/include/rosbag2_storage/yaml.hpp`` (0.21.0
    on): the key order of ``convert<BagMetadata>::encode`` per release,
    written through yaml-cpp's emitter (block style, sequences indented
    under their key, ``""`` for empty strings, ``~`` for an empty
    ``custom_data``, no final newline). QoS: ``rosbag2_transport/src/
    rosbag2_transport/qos.cpp`` (0.3.11) and ``rosbag2_storage/src/
    rosbag2_storage/qos.cpp`` (0.26.5): before version 9 a YAML text
    (``YAML::Dump`` of the profiles, policies as integers) stored as a string;
    from 9 on nested YAML with policy names (``keep_last``, ``best_effort``...).
sqlite3 (same SQL text, pragmas, tables and rows; not the same bytes, which
depend on the SQLite library)
    ``rosbag2_storage_default_plugins/src/.../sqlite/sqlite_storage.cpp`` and
    ``sqlite_wrapper.cpp`` (0.3.11: WAL journal; 0.15.12: schema 3 with the
    ``schema`` and ``metadata`` tables, ``journal_mode=MEMORY``);
    ``rosbag2_storage_sqlite3/src/.../sqlite_storage.cpp`` (0.21.0; 0.22.7
    on: schema 4, ``type_description_hash`` and ``message_definitions``, the
    ``metadata`` table filled by ``update_metadata`` at open, split and close).
MCAP (same records and fields; chunk layout and CRCs are the Python mcap
writer's)
    ``rosbag2_storage_mcap/src/mcap_storage.cpp`` (0.15.12, 0.21.0, 0.22.7,
    0.24.0, 0.26.5): profile ``ros2``, library ``libmcap <mcap_vendor version>``
    (``mcap_vendor/CMakeLists.txt``), no chunk compression, schema per type
    (``ros2msg``), channel metadata ``offered_qos_profiles`` (+
    ``topic_type_hash`` from 0.22), metadata record ``rosbag2`` holding
    ``ROS_DISTRO`` (once at open in 0.15/0.22, at each metadata update in
    0.24) or ``serialized_metadata`` (0.26), message ``sequence`` 0.
Message definitions
    ``rosbag2_cpp/src/rosbag2_cpp/message_definitions/
    local_message_definition_source.cpp`` (0.26.5): the ``.msg`` text, then
    each dependency (sorted, found by a field-type pattern) after a line of 80
    ``=`` and ``MSG: <type as written>``.
Compression (``rosbag2_compression/src/.../sequential_compression_writer.cpp``,
``rosbag2_compression_zstd/src/.../zstd_compressor.cpp``)
    ``FILE``: each closed storage file is zstd-compressed as a stream (no
    content size; the context's default level 3) into ``<file>.zstd`` and
    removed; ``relative_file_paths`` gets the new names, ``files[].path``
    keeps the old ones. ``MESSAGE``: each message is compressed on its own
    at level 1. ``compression_mode`` is written ``FILE``/``MESSAGE``.
Splitting (``rosbag2_cpp/src/rosbag2_cpp/writers/sequential_writer.cpp``)
    ``<bag>_<n>.<ext>``; a message whose receive time is more than
    ``max_bagfile_duration`` after the current file's first message opens
    the next file first; every topic is re-created in the new file.
``ros2 bag reindex`` (``rosbag2_cpp/src/rosbag2_cpp/reindexer.cpp``, 0.26.5)
    :func:`reindex` rewrites ``metadata.yaml`` from the storage files as
    Jazzy's reindexer does: QoS decoded (Foxy-era "infinite" durations
    translated to ``RMW_DURATION_INFINITE``) and re-encoded in the version-9
    form, the last file's profiles kept for a topic of several files. Such a
    bag disagrees with its storage files about the offered QoS, the case in
    which ``rosbags``' directory reader yields no message.

Not reproduced: the topic order of ``metadata.yaml`` (rosbag2 walks a
``std::unordered_map``; here topics keep their creation order) and v4 MCAP
(written only by the separate ros-tooling plugin, not by rosbag2 0.3).
"""

from __future__ import annotations

import json
import re
import sqlite3
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Final

import zstandard
from mcap.writer import CompressionType, Writer

from worm_model.bags.reader import BagReader, normalize_qos
from worm_model.bags.typestore import ament_prefixes, normalize_type_name

__all__ = [
    'LAYOUTS',
    'FixtureTopic',
    'Layout',
    'QosProfile',
    'message_definition_text',
    'reindex',
    'type_hash',
    'write_rosbag2_bag',
    'yaml_cpp_dump',
]

INT64_MAX: Final[int] = 2**63 - 1
RMW_DURATION_INFINITE: Final[tuple[int, int]] = (9223372036, 854775807)
"""rmw's infinite duration (sec, nsec), Galactic on."""
FOXY_FASTRTPS_INFINITE: Final[tuple[int, int]] = (0x7FFFFFFF, 0xFFFFFFFF)
"""What rmw_fastrtps reported for "infinite" in Foxy (qos.cpp translates it on reading)."""
FOXY_INFINITES: Final[tuple[tuple[int, int], ...]] = (
    FOXY_FASTRTPS_INFINITE, (0x7FFFFFFF, 0x7FFFFFFF), divmod(INT64_MAX, 1_000_000_000))


@dataclass(frozen=True)
class Layout:
    """What one rosbag2 release writes."""

    name: str
    release: str
    """rosbag2 release tag the details were read at."""
    ros_distro: str
    version: int
    """metadata.yaml ``version``."""
    sqlite_schema: int
    """2: topics+messages only; 3: + ``schema``, ``metadata``; 4: + definitions, hashes."""
    sqlite_pragmas: tuple[str, ...]
    sqlite_metadata_rows: bool
    """Whether ``update_metadata`` writes rows into the sqlite ``metadata`` table."""
    mcap_library: str | None
    """Header ``library`` of the MCAP files; None: no MCAP storage in this release."""
    mcap_metadata: str
    """``''``: none; ``distro_at_open``; ``distro_per_update``; ``serialized_per_update``."""
    metadata_updates: bool
    """Whether the writer calls ``storage->update_metadata`` at open, split and close."""
    key_order: tuple[str, ...]
    """Keys of ``rosbag2_bagfile_information`` in the order written."""
    topic_keys: tuple[str, ...]
    """Keys of ``topic_metadata`` in the order written."""

    @property
    def storages(self) -> tuple[str, ...]:
        """Storage identifiers this release can write."""
        return ('sqlite3', 'mcap') if self.mcap_library else ('sqlite3',)


_V4_KEYS = ('version', 'storage_identifier', 'relative_file_paths', 'duration', 'starting_time',
            'message_count', 'topics_with_message_count', 'compression_format', 'compression_mode')
_V5_KEYS = ('version', 'storage_identifier', 'duration', 'starting_time', 'message_count',
            'topics_with_message_count', 'compression_format', 'compression_mode',
            'relative_file_paths', 'files')
_TOPIC_KEYS = ('name', 'type', 'serialization_format', 'offered_qos_profiles')
_FAST_WRITE = ('PRAGMA schema_version;', 'PRAGMA journal_mode=MEMORY;', 'PRAGMA synchronous=OFF;')

LAYOUTS: Final[Mapping[str, Layout]] = {
    layout.name: layout for layout in (
        Layout('foxy', '0.3.11', 'foxy', 4, 2,
               ('PRAGMA journal_mode = WAL;', 'PRAGMA synchronous = NORMAL;'), False,
               None, '', False, _V4_KEYS, _TOPIC_KEYS),
        Layout('humble', '0.15.12', 'humble', 5, 3, _FAST_WRITE, False,
               'libmcap 0.8.0', 'distro_at_open', False, _V5_KEYS, _TOPIC_KEYS),
        Layout('rolling-0.21', '0.21.0', 'rolling', 6, 3, _FAST_WRITE, False,
               'libmcap 0.8.0', '', True, (*_V5_KEYS, 'custom_data'), _TOPIC_KEYS),
        Layout('iron', '0.22.7', 'iron', 7, 4, _FAST_WRITE, True,
               'libmcap 0.8.0', 'distro_at_open', True, (*_V5_KEYS, 'custom_data'),
               (*_TOPIC_KEYS, 'type_description_hash')),
        Layout('rolling-0.24', '0.24.0', 'rolling', 8, 4, _FAST_WRITE, True,
               'libmcap 1.1.0', 'distro_per_update', True, (*_V5_KEYS, 'custom_data', 'ros_distro'),
               (*_TOPIC_KEYS, 'type_description_hash')),
        Layout('jazzy', '0.26.5', 'jazzy', 9, 4, _FAST_WRITE, True,
               'libmcap 1.3.0', 'serialized_per_update', True,
               (*_V5_KEYS, 'custom_data', 'ros_distro'), (*_TOPIC_KEYS, 'type_description_hash')),
    )
}
"""One layout per metadata version 4..9, by name."""

_SQLITE_TABLES: Final[Mapping[str, str]] = {
    'schema': 'CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);',
    'metadata': ('CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,'
                 'metadata TEXT NOT NULL);'),
    'topics2': ('CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,'
                'serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL);'),
    'topics4': ('CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,'
                'serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL,'
                'type_description_hash TEXT NOT NULL);'),
    'message_definitions': ('CREATE TABLE message_definitions(id INTEGER PRIMARY KEY,'
                            'topic_type TEXT NOT NULL,encoding TEXT NOT NULL,'
                            'encoded_message_definition TEXT NOT NULL,'
                            'type_description_hash TEXT NOT NULL);'),
    'messages': ('CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,'
                 'timestamp INTEGER NOT NULL, data BLOB NOT NULL);'),
    'index': 'CREATE INDEX timestamp_idx ON messages (timestamp ASC);',
}
"""The DDL as rosbag2 concatenates it (the schema SQL stored in ``sqlite_master``)."""

_SCHEMA_TABLES: Final[Mapping[int, tuple[str, ...]]] = {
    2: ('topics2', 'messages', 'index'),
    3: ('schema', 'metadata', 'topics2', 'messages', 'index'),
    4: ('schema', 'metadata', 'topics4', 'message_definitions', 'messages', 'index'),
}

# --- yaml-cpp's emitter ---------------------------------------------------------------------------

_NULL_STRINGS: Final[frozenset[str]] = frozenset({'~', 'null', 'Null', 'NULL'})
_INDICATORS: Final[str] = ',[]{}#&*!|>\'"%@`'
_ESCAPES: Final[Mapping[str, str]] = {'"': '\\"', '\\': '\\\\', '\n': '\\n', '\t': '\\t',
                                      '\r': '\\r', '\b': '\\b', '\f': '\\f'}


def _plain(text: str) -> bool:
    """Whether yaml-cpp writes ``text`` unquoted (its ``IsValidPlainScalar``, block context)."""
    if not text or text in _NULL_STRINGS or text[0] in _INDICATORS or text[0] in ' \t':
        return False
    if text[0] in '-?:' and (len(text) == 1 or text[1] in ' \t\n'):
        return False
    if text[-1] in ' \t' or text.endswith(':'):
        return False
    if ': ' in text or ' #' in text or '\t' in text or '\n' in text or '\r' in text:
        return False
    return all(ch.isprintable() for ch in text)


def _scalar(value: Any) -> str:
    if value is None:
        return '~'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    text = str(value)
    if _plain(text):
        return text
    escaped = ''.join(_ESCAPES.get(ch, ch if ch.isprintable() else f'\\x{ord(ch):02x}')
                      for ch in text)
    return f'"{escaped}"'


def _is_block(value: Any) -> bool:
    return isinstance(value, (Mapping, list, tuple)) and len(value) > 0


def _empty(value: Any) -> str:
    return '{}' if isinstance(value, Mapping) else '[]'


def _emit_map(node: Mapping[str, Any], indent: int, out: list[str], first_prefix: str = '') -> None:
    for i, (key, value) in enumerate(node.items()):
        lead = first_prefix if i == 0 and first_prefix else ' ' * indent
        if _is_block(value):
            out.append(f'{lead}{key}:')
            _emit_block(value, indent + 2, out)
        elif isinstance(value, (Mapping, list, tuple)):
            out.append(f'{lead}{key}: {_empty(value)}')
        else:
            out.append(f'{lead}{key}: {_scalar(value)}')


def _emit_block(node: Any, indent: int, out: list[str]) -> None:
    if isinstance(node, Mapping):
        _emit_map(node, indent, out)
        return
    for item in node:
        lead = ' ' * indent + '- '
        if isinstance(item, Mapping) and item:
            _emit_map(item, indent + 2, out, first_prefix=lead)
        elif _is_block(item):
            out.append(lead.rstrip())
            _emit_block(item, indent + 2, out)
        elif isinstance(item, (Mapping, list, tuple)):
            out.append(f'{lead}{_empty(item)}')
        else:
            out.append(f'{lead}{_scalar(item)}')


def yaml_cpp_dump(node: Any) -> str:
    """Serialize like yaml-cpp's ``YAML::Dump`` / ``operator<<``: block style, no final newline."""
    if not _is_block(node):
        return _empty(node) if isinstance(node, (Mapping, list, tuple)) else _scalar(node)
    out: list[str] = []
    _emit_block(node, 0, out)
    return '\n'.join(out)


# --- QoS -----------------------------------------------------------------------------------------

_HISTORY = {0: 'system_default', 1: 'keep_last', 2: 'keep_all', 3: 'unknown'}
_RELIABILITY = {0: 'system_default', 1: 'reliable', 2: 'best_effort', 3: 'unknown',
                4: 'best_available'}
_DURABILITY = {0: 'system_default', 1: 'transient_local', 2: 'volatile', 3: 'unknown',
               4: 'best_available'}
_LIVELINESS = {0: 'system_default', 1: 'automatic', 3: 'manual_by_topic', 4: 'unknown',
               5: 'best_available'}


@dataclass(frozen=True)
class QosProfile:
    """A publisher's offered QoS as rosbag2 records it (rmw enum integers, durations sec/nsec).

    Defaults: what the graph reports for a sensor-data publisher (history is
    not communicated by DDS, so it reads UNKNOWN with depth 0).
    """

    history: int = 3
    depth: int = 0
    reliability: int = 2
    durability: int = 2
    deadline: tuple[int, int] = RMW_DURATION_INFINITE
    lifespan: tuple[int, int] = RMW_DURATION_INFINITE
    liveliness: int = 1
    liveliness_lease_duration: tuple[int, int] = RMW_DURATION_INFINITE
    avoid_ros_namespace_conventions: bool = False

    def node(self, names: bool) -> dict[str, Any]:
        """The YAML node of ``convert<rclcpp::QoS>::encode``; policy names for version >= 9."""
        def policy(value: int, table: Mapping[int, str]) -> int | str:
            return table.get(value, 'unknown') if names else value

        return {
            'history': policy(self.history, _HISTORY),
            'depth': self.depth,
            'reliability': policy(self.reliability, _RELIABILITY),
            'durability': policy(self.durability, _DURABILITY),
            'deadline': {'sec': self.deadline[0], 'nsec': self.deadline[1]},
            'lifespan': {'sec': self.lifespan[0], 'nsec': self.lifespan[1]},
            'liveliness': policy(self.liveliness, _LIVELINESS),
            'liveliness_lease_duration': {'sec': self.liveliness_lease_duration[0],
                                          'nsec': self.liveliness_lease_duration[1]},
            'avoid_ros_namespace_conventions': self.avoid_ros_namespace_conventions,
        }

    @classmethod
    def foxy(cls, **kwargs: Any) -> QosProfile:
        """A profile as rmw_fastrtps reported it in Foxy (its own "infinite")."""
        infinite = FOXY_FASTRTPS_INFINITE
        return cls(**{'deadline': infinite, 'lifespan': infinite,
                      'liveliness_lease_duration': infinite, **kwargs})

    @classmethod
    def from_node(cls, node: Mapping[str, Any]) -> QosProfile:
        """Decode as rosbag2 0.26 does, translating Foxy-era infinities (qos.cpp)."""
        def policy(value: Any, table: Mapping[int, str]) -> int:
            if isinstance(value, int):
                return value
            reverse = {name: code for code, name in table.items()}
            return reverse.get(str(value).lower(), 3)

        def duration(value: Mapping[str, int]) -> tuple[int, int]:
            pair = (int(value['sec']), int(value['nsec']))
            return RMW_DURATION_INFINITE if pair in FOXY_INFINITES else pair

        return cls(
            history=policy(node['history'], _HISTORY),
            depth=int(node['depth']),
            reliability=policy(node['reliability'], _RELIABILITY),
            durability=policy(node['durability'], _DURABILITY),
            deadline=duration(node['deadline']),
            lifespan=duration(node['lifespan']),
            liveliness=policy(node['liveliness'], _LIVELINESS),
            liveliness_lease_duration=duration(node['liveliness_lease_duration']),
            avoid_ros_namespace_conventions=bool(node['avoid_ros_namespace_conventions']),
        )


def qos_text(profiles: Sequence[QosProfile], version: int) -> str:
    """``serialize_rclcpp_qos_vector``: what storage files hold (and metadata before v9)."""
    return yaml_cpp_dump([p.node(version >= 9) for p in profiles])


# --- message definitions and hashes --------------------------------------------------------------

_FIELD_TYPE: Final[re.Pattern[str]] = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES: Final[frozenset[str]] = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string'})


def _share_dirs() -> list[Path]:
    return [p / 'share' for p in (*ament_prefixes(), Path(sys.prefix))]


def _interface_file(type_name: str, suffix: str) -> Path:
    package, _kind, name = normalize_type_name(type_name).split('/')
    for share in _share_dirs():
        if (path := share / package / 'msg' / f'{name}{suffix}').is_file():
            return path
    msg = f'No {suffix} file for {type_name} under {[str(s) for s in _share_dirs()]}'
    raise FileNotFoundError(msg)


def message_definition_text(type_name: str) -> str:
    """rosbag2's concatenated ``ros2msg`` definition of ``type_name`` (see module docstring)."""
    seen: set[str] = set()

    def expand(name: str, text: str) -> str:
        package = normalize_type_name(name).split('/')[0]
        dependencies = set()
        for match in _FIELD_TYPE.finditer(text):
            field_type = match.group(1)
            if field_type in _PRIMITIVES:
                continue
            dependencies.add(field_type if '/' in field_type else f'{package}/{field_type}')
        result = text
        for dependency in sorted(dependencies):
            if dependency in seen:
                continue
            seen.add(dependency)
            dep_text = _interface_file(dependency, '.msg').read_text(encoding='utf-8')
            result += '\n' + '=' * 80 + '\n' + f'MSG: {dependency}\n' + expand(dependency, dep_text)
        return result

    return expand(type_name, _interface_file(type_name, '.msg').read_text(encoding='utf-8'))


def type_hash(type_name: str) -> str:
    """The RIHS01 hash rosidl generated for ``type_name`` (its ``.json`` type description)."""
    name = normalize_type_name(type_name)
    description = json.loads(_interface_file(name, '.json').read_text(encoding='utf-8'))
    return next(h['hash_string'] for h in description['type_hashes'] if h['type_name'] == name)


# --- the writer ----------------------------------------------------------------------------------


@dataclass
class FixtureTopic:
    """A topic of a fixture bag."""

    name: str
    type: str
    offered_qos: Sequence[QosProfile] = (QosProfile(),)
    definition: str | None = None
    """Full ``ros2msg`` text; None: :func:`message_definition_text` of the type."""
    hash: str | None = None
    """RIHS01 hash; None: :func:`type_hash` of the type."""

    def resolved(self) -> FixtureTopic:
        """With definition and hash filled in."""
        return replace(
            self,
            definition=self.definition if self.definition is not None else
            message_definition_text(self.type),
            hash=self.hash if self.hash is not None else type_hash(self.type))


@dataclass
class _FileStats:
    path: str
    starting_time: int = INT64_MAX
    end_time: int = 0
    message_count: int = 0

    @property
    def duration(self) -> int:
        return max(0, self.end_time - self.starting_time) if self.message_count else 0


@dataclass
class _BagState:
    layout: Layout
    storage: str
    topics: list[FixtureTopic]
    compression: str
    ros_distro: str
    custom_data: dict[str, str]
    files: list[_FileStats] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    relative_file_paths: list[str] = field(default_factory=list)

    def metadata_node(self) -> dict[str, Any]:
        """``convert<BagMetadata>::encode`` of the current state, in the layout's key order."""
        layout = self.layout
        names = layout.version >= 9
        start = min((f.starting_time for f in self.files if f.message_count), default=INT64_MAX)
        end = max((f.end_time for f in self.files if f.message_count), default=0)
        topic_nodes = []
        for topic in self.topics:
            qos: Any = ([p.node(names) for p in topic.offered_qos] if names
                        else qos_text(topic.offered_qos, layout.version))
            values = {'name': topic.name, 'type': topic.type, 'serialization_format': 'cdr',
                      'offered_qos_profiles': qos, 'type_description_hash': topic.hash or ''}
            topic_nodes.append({'topic_metadata': {k: values[k] for k in layout.topic_keys},
                                'message_count': self.counts.get(topic.name, 0)})
        values: dict[str, Any] = {
            'version': layout.version,
            'storage_identifier': self.storage,
            'relative_file_paths': list(self.relative_file_paths),
            'duration': {'nanoseconds': max(0, end - start) if end else 0},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': sum(self.counts.values()),
            'topics_with_message_count': topic_nodes,
            'compression_format': 'zstd' if self.compression else '',
            'compression_mode': self.compression.upper(),
            'files': [{'path': f.path,
                       'starting_time': {'nanoseconds_since_epoch': f.starting_time},
                       'duration': {'nanoseconds': f.duration},
                       'message_count': f.message_count} for f in self.files],
            'custom_data': dict(self.custom_data) or None,
            'ros_distro': self.ros_distro,
        }
        return {k: values[k] for k in layout.key_order}


class _Sqlite3Storage:
    def __init__(self, path: Path, state: _BagState) -> None:
        self.state = state
        layout = state.layout
        self.db = sqlite3.connect(path, isolation_level=None)
        for pragma in layout.sqlite_pragmas:
            self.db.execute(pragma).fetchall()
        for table in _SCHEMA_TABLES[layout.sqlite_schema]:
            self.db.execute(_SQLITE_TABLES[table])
        if layout.sqlite_schema >= 3:
            self.db.execute('INSERT INTO schema (schema_version, ros_distro) VALUES (?, ?)',
                            (layout.sqlite_schema, state.ros_distro))
        self.ids: dict[str, int] = {}
        self.definitions: set[str] = set()
        self.db.execute('BEGIN TRANSACTION;')

    def update_metadata(self) -> None:
        if self.state.layout.sqlite_metadata_rows:
            self.db.execute('INSERT INTO metadata (metadata_version, metadata) VALUES (?, ?)',
                            (self.state.layout.version, yaml_cpp_dump(self.state.metadata_node())))

    def create_topic(self, topic: FixtureTopic) -> None:
        layout = self.state.layout
        qos = qos_text(topic.offered_qos, layout.version)
        if layout.sqlite_schema >= 4:
            cursor = self.db.execute(
                'INSERT INTO topics(name, type, serialization_format, offered_qos_profiles, '
                'type_description_hash) VALUES (?, ?, ?, ?, ?)',
                (topic.name, topic.type, 'cdr', qos, topic.hash))
            if topic.type not in self.definitions:
                self.definitions.add(topic.type)
                self.db.execute(
                    'INSERT INTO message_definitions (topic_type, encoding, '
                    'encoded_message_definition, type_description_hash) VALUES (?, ?, ?, ?)',
                    (topic.type, 'ros2msg', topic.definition, topic.hash))
        else:
            cursor = self.db.execute(
                'INSERT INTO topics (name, type, serialization_format, offered_qos_profiles) '
                'VALUES (?, ?, ?, ?)', (topic.name, topic.type, 'cdr', qos))
        assert cursor.lastrowid is not None
        self.ids[topic.name] = cursor.lastrowid

    def write(self, topic: str, timestamp: int, data: bytes) -> None:
        self.db.execute('INSERT INTO messages (timestamp, topic_id, data) VALUES (?, ?, ?);',
                        (timestamp, self.ids[topic], sqlite3.Binary(data)))

    def close(self) -> None:
        self.db.execute('COMMIT;')
        self.db.close()


class _McapStorage:
    def __init__(self, path: Path, state: _BagState) -> None:
        self.state = state
        layout = state.layout
        assert layout.mcap_library is not None
        self.stream = path.open('wb')
        # rosbag2: chunkSize 768 KiB (mcap default), no chunk compression, noChunkCRC.
        self.writer = Writer(self.stream, chunk_size=768 * 1024, compression=CompressionType.NONE)
        self.writer.start(profile='ros2', library=layout.mcap_library)
        if layout.mcap_metadata == 'distro_at_open':
            self.writer.add_metadata('rosbag2', {'ROS_DISTRO': state.ros_distro})
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}

    def update_metadata(self) -> None:
        kind = self.state.layout.mcap_metadata
        if kind == 'distro_per_update':
            self.writer.add_metadata('rosbag2', {'ROS_DISTRO': self.state.ros_distro})
        elif kind == 'serialized_per_update':
            self.writer.add_metadata(
                'rosbag2', {'serialized_metadata': yaml_cpp_dump(self.state.metadata_node())})

    def create_topic(self, topic: FixtureTopic) -> None:
        if topic.type not in self.schemas:
            self.schemas[topic.type] = self.writer.register_schema(
                topic.type, 'ros2msg', (topic.definition or '').encode('utf-8'))
        metadata = {'offered_qos_profiles': qos_text(topic.offered_qos, self.state.layout.version)}
        if self.state.layout.version >= 7:
            metadata['topic_type_hash'] = topic.hash or ''
        self.channels[topic.name] = self.writer.register_channel(
            topic.name, 'cdr', self.schemas[topic.type], metadata)

    def write(self, topic: str, timestamp: int, data: bytes) -> None:
        self.writer.add_message(self.channels[topic], log_time=timestamp, data=data,
                                publish_time=timestamp, sequence=0)

    def close(self) -> None:
        self.writer.finish()
        self.stream.close()


_STORAGES: Final[Mapping[str, tuple[str, type]]] = {
    'sqlite3': ('.db3', _Sqlite3Storage),
    'mcap': ('.mcap', _McapStorage),
}


def _compress_file(path: Path) -> Path:
    """FILE mode: stream-compress ``path`` to ``path.zstd`` (no content size) and remove it."""
    target = path.with_name(path.name + '.zstd')
    compressor = zstandard.ZstdCompressor(level=3, write_content_size=False)
    with path.open('rb') as source, target.open('wb') as sink:
        compressor.copy_stream(source, sink, read_size=zstandard.COMPRESSION_RECOMMENDED_INPUT_SIZE)
    path.unlink()
    return target


def write_rosbag2_bag(
    path: Path | str,
    layout: Layout | str,
    storage: str,
    topics: Sequence[FixtureTopic],
    messages: Iterable[tuple[str, int, bytes]],
    *,
    compression: str = '',
    max_bagfile_duration_ns: int | None = None,
    ros_distro: str | None = None,
    custom_data: Mapping[str, str] | None = None,
) -> Path:
    """Write a bag as rosbag2 release ``layout`` records it (see the module docstring).

    Args:
        path: Bag directory to create (must not exist).
        layout: A :class:`Layout` or its name in :data:`LAYOUTS`.
        storage: ``sqlite3`` or ``mcap``.
        topics: Topics, created in this order before the first message.
        messages: ``(topic, receive_time_ns, cdr_bytes)`` in receive order.
        compression: ``''``, ``'file'`` or ``'message'`` (zstd).
        max_bagfile_duration_ns: Split as ``--max-bag-duration`` does.
        ros_distro: ``ROS_DISTRO`` of the recording; the layout's by default.
        custom_data: ``--custom-data`` key/values (version 6 on).

    Returns:
        The bag directory.

    Raises:
        ValueError: A combination the release cannot write (MCAP before 0.15,
            message compression with MCAP from 0.26 on).

    """
    layout = LAYOUTS[layout] if isinstance(layout, str) else layout
    if storage not in layout.storages:
        msg = f'rosbag2 {layout.release} ({layout.name}) cannot write {storage!r}'
        raise ValueError(msg)
    if compression not in ('', 'file', 'message'):
        msg = f'compression {compression!r}: expected "", "file" or "message"'
        raise ValueError(msg)
    if compression == 'message' and storage == 'mcap' and layout.version >= 9:
        msg = 'rosbag2 0.26 refuses message compression with MCAP (mcap_storage.cpp)'
        raise ValueError(msg)
    bag = Path(path)
    bag.mkdir(parents=True)
    state = _BagState(layout, storage, [t.resolved() for t in topics], compression,
                      layout.ros_distro if ros_distro is None else ros_distro,
                      dict(custom_data or {}))
    suffix, storage_class = _STORAGES[storage]
    message_compressor = zstandard.ZstdCompressor(level=1)
    closed: list[Path] = []

    def open_file() -> Any:
        name = f'{bag.name}_{len(state.files)}{suffix}'
        state.files.append(_FileStats(name))
        state.relative_file_paths.append(name)
        opened = storage_class(bag / name, state)
        if layout.metadata_updates:
            opened.update_metadata()
        for topic in state.topics:
            opened.create_topic(topic)
        return opened

    current = open_file()
    for topic, timestamp, data in messages:
        stats = state.files[-1]
        if (max_bagfile_duration_ns is not None and stats.message_count
                and timestamp - stats.starting_time > max_bagfile_duration_ns):
            if layout.metadata_updates:
                current.update_metadata()
            current.close()
            closed.append(bag / stats.path)
            current = open_file()
            stats = state.files[-1]
        if compression == 'message':
            data = message_compressor.compress(data)
        current.write(topic, timestamp, data)
        stats.message_count += 1
        stats.starting_time = min(stats.starting_time, timestamp)
        stats.end_time = max(stats.end_time, timestamp)
        state.counts[topic] = state.counts.get(topic, 0) + 1
    if layout.metadata_updates:
        current.update_metadata()
    current.close()
    closed.append(bag / state.files[-1].path)
    if compression == 'file':
        for index, file in enumerate(closed):
            state.relative_file_paths[index] = _compress_file(file).name
    (bag / 'metadata.yaml').write_text(
        yaml_cpp_dump({'rosbag2_bagfile_information': state.metadata_node()}), encoding='utf-8')
    return bag


def reindex(path: Path | str) -> None:
    """Rewrite ``metadata.yaml`` from the storage files as ``ros2 bag reindex`` of Jazzy does.

    Topics, counts and times come from the files; offered QoS is decoded from
    each file (Foxy-era infinite durations translated, as ``qos.cpp`` of 0.26
    does) and re-encoded in the version-9 form; for a topic in several files
    the last file's profiles win (``reindexer.cpp``). Other keys are kept.
    """
    bag = Path(path)
    with BagReader(bag) as reader:
        old = reader.metadata
        assert old is not None
        counts = reader.count_messages()
        topics: dict[str, dict[str, Any]] = {}
        for storage in reader.files:
            for st in storage.topics:
                profiles = normalize_qos(st.offered_qos_profiles) or []
                nodes = [QosProfile.from_node(p).node(names=True) for p in profiles]
                have = topics.setdefault(st.name, {
                    'name': st.name, 'type': st.type, 'serialization_format': st.serialization_format,
                    'offered_qos_profiles': nodes, 'type_description_hash': st.type_hash})
                if nodes:
                    have['offered_qos_profiles'] = nodes
    info = {
        'version': 9,
        'storage_identifier': old.storage_identifier,
        'duration': {'nanoseconds': old.duration_ns or 0},
        'starting_time': {'nanoseconds_since_epoch': old.starting_time_ns or 0},
        'message_count': sum(counts.values()),
        'topics_with_message_count': [{'topic_metadata': t, 'message_count': counts.get(n, 0)}
                                      for n, t in topics.items()],
        'compression_format': old.compression_format,
        'compression_mode': old.compression_mode,
        'relative_file_paths': list(old.relative_file_paths),
        'files': [],  # the reindexer leaves them out
        'custom_data': old.custom_data or None,
        'ros_distro': 'jazzy',
    }
    (bag / 'metadata.yaml').write_text(yaml_cpp_dump({'rosbag2_bagfile_information': info}),
                                       encoding='utf-8')


def rosbags_reader_count(path: Path | str) -> int:
    """Messages the ``rosbags`` directory reader yields for the bag (for the comparison)."""
    from rosbags.rosbag2 import Reader

    with Reader(Path(path)) as reader:
        return sum(1 for _ in reader.messages())
