"""Write rosbag2 bags of raw CDR messages, without rclpy; read them via :mod:`bag_reader`.

This is the core of the recorder node (``recorder_node.py`` is a thin rclpy
shell over it). It uses the pure-Python ``rosbags`` library, so it runs where
rosbag2 itself is not installed, and writes bags that the stock tools read:
``ros2 bag info/play``, Foxglove, PlotJuggler.

Message definitions are embedded in every bag; where a type's definition
comes from is described in :mod:`worm_model.bags.typestore`. The MCAP storage
carries the definition as a ``ros2msg`` schema per type; the sqlite3 storage
carries it in its ``message_definitions`` table. Both carry the RIHS01 type
hash in the topic metadata, as rosbag2 does since Iron.

Reading goes through :class:`worm_model.bags.reader.BagReader`, which
also reads what the real rosbag2 writes; :func:`read_bag_counts` and
:func:`read_messages` are kept here as short cuts.

Units: timestamps are integer nanoseconds (ROS time) throughout.

Raises:
    Every failure is a :class:`BagRecordingError` (or a subclass) whose message
    names the bag path, topic or type concerned.
"""

from __future__ import annotations

import tempfile
import threading
from array import array
from collections.abc import Iterator, Mapping, Sequence
from io import SEEK_END, BytesIO
from dataclasses import dataclass
from pathlib import Path
from typing import Final, Literal

from rosbags.interfaces import Connection, Qos
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer, WriterError
from rosbags.typesys import TypesysError

from worm_model.bags.reader import BagReader
from worm_model.bags.typestore import (STOCK_STORE, ClosesOnExit, MessageTypes, ament_prefixes, deserialize_cdr,
    normalize_type_name)
from worm_model.errors import BagClosedError, BagReadError, BagRecordingError, TypeDefinitionNotFoundError

__all__ = [
    'COMPRESSIONS',
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

StorageName = Literal['mcap', 'sqlite3']

STORAGES: Final[Mapping[str, StoragePlugin]] = {
    'mcap': StoragePlugin.MCAP,
    'sqlite3': StoragePlugin.SQLITE3,
}
"""Storage name (as ``ros2 bag record -s`` spells it) -> rosbags plugin."""

COMPRESSIONS: Final[tuple[str, ...]] = ('none', 'zstd')
"""Compression of an MCAP bag's chunks: ``none`` (what ``ros2 bag record`` writes by
default) or ``zstd`` (as ``ros2 bag record -s mcap --storage-preset-profile zstd_fast``
does). Chunk compression is MCAP's own, so every MCAP reader (Foxglove, PlotJuggler,
``mcap`` CLI) opens the file as it is; rosbag2's file and message compression are not
offered here: Foxglove and PlotJuggler open neither."""


@dataclass(frozen=True, slots=True)
class TopicHandle:
    """A topic added to a :class:`BagWriter`; pass it to :meth:`BagWriter.write`."""

    topic: str
    type_name: str
    type_hash: str
    """RIHS01 hash of the embedded definition (``RIHS01_<hex>``)."""
    connection: Connection


class _ChunkIndexes:
    """The MCAP writer's chunk index records, kept on disk until the bag's close reads them back.

    rosbags' McapWriter keeps one record per closed chunk (a BytesIO of ~190 bytes with 13 topics) for
    the summary it writes at close, and the recorder closes a chunk every second (:meth:`BagWriter.flush`):
    1.16 MB an hour of a recorder's resident set that only the bag's close gave back. Here each record is
    appended to an unnamed temporary file in the bag's folder (no name on disk: it leaves nothing behind
    when the process is killed) and only its end offset stays in memory: 8 bytes a chunk, 29 kB an hour.
    The writer only appends, counts and iterates (its close); iterating gives each record back as a
    BytesIO positioned at its end, as the writer made it.
    """

    def __init__(self, folder: Path) -> None:
        self._file = tempfile.TemporaryFile(dir=folder)
        self._ends = array('Q')

    def append(self, record: BytesIO) -> None:
        self._file.write(record.getbuffer())
        self._ends.append(self._file.tell())

    def __len__(self) -> int:
        return len(self._ends)

    def __iter__(self) -> Iterator[BytesIO]:
        self._file.seek(0)
        start = 0
        for end in self._ends:
            record = BytesIO(self._file.read(end - start))
            record.seek(0, SEEK_END)
            yield record
            start = end
        self._file.seek(0, SEEK_END)

    def close(self) -> None:
        self._file.close()


class BagWriter(ClosesOnExit):
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
        compression: str = 'none',
    ) -> None:
        """Create the bag directory and open its storage file.

        Args:
            path: Bag directory to create; it must not exist.
            storage: ``"mcap"`` or ``"sqlite3"``.
            types: Type store to take definitions from; a new
                :class:`MessageTypes` over ``AMENT_PREFIX_PATH`` when None.
            version: rosbag2 metadata version.
            compression: One of :data:`COMPRESSIONS`; ``zstd`` for MCAP only.

        Raises:
            BagRecordingError: Unknown storage or compression, zstd with
                sqlite3, the path exists, or it cannot be created.

        """
        self.path = Path(path)
        if (plugin := STORAGES.get(storage)) is None:
            msg = (
                f'Unknown storage {storage!r} for bag {self.path}; '
                f'expected one of {sorted(STORAGES)}'
            )
            raise BagRecordingError(msg)
        if compression not in COMPRESSIONS or (compression != 'none' and storage != 'mcap'):
            msg = (
                f'Compression {compression!r} for bag {self.path} ({storage}); expected one of '
                f'{list(COMPRESSIONS)}, and zstd (MCAP chunk compression) with storage mcap only'
            )
            raise BagRecordingError(msg)
        self.storage = storage
        self.compression = compression
        self.types = MessageTypes() if types is None else types
        self.counts: dict[str, int] = {}
        """Messages written so far, per topic."""
        self._handles: dict[str, TopicHandle] = {}
        self._lock = threading.Lock()
        self._writer: Writer | None = None
        try:
            writer = Writer(self.path, version=version, storage_plugin=plugin)
            if compression == 'zstd':
                writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
            writer.open()
        except (WriterError, OSError) as err:
            msg = f'Cannot create bag {self.path}: {err}'
            raise BagRecordingError(msg) from err
        self._chunk_indexes: _ChunkIndexes | None = None
        if isinstance(getattr(writer.storage, 'chunks', None), list) and not writer.storage.chunks:  # MCAP
            try:
                self._chunk_indexes = writer.storage.chunks = _ChunkIndexes(self.path)
            except OSError as err:
                writer.close()
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

    def flush(self) -> None:
        """Put what was written so far on disk, so a writer killed without close() leaves it readable.

        rosbags keeps an MCAP chunk in memory until it holds 1 MiB (minutes of our streams), and
        sqlite3 rows in an open transaction: here the pending chunk is closed and the file
        flushed (MCAP), or the transaction committed (sqlite3). A reader then reads the bag up to
        the last flush (without metadata.yaml or the MCAP summary, as :mod:`reader` handles).
        This reaches into the storage writers of the pinned rosbags release (McapWriter.chunk,
        .close_chunk, .bio; Sqlite3Writer.conn): test_bag_recording checks it still works.
        """
        with self._lock:
            storage = None if self._writer is None else self._writer.storage
            if storage is None:
                return
            if hasattr(storage, 'close_chunk'):  # MCAP
                if storage.chunk.msgs:
                    storage.close_chunk()
                storage.bio.flush()
            elif hasattr(storage, 'conn'):  # sqlite3
                storage.conn.commit()

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
            finally:
                if self._chunk_indexes is not None:
                    self._chunk_indexes.close()

    def _open_writer(self, topic: str) -> Writer:
        """Return the rosbags writer, or raise if closed (caller holds the lock)."""
        if self._writer is None:
            msg = f'Bag {self.path} is closed; cannot write topic {topic!r}'
            raise BagClosedError(msg)
        return self._writer


def read_bag_counts(path: Path | str, types: MessageTypes | None = None) -> dict[str, int]:
    """Count the messages actually stored per topic (not the metadata's claim).

    Args:
        path: Bag directory, or a single ``.mcap`` / ``.db3`` file.
        types: Typestore for bags without embedded definitions.

    Raises:
        BagReadError: The bag cannot be opened or read.

    """
    with BagReader(path, types) as reader:
        return reader.count_messages()


def read_messages(
    path: Path | str,
    topic: str,
    types: MessageTypes | None = None,
) -> Iterator[tuple[int, object]]:
    """Yield ``(timestamp_ns, message)`` of one topic in storage order.

    Messages are rosbags dataclasses (field names as in the ``.msg``),
    decoded with the definitions embedded in the bag.

    Args:
        path: Bag directory, or a single ``.mcap`` / ``.db3`` file.
        topic: Topic to read.
        types: Typestore for bags without embedded definitions.

    Raises:
        BagReadError: The bag cannot be opened or decoded, or has no such topic.

    """
    with BagReader(path, types) as reader:
        for message in reader.messages([topic]):
            yield message.timestamp, message.decoded
