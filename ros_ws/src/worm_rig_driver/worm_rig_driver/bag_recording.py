"""Write and read rosbag2 bags of raw CDR messages, without rclpy.

This is the core of the recorder node (``recorder_node.py`` is a thin rclpy
shell over it). It uses the pure-Python ``rosbags`` library, so it runs where
rosbag2 itself is not installed, and writes bags that the stock tools read:
``ros2 bag info/play``, Foxglove, PlotJuggler.

Message definitions are embedded in every bag. A type's definition comes from

1. the stock ROS 2 typestore of ``rosbags`` (:data:`STOCK_STORE`, the newest
   distribution it knows): ``std_msgs``, ``sensor_msgs``, ``builtin_interfaces``,
   ``rcl_interfaces``, ... ;
2. otherwise from its interface file under an ament prefix:
   ``<prefix>/share/<pkg>/<kind>/<Name>.msg`` (or ``.idl``), searched in the
   order of ``AMENT_PREFIX_PATH``. Types it references are resolved the same
   way, recursively.

The MCAP storage carries the definition as a ``ros2msg`` schema per type; the
sqlite3 storage carries it in its ``message_definitions`` table. Both carry
the RIHS01 type hash in the topic metadata, as rosbag2 does since Iron.

Units: timestamps are integer nanoseconds (ROS time) throughout.

Raises:
    Every failure is a :class:`BagRecordingError` (or a subclass) whose message
    names the bag path, topic or type concerned.
"""

from __future__ import annotations

import os
import struct
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Final, Literal, Self, cast

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Connection, Nodetype, Qos
from rosbags.interfaces.typing import FieldDesc, Typesdict
from rosbags.rosbag2 import ReaderError, StoragePlugin, Writer, WriterError
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

__all__ = [
    'STOCK_STORE',
    'STORAGES',
    'BagClosedError',
    'BagReadError',
    'BagRecordingError',
    'BagWriter',
    'MessageTypes',
    'TopicHandle',
    'TypeDefinitionNotFoundError',
    'ament_prefixes',
    'deserialize_cdr',
    'normalize_type_name',
    'read_bag_counts',
    'read_messages',
]

STOCK_STORE: Final[Stores] = next(
    getattr(Stores, name)
    for name in ('ROS2_KILTED', 'ROS2_JAZZY', 'ROS2_HUMBLE')
    if hasattr(Stores, name)
)
"""Newest stock ROS 2 typestore this ``rosbags`` version ships."""

StorageName = Literal['mcap', 'sqlite3']

STORAGES: Final[Mapping[str, StoragePlugin]] = {
    'mcap': StoragePlugin.MCAP,
    'sqlite3': StoragePlugin.SQLITE3,
}
"""Storage name (as ``ros2 bag record -s`` spells it) -> rosbags plugin."""

INTERFACE_LOADERS: Final[Mapping[str, Callable[[str, str], Typesdict]]] = {
    '.msg': lambda text, type_name: get_types_from_msg(text, type_name),
    '.idl': lambda text, _type_name: get_types_from_idl(text),
}
"""Interface file suffix -> parser, in order of preference."""


class BagRecordingError(Exception):
    """A bag could not be written or read; the message names path/topic/type."""


class TypeDefinitionNotFoundError(BagRecordingError):
    """No definition of a message type in the stock store or the ament prefixes."""


class BagClosedError(BagRecordingError):
    """A write reached a bag that is already closed."""


class BagReadError(BagRecordingError):
    """A bag could not be opened or decoded."""


def ament_prefixes(environ: Mapping[str, str] | None = None) -> list[Path]:
    """Return the ament prefixes of ``AMENT_PREFIX_PATH``, in search order.

    Args:
        environ: Environment to read; ``os.environ`` when None.

    """
    value = (os.environ if environ is None else environ).get('AMENT_PREFIX_PATH', '')
    return [Path(entry) for entry in value.split(os.pathsep) if entry]


def normalize_type_name(type_name: str) -> str:
    """Return the canonical ``pkg/msg/Name`` form of a message type name.

    ``pkg/Name`` (ROS 1 / short form) becomes ``pkg/msg/Name``.

    Raises:
        BagRecordingError: The name has neither two nor three parts.

    """
    parts = type_name.split('/')
    if len(parts) == 2 and all(parts):
        return f'{parts[0]}/msg/{parts[1]}'
    if len(parts) == 3 and all(parts):
        return type_name
    msg = f'Invalid message type name {type_name!r}; expected "pkg/msg/Name".'
    raise BagRecordingError(msg)


def _referenced_types(desc: FieldDesc) -> Iterator[str]:
    """Yield the message type names a field descriptor refers to."""
    kind, payload = desc
    if kind == Nodetype.NAME:
        yield cast('str', payload)
    elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        inner, _length = cast('tuple[FieldDesc, int]', payload)
        yield from _referenced_types(inner)


class MessageTypes:
    """A typestore: the stock ROS 2 types plus custom types loaded on demand.

    Custom types are parsed from their interface files under ament prefixes
    (see the module docstring); what is registered once stays registered.
    """

    def __init__(
        self,
        search_prefixes: Sequence[Path] | None = None,
        stock_store: Stores = STOCK_STORE,
    ) -> None:
        """Create the store.

        Args:
            search_prefixes: Ament prefixes to search for custom interface
                files; ``AMENT_PREFIX_PATH`` when None.
            stock_store: Stock typestore to start from.

        """
        self.search_prefixes: list[Path] = (
            ament_prefixes() if search_prefixes is None else list(search_prefixes)
        )
        self.typestore: Typestore = get_typestore(stock_store)

    def __contains__(self, type_name: str) -> bool:
        """Whether ``type_name`` is registered already (no file lookup)."""
        return normalize_type_name(type_name) in self.typestore.fielddefs

    def ensure(self, type_name: str) -> str:
        """Make ``type_name`` and every type it references known to the store.

        Args:
            type_name: ``pkg/msg/Name`` (or ``pkg/Name``).

        Returns:
            The canonical type name.

        Raises:
            TypeDefinitionNotFoundError: No interface file for it (or for a type
                it references) under any search prefix.
            BagRecordingError: An interface file does not parse, or clashes with
                a registered type of the same name.

        """
        name = normalize_type_name(type_name)
        found: Typesdict = {}
        pending = [name]
        while pending:
            current = pending.pop()
            if current in self.typestore.fielddefs or current in found:
                continue
            parsed = self._load(current)
            found.update(parsed)
            pending.extend(
                ref
                for _consts, fields in parsed.values()
                for _field, desc in fields
                for ref in _referenced_types(desc)
            )
        if found:
            try:
                self.typestore.register(found)
            except TypesysError as err:
                msg = f'Cannot register {sorted(found)} for {name!r}: {err}'
                raise BagRecordingError(msg) from err
        return name

    def interface_file(self, type_name: str) -> Path:
        """Return the first interface file defining ``type_name``.

        Raises:
            TypeDefinitionNotFoundError: None exists under the search prefixes.

        """
        package, kind, base = normalize_type_name(type_name).split('/')
        candidates = [
            prefix / 'share' / package / kind / f'{base}{suffix}'
            for suffix in INTERFACE_LOADERS
            for prefix in self.search_prefixes
        ]
        if path := next((c for c in candidates if c.is_file()), None):
            return path
        prefixes = os.pathsep.join(str(p) for p in self.search_prefixes) or '<empty>'
        msg = (
            f'Type definition not found for {type_name!r}: not in the stock '
            f'{STOCK_STORE.value} typestore, and no share/{package}/{kind}/{base}'
            f'{{{",".join(INTERFACE_LOADERS)}}} under AMENT_PREFIX_PATH={prefixes}'
        )
        raise TypeDefinitionNotFoundError(msg)

    def _load(self, type_name: str) -> Typesdict:
        """Parse the interface file of one type (not its references)."""
        path = self.interface_file(type_name)
        try:
            parsed = INTERFACE_LOADERS[path.suffix](path.read_text(encoding='utf-8'), type_name)
        except (OSError, TypesysError) as err:
            msg = f'Cannot parse definition of {type_name!r} in {path}: {err}'
            raise BagRecordingError(msg) from err
        if type_name not in parsed:
            msg = f'{path} does not define {type_name!r} (it defines {sorted(parsed)})'
            raise BagRecordingError(msg)
        return parsed


@dataclass(frozen=True, slots=True)
class TopicHandle:
    """A topic added to a :class:`BagWriter`; pass it to :meth:`BagWriter.write`."""

    topic: str
    type_name: str
    type_hash: str
    """RIHS01 hash of the embedded definition (``RIHS01_<hex>``)."""
    connection: Connection


class BagWriter:
    """A rosbag2 bag directory being written with raw CDR messages.

    Use as a context manager, or call :meth:`close` (idempotent). :meth:`write`
    is thread-safe, so callbacks of a multi-threaded executor may share one
    writer.

    Format: rosbag2 metadata version 9 (Jazzy and later) by default, 8 on
    request for older readers; storage MCAP (rosbag2's default since Iron) or
    sqlite3.
    """

    def __init__(
        self,
        path: Path | str,
        storage: StorageName | str = 'mcap',
        *,
        types: MessageTypes | None = None,
        version: Literal[8, 9] = Writer.VERSION_LATEST,
    ) -> None:
        """Create the bag directory and open its storage file.

        Args:
            path: Bag directory to create; it must not exist.
            storage: ``"mcap"`` or ``"sqlite3"``.
            types: Type store to take definitions from; a new
                :class:`MessageTypes` over ``AMENT_PREFIX_PATH`` when None.
            version: rosbag2 metadata version.

        Raises:
            BagRecordingError: Unknown storage, the path exists, or it cannot
                be created.

        """
        self.path = Path(path)
        if (plugin := STORAGES.get(storage)) is None:
            msg = (
                f'Unknown storage {storage!r} for bag {self.path}; '
                f'expected one of {sorted(STORAGES)}'
            )
            raise BagRecordingError(msg)
        self.storage = storage
        self.types = MessageTypes() if types is None else types
        self.counts: dict[str, int] = {}
        """Messages written so far, per topic."""
        self._handles: dict[str, TopicHandle] = {}
        self._lock = threading.Lock()
        self._writer: Writer | None = None
        try:
            writer = Writer(self.path, version=version, storage_plugin=plugin)
            writer.open()
        except (WriterError, OSError) as err:
            msg = f'Cannot create bag {self.path}: {err}'
            raise BagRecordingError(msg) from err
        self._writer = writer

    @property
    def closed(self) -> bool:
        """Whether the bag is closed (metadata.yaml written)."""
        return self._writer is None

    @property
    def topics(self) -> Mapping[str, TopicHandle]:
        """Handles of the topics added so far, by topic name."""
        return dict(self._handles)

    def add_topic(
        self,
        topic: str,
        type_name: str,
        offered_qos: Sequence[Qos] = (),
    ) -> TopicHandle:
        """Add a topic; its type's definition is embedded in the bag.

        Args:
            topic: Topic name, e.g. ``/rig/sample``.
            type_name: ``pkg/msg/Name`` (or ``pkg/Name``).
            offered_qos: QoS profiles of the topic's publishers, stored as
                rosbag2's ``offered_qos_profiles`` (used by ``ros2 bag play``).

        Returns:
            The handle to write the topic's messages with.

        Raises:
            TypeDefinitionNotFoundError: No definition of the type.
            BagRecordingError: Topic added before, bag closed, or rosbags
                refused the connection.

        """
        name = self.types.ensure(type_name)
        with self._lock:
            writer = self._open_writer(topic)
            if (have := self._handles.get(topic)) is not None:
                msg = f'Topic {topic!r} is already in bag {self.path} as {have.type_name!r}'
                raise BagRecordingError(msg)
            try:
                connection = writer.add_connection(
                    topic,
                    name,
                    typestore=self.types.typestore,
                    offered_qos_profiles=list(offered_qos),
                )
            except (WriterError, TypesysError, KeyError) as err:
                msg = f'Cannot add topic {topic!r} of type {name!r} to bag {self.path}: {err!r}'
                raise BagRecordingError(msg) from err
            handle = TopicHandle(topic, name, connection.digest, connection)
            self._handles[topic] = handle
            self.counts[topic] = 0
        return handle

    def write(self, handle: TopicHandle, timestamp_ns: int, cdr_bytes: bytes | memoryview) -> None:
        """Append one serialized message, as received (no re-serialization).

        Args:
            handle: From :meth:`add_topic` of this writer.
            timestamp_ns: Receive time (ns, ROS time).
            cdr_bytes: The message in CDR, with its 4-byte encapsulation header.

        Raises:
            BagClosedError: The bag is closed.
            BagRecordingError: The handle belongs to another bag.

        """
        with self._lock:
            writer = self._open_writer(handle.topic)
            if self._handles.get(handle.topic) is not handle:
                msg = f'Topic {handle.topic!r} was not added to bag {self.path}'
                raise BagRecordingError(msg)
            writer.write(handle.connection, timestamp_ns, cdr_bytes)
            self.counts[handle.topic] += 1

    def close(self) -> None:
        """Finish the storage file and write ``metadata.yaml``; idempotent.

        Raises:
            BagRecordingError: rosbags failed to finish the bag.

        """
        with self._lock:
            writer, self._writer = self._writer, None
            if writer is None:
                return
            try:
                writer.close()
            except (WriterError, OSError) as err:
                msg = f'Cannot finish bag {self.path}: {err}'
                raise BagRecordingError(msg) from err

    def _open_writer(self, topic: str) -> Writer:
        """Return the rosbags writer, or raise if closed (caller holds the lock)."""
        if self._writer is None:
            msg = f'Bag {self.path} is closed; cannot write topic {topic!r}'
            raise BagClosedError(msg)
        return self._writer

    def __enter__(self) -> Self:
        """Return self; the bag is open already."""
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc_val: BaseException | None,
        exc_tb: TracebackType | None,
    ) -> None:
        """Close the bag, also on error (what was written stays readable)."""
        self.close()


CDR_HEADER_BYTES: Final[int] = 4
"""Encapsulation header (representation id + options) before a CDR payload."""
CDR_MAX_FINAL_PADDING: Final[int] = 7
"""Fast CDR pads a payload to 8-byte alignment; rosbags tolerates only 3."""
CDR_ENCAPSULATIONS: Final[Mapping[bytes, bool]] = {b'\x00\x00': False, b'\x00\x01': True}
"""Representation id (plain CDR) -> little endian."""


def deserialize_cdr(typestore: Typestore, data: bytes | memoryview, type_name: str) -> object:
    """Decode one CDR message as the ROS 2 middlewares write it.

    Like ``Typestore.deserialize_cdr`` but accepting up to 7 bytes of final
    padding: Fast DDS (rmw_fastrtps) pads every payload to 8-byte alignment,
    so e.g. a ``sensor_msgs/msg/JointState`` with an empty ``effort`` arrives
    4 bytes longer than its content, and rosbags would reject it.

    Raises:
        BagReadError: Not plain CDR, or the bytes do not fit ``type_name``.

    """
    little_endian = CDR_ENCAPSULATIONS.get(bytes(data[:2]))
    if little_endian is None or len(data) < CDR_HEADER_BYTES:
        msg = f'Not a plain CDR message of {type_name!r} (header {bytes(data[:4])!r})'
        raise BagReadError(msg)
    msgdef = typestore.get_msgdef(type_name)
    decode = msgdef.deserialize_cdr_le if little_endian else msgdef.deserialize_cdr_be
    try:
        message, end = decode(data[CDR_HEADER_BYTES:], 0, msgdef.cls, typestore)
    except (struct.error, UnicodeDecodeError, ValueError, IndexError) as err:
        msg = f'Cannot decode {len(data)} bytes as {type_name!r}: {err}'
        raise BagReadError(msg) from err
    if (excess := len(data) - CDR_HEADER_BYTES - end) > CDR_MAX_FINAL_PADDING:
        msg = f'{excess} bytes left over after decoding {len(data)} bytes as {type_name!r}'
        raise BagReadError(msg)
    return message


def _reader_paths(path: Path) -> list[Path]:
    """Return what to open with rosbags to read the bag at ``path``.

    For an uncompressed bag directory these are its storage files, opened
    one by one: rosbags' directory reader matches the topics of
    ``metadata.yaml`` against those of the storage file by their offered-QoS
    text, and yields nothing when the real rosbag2 wrote the two differently.
    A storage file carries its own topics, types and definitions. Compressed
    bags (and anything else) go to the directory reader.

    Raises:
        BagReadError: No such path, or an unreadable ``metadata.yaml``.

    """
    if not path.exists():
        msg = f'No bag at {path}'
        raise BagReadError(msg)
    metapath = path / 'metadata.yaml'
    if not metapath.is_file():
        return [path]
    try:
        document = YAML(typ='safe').load(metapath.read_text(encoding='utf-8'))
        info = document['rosbag2_bagfile_information']
        files = [path / Path(name).name for name in info['relative_file_paths']]
        compressed = (info.get('compression_mode') or 'none').lower() != 'none'
    except (OSError, YAMLError, KeyError, TypeError) as err:
        msg = f'Cannot read bag metadata {metapath}: {err!r}'
        raise BagReadError(msg) from err
    if compressed or not files or not all(f.is_file() for f in files):
        return [path]
    return files


class _BagReader:
    """An open rosbags ``AnyReader`` over one bag, with domain errors."""

    def __init__(self, path: Path | str, types: MessageTypes | None) -> None:
        self.path = Path(path)
        self.types = MessageTypes() if types is None else types
        self.reader = AnyReader(_reader_paths(self.path), default_typestore=self.types.typestore)

    def __enter__(self) -> AnyReader:
        try:
            self.reader.open()
        except (AnyReaderError, ReaderError, TypesysError, OSError) as err:
            msg = f'Cannot open bag {self.path}: {err}'
            raise BagReadError(msg) from err
        return self.reader

    def __exit__(self, *exc: object) -> None:
        self.reader.close()


def read_bag_counts(path: Path | str, types: MessageTypes | None = None) -> dict[str, int]:
    """Count the messages actually stored per topic (not the metadata's claim).

    Args:
        path: Bag directory, or a single ``.mcap`` / ``.db3`` file.
        types: Typestore for bags without embedded definitions.

    Raises:
        BagReadError: The bag cannot be opened or read.

    """
    with _BagReader(path, types) as reader:
        counts = dict.fromkeys(sorted({c.topic for c in reader.connections}), 0)
        try:
            for connection, _timestamp, _data in reader.messages():
                counts[connection.topic] += 1
        except (AnyReaderError, ReaderError) as err:
            msg = f'Cannot read bag {path}: {err}'
            raise BagReadError(msg) from err
    return counts


def read_messages(
    path: Path | str,
    topic: str,
    types: MessageTypes | None = None,
) -> Iterator[tuple[int, object]]:
    """Yield ``(timestamp_ns, message)`` of one topic in time order.

    Messages are rosbags dataclasses (field names as in the ``.msg``),
    decoded with the definitions embedded in the bag.

    Args:
        path: Bag directory, or a single ``.mcap`` / ``.db3`` file.
        topic: Topic to read.
        types: Typestore for bags without embedded definitions.

    Raises:
        BagReadError: The bag cannot be opened or decoded, or has no such topic.

    """
    with _BagReader(path, types) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        if not connections:
            have = sorted({c.topic for c in reader.connections})
            msg = f'Bag {path} has no topic {topic!r}; it has {have}'
            raise BagReadError(msg)
        try:
            for connection, timestamp, data in reader.messages(connections=connections):
                yield timestamp, deserialize_cdr(reader.typestore, data, connection.msgtype)
        except (AnyReaderError, ReaderError) as err:
            msg = f'Cannot decode topic {topic!r} of bag {path}: {err}'
            raise BagReadError(msg) from err

