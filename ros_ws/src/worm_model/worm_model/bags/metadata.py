"""A bag's metadata: ``metadata.yaml`` and the copy rosbag2 embeds in its storage files, read and checked.

:class:`BagMetadata` is what either says; :func:`read_metadata_file` reads
``<bag>/metadata.yaml``, :func:`parse_metadata` checks a parsed document of
any version from 1 to 9 (see :mod:`worm_model.bags.reader` for what each
version added), :func:`parse_embedded_metadata` the copy inside a sqlite3
(Humble on) or MCAP (Jazzy on) file. Times are integer ns.

Raises:
    :class:`~worm_model.errors.BagReadError` naming the file and the key.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from ruamel.yaml import YAML
from ruamel.yaml.error import YAMLError

from worm_model.errors import BagReadError, InputError
from worm_model.files.reading import MAX_YAML_BYTES, check_yaml, read_text

__all__ = [
    'BagMetadata',
    'METADATA_FILE',
    'METADATA_KEY',
    'parse_embedded_metadata',
    'parse_metadata',
    'read_metadata_file',
]

METADATA_FILE: Final[str] = 'metadata.yaml'
METADATA_KEY: Final[str] = 'rosbag2_bagfile_information'
NEWEST_KNOWN_VERSION: Final[int] = 9


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


def parse_embedded_metadata(text: str, source: str) -> BagMetadata | None:
    """Metadata rosbag2 serialized into a storage file; None if unusable."""
    try:
        document = YAML(typ='safe', pure=True).load(text)
        return parse_metadata(document, source)
    except (YAMLError, BagReadError):
        return None
