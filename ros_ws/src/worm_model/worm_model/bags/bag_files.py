"""The files of a bag: which storage files a directory holds and in what split order, which plugin reads each, zstd.

:func:`storage_files` lists a directory's storage files (``<name>_0``,
``<name>_1``, ..., ``<name>_10``); :func:`storage_of` tells a file's storage
by suffix or magic number and :data:`STORAGE_READERS` maps it to its plugin;
:func:`decompress_message` undoes rosbag2's per-message (``MESSAGE`` mode)
zstd compression.

Raises:
    :class:`~worm_model.errors.BagReadError` for a message that is not zstd.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Final

import zstandard

from worm_model.errors import BagReadError
from worm_model.bags.storage import StorageFile
from worm_model.bags.storage_mcap import McapFile
from worm_model.bags.storage_sqlite3 import Sqlite3File

__all__ = [
    'STORAGE_READERS',
    'STORAGE_SUFFIXES',
    'ZSTD_MAGIC',
    'ZSTD_SUFFIX',
    'decompress_message',
    'storage_files',
    'storage_of',
]

ZSTD_SUFFIX: Final[str] = '.zstd'
ZSTD_MAGIC: Final[bytes] = b'\x28\xb5\x2f\xfd'
"""First bytes of a zstd frame; a CDR message starts with 0x00 instead."""
SQLITE_MAGIC: Final[bytes] = b'SQLite format 3\x00'
MCAP_MAGIC: Final[bytes] = b'\x89MCAP0\r\n'
SPLIT_INDEX: Final[re.Pattern[str]] = re.compile(r'^(.*?)(?:_(\d+))?$')


STORAGE_READERS: Final[Mapping[str, Callable[[Path, str], StorageFile]]] = {
    'sqlite3': Sqlite3File,
    'mcap': McapFile,
}
"""Storage identifier (as rosbag2 spells it) -> reader of one file."""

STORAGE_SUFFIXES: Final[Mapping[str, str]] = {'.db3': 'sqlite3', '.mcap': 'mcap'}


def storage_of(path: Path, default: str) -> str:
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


def decompress_message(data: bytes, where: str) -> bytes:
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

