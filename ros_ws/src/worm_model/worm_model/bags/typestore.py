"""Message types and CDR decoding for bags, without rclpy.

Shared by the writer (:mod:`worm_model.bags.writer`) and the reader
(:mod:`worm_model.bags.reader`). A type's definition comes from

1. the stock ROS 2 typestore of ``rosbags`` (:data:`STOCK_STORE`, the newest
   distribution it knows): ``std_msgs``, ``sensor_msgs``, ``builtin_interfaces``,
   ``rcl_interfaces``, ... ;
2. otherwise from its interface file under an ament prefix:
   ``<prefix>/share/<pkg>/<kind>/<Name>.msg`` (or ``.idl``), searched in the
   order of ``AMENT_PREFIX_PATH``. Types it references are resolved the same
   way, recursively.

Raises:
    Every failure is a :class:`BagRecordingError` (or a subclass) whose message
    names the bag path, topic or type concerned.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Final, Self, cast

from rosbags.interfaces import Nodetype
from rosbags.interfaces.typing import FieldDesc, Typesdict
from rosbags.typesys import (
    Stores,
    TypesysError,
    get_types_from_idl,
    get_types_from_msg,
    get_typestore,
)
from rosbags.typesys.store import Typestore

from worm_model.ros.ament import ament_prefixes
from worm_model.errors import BagClosedError, BagReadError, BagRecordingError, TypeDefinitionNotFoundError

__all__ = [
    'STOCK_STORE',
    'BagClosedError',
    'BagReadError',
    'BagRecordingError',
    'ClosesOnExit',
    'MessageTypes',
    'TypeDefinitionNotFoundError',
    'ament_prefixes',
    'deserialize_cdr',
    'normalize_type_name',
    'referenced_types',
]

STOCK_STORE: Final[Stores] = next(
    getattr(Stores, name)
    for name in ('ROS2_KILTED', 'ROS2_JAZZY', 'ROS2_HUMBLE')
    if hasattr(Stores, name)
)
"""Newest stock ROS 2 typestore this ``rosbags`` version ships."""


INTERFACE_LOADERS: Final[Mapping[str, Callable[[str, str], Typesdict]]] = {
    '.msg': lambda text, type_name: get_types_from_msg(text, type_name),
    '.idl': lambda text, _type_name: get_types_from_idl(text),
}
"""Interface file suffix -> parser, in order of preference."""


class ClosesOnExit:
    """Context-manager protocol of an open bag (reader or writer): ``with`` gives the bag
    itself, which is open already, and closes it on leaving, also on error.

    Subclasses implement :meth:`close` (idempotent).
    """

    def close(self) -> None:
        """Release the bag's files; subclasses override."""
        raise NotImplementedError

    def __enter__(self) -> Self:
        """Return self (the bag is open already)."""
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc_val: BaseException | None,
        exc_tb: TracebackType | None,
    ) -> None:
        """Close the bag, also on error (what a writer wrote stays readable)."""
        self.close()


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


def referenced_types(desc: FieldDesc) -> Iterator[str]:
    """Yield the message type names a rosbags field descriptor refers to."""
    kind, payload = desc
    if kind == Nodetype.NAME:
        yield cast('str', payload)
    elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        inner, _length = cast('tuple[FieldDesc, int]', payload)
        yield from referenced_types(inner)


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
                for ref in referenced_types(desc)
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


CDR_HEADER_BYTES: Final[int] = 4
"""Encapsulation header (representation id + options) before a CDR payload."""
CDR_MAX_FINAL_PADDING: Final[int] = 7
"""Fast CDR pads a payload to 8-byte alignment; rosbags tolerates only 3."""
CDR_EMPTY_SEQUENCE_SLACK: Final[int] = 4
"""Bytes Fast CDR's size estimate may reserve per sequence and leave unwritten when it is empty.

Fast DDS sizes a payload before writing it, reserving the alignment of a
sequence's elements even when the sequence turns out empty, and sends the
reserved length: e.g. a ``sensor_msgs/msg/JointState`` with empty
``velocity`` and ``effort`` arrives 8 bytes longer than its content."""
CDR_ENCAPSULATIONS: Final[Mapping[bytes, bool]] = {b'\x00\x00': False, b'\x00\x01': True}
"""Representation id (plain CDR) -> little endian."""


def deserialize_cdr(typestore: Typestore, data: bytes | memoryview, type_name: str) -> object:
    """Decode one CDR message as the ROS 2 middlewares write it.

    Like ``Typestore.deserialize_cdr`` but accepting the bytes Fast DDS
    (rmw_fastrtps) leaves after the content: up to 7 bytes of final padding
    to 8-byte alignment, plus :data:`CDR_EMPTY_SEQUENCE_SLACK` per sequence
    field of the type (see there). rosbags alone rejects more than 3.

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
    if (excess := len(data) - CDR_HEADER_BYTES - end) > _slack(typestore, type_name):
        msg = f'{excess} bytes left over after decoding {len(data)} bytes as {type_name!r}'
        raise BagReadError(msg)
    return message


_SLACK_CACHE: dict[tuple[int, str], int] = {}


def _slack(typestore: Typestore, type_name: str) -> int:
    """Bytes allowed after the content of a ``type_name`` payload (see :func:`deserialize_cdr`)."""
    key = (id(typestore), type_name)
    if (cached := _SLACK_CACHE.get(key)) is not None:
        return cached

    def sequences(name: str, depth: int) -> int:
        if depth > 32 or name not in typestore.fielddefs:
            return 0
        count = 0
        for _field, desc in typestore.fielddefs[name][1]:
            kind, payload = desc
            if kind == Nodetype.SEQUENCE:
                count += 1
            elif kind == Nodetype.NAME:
                count += sequences(cast('str', payload), depth + 1)
            elif kind == Nodetype.ARRAY:
                inner, length = cast('tuple[FieldDesc, int]', payload)
                if inner[0] == Nodetype.NAME:
                    count += length * sequences(cast('str', inner[1]), depth + 1)
        return count

    slack = CDR_MAX_FINAL_PADDING + CDR_EMPTY_SEQUENCE_SLACK * sequences(type_name, 0)
    _SLACK_CACHE[key] = slack
    return slack
