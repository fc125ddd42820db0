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

This module is the facade: it opens the bag, merges the topics of its files
and decodes. The parts it puts together live beside it:
:mod:`~worm_model.bags.metadata` (``metadata.yaml`` and the copies in
storage), :mod:`~worm_model.bags.bag_files` (which files, in what order,
which plugin reads each, zstd), one module per storage plugin
(:mod:`~worm_model.bags.storage_sqlite3`, :mod:`~worm_model.bags.storage_mcap`,
their interface in :mod:`~worm_model.bags.storage`) and
:mod:`~worm_model.bags.qos` (offered-QoS comparison, for the warnings).

Raises:
    :class:`~worm_model.errors.BagReadError` for every failure, its
    message naming the file and, for a bad ``metadata.yaml``, the key.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import zstandard
from rosbags.typesys import (
    Stores,
    TypesysError,
    get_types_from_idl,
    get_types_from_msg,
    get_typestore,
)
from rosbags.typesys.store import Typestore

from worm_model.errors import BagReadError, BagRecordingError, InputError
from worm_model.files.reading import check_input
from worm_model.bags.bag_files import (
    STORAGE_READERS,
    ZSTD_MAGIC,
    ZSTD_SUFFIX,
    decompress_message,
    storage_files,
    storage_of,
)
from worm_model.bags.metadata import METADATA_FILE, BagMetadata, read_metadata_file
from worm_model.bags.qos import qos_differs
from worm_model.bags.storage import MessageDefinition, StorageFile
from worm_model.bags.storage_mcap import McapFile
from worm_model.bags.typestore import ClosesOnExit, MessageTypes, deserialize_cdr, referenced_types

__all__ = [
    'BagMessage',
    'BagReader',
    'TopicInfo',
]

DEFINITION_SEPARATOR: Final[str] = '=' * 80 + '\n'


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
        storage = storage_of(opened, default)
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
                if qos_differs(have.offered_qos_profiles, st.offered_qos_profiles):
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
            if qos_differs(have.offered_qos_profiles, record['offered_qos_profiles']):
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
                    data = decompress_message(data, f'{storage.name}: {topic} at {timestamp} ns')
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
