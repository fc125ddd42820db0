"""Writing outputs that never half-exist: nothing a user made is replaced without ``--force``; files
and folders are written to a temporary beside the target and renamed at the end.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from worm_model.cli.errors import InputError


def check_output(path: str | os.PathLike[str], force: bool = False, *, folder: bool = False,
                 option: str = "--out") -> Path:
    """Refuse an output path before any work is done.

    Refused: the target exists and ``force`` is False (nothing a user made is replaced without
    ``--force``); a file where a folder is wanted or the reverse; a parent folder that does not exist.

    Raises:
        InputError: naming the option and the path.
    """
    target = Path(path)
    where = f"{option} {target}"
    if target.is_dir() and not folder:
        raise InputError(where, "is a folder, expected a file name")
    if target.exists() and folder and not target.is_dir():
        raise InputError(where, "is a file, expected a folder")
    if target.exists() or target.is_symlink():
        if not force:
            raise InputError(where, "exists; pass --force to replace it")
    parent = target.absolute().parent
    if not parent.is_dir():
        raise InputError(where, f"folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise InputError(where, f"folder {parent} is not writable")
    return target


def write_text_atomically(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` so that a reader, or a crash, sees the old file or the new one.

    The text goes to a temporary file in the same directory, is synced, then
    moved over ``path`` with :func:`os.replace`.

    Raises:
        OSError: the directory is not writable.
    """
    with atomic_file(path, force=True) as tmp:
        with open(tmp, "w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())


@contextmanager
def atomic_file(path: str | os.PathLike[str], force: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed to ``path``, on failure removed.

    With ``force`` False an existing ``path`` is refused first (:func:`check_output`).
    """
    target = Path(path)
    if not force:
        check_output(target)
    fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.absolute().parent)
    tmp = Path(name)
    try:
        umask = os.umask(0o022)  # mkstemp makes the file 0600; give it the mode open() would
        os.umask(umask)
        os.chmod(fd, 0o666 & ~umask)
        os.close(fd)
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_dir(path: str | os.PathLike[str], force: bool = False) -> Iterator[Path]:
    """Yield a new temporary folder beside ``path``; on success it replaces ``path``, on failure it is removed.

    An existing ``path`` is refused unless ``force`` (:func:`check_output`); with ``force`` the old
    folder is removed only once the new one is complete.
    """
    target = Path(path)
    check_output(target, force, folder=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.absolute().parent))
    try:
        yield tmp
        old = None
        if target.exists():
            old = target.with_name(f".{target.name}.{os.getpid()}.old")
            os.replace(target, old)
        os.replace(tmp, target)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
