"""The folder a recording goes into: always a new one, and beside a recording that was cut off (no rclpy).

A recorder started again after it was killed (``run_graph --respawn``, launch's
``respawn``, a user running the same command again) finds its ``output`` holding
the bag it was writing: storage files and no ``metadata.yaml``, which the recorder
writes only when it closes the bag. That bag is left exactly as it is (it reads up
to its last flush: :mod:`worm_model.bags.reader`), and the new recording goes into
the first free ``<output>.1``, ``<output>.2``, ... beside it. Anything else at
``output`` is refused by the caller as before (a closed bag, a folder of other
files, a file). A recorder holds an exclusive ``flock`` on its folder while it
records, so a folder another recorder is still writing is not taken for a cut-off
one; the kernel drops the lock when the process dies, however it dies.
"""
from __future__ import annotations

import errno
import fcntl
import os
from datetime import datetime
from pathlib import Path
from typing import Final

from worm_model.errors import BagRecordingError

#: storage files of a bag (rosbag2's MCAP and sqlite3 plugins), compressed per file or not
STORAGE_SUFFIXES: Final[tuple[str, ...]] = ('.mcap', '.db3', '.mcap.zstd', '.db3.zstd')
#: the default folder name's pattern, as ``ros2 bag record`` names one
DEFAULT_NAME: Final[str] = 'rosbag2_%Y_%m_%d-%H_%M_%S'


def unclosed(path: Path) -> bool:
    """Whether ``path`` is a bag folder whose bag was never closed: a storage file and no ``metadata.yaml``
    (a recorder writing it now, or one that was killed)."""
    if not path.is_dir() or path.is_symlink() or (path / 'metadata.yaml').exists():
        return False
    return any(p.name.endswith(STORAGE_SUFFIXES) for p in path.iterdir() if p.is_file())


def recording(path: Path) -> bool:
    """Whether a live recorder holds the folder ``path`` (:func:`hold`)."""
    try:
        os.close(hold(path))
    except BlockingIOError:
        return True
    return False


def beside(path: Path) -> Path:
    """The first of ``<path>.1``, ``<path>.2``, ... that does not exist (not even as a dangling link)."""
    n = 1
    while os.path.lexists(f'{path}.{n}'):
        n += 1
    return Path(f'{path}.{n}')


def bag_folder(output: str, now: datetime | None = None) -> tuple[Path, str | None]:
    """The folder to record into for the ``output`` parameter, and why it is not ``output`` (None if it is).

    ``output`` empty: ``rosbag2_<date-time>`` in the working directory, or beside it if that exists (a recorder
    started again within the same second). ``output`` a bag that was cut off (:func:`unclosed`, and no recorder
    holds it): beside it. Any other ``output``, existing or not, is returned as it is, for the caller's check
    (which refuses an existing one).

    Raises:
        BagRecordingError: another recorder is writing ``output`` now.
    """
    if not output:
        path = Path((now or datetime.now()).strftime(DEFAULT_NAME))
        return (path, None) if not os.path.lexists(path) else (beside(path), f'{path} exists')
    path = Path(output)
    if not unclosed(path):
        return path, None
    if recording(path):
        raise BagRecordingError(f'parameter output {path}: another recorder is recording into it now')
    return beside(path), (f'{path} holds a recording that stopped without closing its bag (no metadata.yaml), '
                          'left as it is')


def hold(path: Path) -> int:
    """Take the exclusive lock of the recorder writing the bag folder ``path``; returns the descriptor that
    holds it (close it to let go; the process's death lets go too).

    Raises:
        BlockingIOError: another process holds it.
        OSError: the folder cannot be opened.
    """
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:
        os.close(fd)
        if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
            raise BlockingIOError(err.errno, f'{path}: a recorder is writing it') from None
        raise
    return fd
