"""Writing outputs: one policy for every tool, so that nothing a user hands a tool is lost.

The policy (:func:`check_output`, applied before any work, and again by :func:`atomic_file` and
:func:`atomic_dir` when the output is put in place):

* An output never is, holds or lies inside one of the run's inputs: no command writes to, replaces or
  deletes a file it reads, a folder holding one, or anything inside an input folder (a bag folder).
  Inputs are the paths the tool names, and every file read through worm_model.files.reading.
* Never an empty path (what ``--out "$UNSET"`` becomes), the file system's root, the home folder, the
  working folder or a folder above it: those are refused even with ``--force``.
* An existing output is replaced only with ``--force``, and only when it is what the same tool wrote
  there before: a folder holding the marker file :data:`MARKER` that names the tool (every output folder
  gets one), or holding nothing at all; a file the tool recognises as its own (an :class:`Output`'s
  ``recognise``: a calibration database for ``calibrate``, a CSV with an estimate column for
  ``estimate``). Anything else is the user's: choose another name, or remove it yourself.
* The output is written under a temporary name beside the target and renamed over it at the end, so a
  failure or Ctrl-C leaves the old output or none, never half of one. A place that cannot be written is
  refused before any work (the folder is tried: permissions do not tell for root or a read-only mount);
  a failure to write names the user's path, never the temporary one (:class:`OutputError`, exit code 2;
  a write that fails later, a full disk, is an OSError naming the user's file, exit code 1).
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from worm_model.files.reading import inputs_read, not_an_input
from worm_model.errors import OutputError

#: the file every output folder holds, naming the tool that wrote it (what lets --force replace it)
MARKER: Final = ".written-by"

PathLike = str | os.PathLike[str]


def _resolved(path: PathLike) -> Path:
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError):
        return Path(os.path.abspath(path))


def _inside(child: Path, parent: Path) -> bool:
    """``child`` is ``parent`` or below it (both resolved)."""
    return child == parent or parent in child.parents


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def tool_name() -> str:
    """The running tool's name (for the marker file when a tool names none): the executable's name."""
    return Path(sys.argv[0]).name.removesuffix(".py") or "python"


@dataclass(frozen=True)
class Output:
    """What a tool writes at one path, and how it recognises its own earlier output there.

    ``tool``: the name written into a folder's :data:`MARKER` and looked for there. ``recognise``: for a
    file output, a predicate saying whether an existing file is one this tool writes (its format);
    without one an existing file is never replaced. ``names``: for a folder output, the names
    (glob patterns) the tool writes into it; a folder without the marker holding only such names is taken
    for this tool's too (written before folders carried the marker).
    """

    tool: str
    recognise: Callable[[Path], bool] | None = None
    names: tuple[str, ...] = field(default=())


def _never_replaced(target: Path) -> str | None:
    """Why ``target`` may never be replaced whatever the options (root, home, working folder, above it)."""
    here = _resolved(os.getcwd())
    if target == Path(target.anchor):
        return "is the root of the file system"
    home = os.environ.get("HOME")
    if home and target == _resolved(home):
        return "is the home folder"
    if _inside(here, target):
        return "is the working folder" if target == here else "holds the working folder"
    return None


def _input_conflict(target: Path, inputs: Iterable[PathLike]) -> str | None:
    """Why writing at ``target`` would touch one of ``inputs`` (is it, holds it, lies inside it), or None."""
    for given in inputs:
        if given is None or not str(given):
            continue
        source = _resolved(given)
        if target == source or _same_file(target, source):
            return f"is an input of this run ({given}): choose another name"
        if _inside(source, target):
            return f"holds an input of this run ({given}): choose another name"
        if source.is_dir() and _inside(target, source):
            return f"lies inside the input folder {given}: choose a name outside it"
    return None


def _ours(target: Path, output: Output | None, folder: bool) -> bool:
    """``target`` (existing) is what ``output``'s tool wrote there before."""
    if folder:
        if not target.is_dir():
            return False
        try:
            entries = list(target.iterdir())
        except OSError:
            return False
        if not entries:
            return True
        if output is None:
            return False
        marker = target / MARKER
        if marker.is_file():
            try:
                return marker.read_text(encoding="utf-8").split("\n", 1)[0].strip() == output.tool
            except (OSError, UnicodeDecodeError):
                return False
        return bool(output.names) and all(any(e.match(p) for p in output.names) for e in entries)
    if output is None or output.recognise is None or not target.is_file():
        return False
    try:
        with not_an_input(target):  # looking at our own earlier output does not make it an input
            return bool(output.recognise(target))
    except Exception:  # noqa: BLE001 - a file the predicate cannot read is not ours
        return False


def check_output(path: PathLike, force: bool = False, *, folder: bool = False, option: str = "--out",
                 inputs: Iterable[PathLike] = (), output: Output | None = None) -> Path:
    """Refuse an output path before any work is done (the module docstring's policy).

    Args:
        force: the user passed ``--force``: an existing output of this tool (``output``) may be replaced.
        folder: the output is a folder (else a file).
        option: names the path in messages (``--out``, ``--template``).
        inputs: the run's inputs (files or folders); the files read so far through
            worm_model.files.reading count too.
        output: the tool and how it recognises its earlier output; None: an existing path is never replaced.

    Raises:
        OutputError: naming the option and the path.
    """
    if not str(path).strip():
        raise OutputError(option, "empty path (an unset shell variable?): name the file or folder to write")
    given = Path(path)
    where = f"{option} {given}"
    try:
        return _checked_output(given, where, force, folder, inputs, output)
    except OSError as err:  # a name too long, a folder on the way that is a file, a symlink loop
        raise OutputError(where, f"cannot write there: {err.strerror or type(err).__name__}") from None


def _checked_output(given: Path, where: str, force: bool, folder: bool, inputs: Iterable[PathLike],
                    output: Output | None) -> Path:
    target = _resolved(given)
    problem = _never_replaced(target) if (folder or target.is_dir()) else None
    if problem:
        raise OutputError(where, f"{problem}: refusing to write there; name a new folder")
    conflict = _input_conflict(target, [*inputs, *inputs_read()])
    if conflict:
        raise OutputError(where, conflict)
    if target.is_dir() and not folder:
        raise OutputError(where, "is a folder, expected a file name")
    if target.exists() and folder and not target.is_dir():
        raise OutputError(where, "is a file, expected a folder")
    if target.exists() or given.is_symlink():
        if not force:  # only a tool that knows its own output (``output``) can replace one
            raise OutputError(where, "exists; pass --force to replace it" if output is not None
                              else "exists; name a new one (this output is never replaced)")
        if not _ours(target, output, folder):
            what = "folder" if folder else "file"
            by = f"written by {output.tool}" if output is not None else "one this tool writes"
            raise OutputError(where, f"exists and is not a {what} {by} (--force replaces only that tool's own "
                                     f"earlier output): choose another name, or remove it yourself")
    parent = target.parent
    if not parent.is_dir():
        raise OutputError(where, f"folder {given.absolute().parent} does not exist")
    problem = unwritable(parent)
    if problem:
        raise OutputError(where, f"folder {given.absolute().parent}: cannot write there ({problem})")
    return given


def unwritable(folder: Path) -> str | None:
    """Why no file can be made in ``folder`` (tried: permissions do not tell for root or a read-only mount)."""
    try:
        fd, name = tempfile.mkstemp(prefix=".write-test.", dir=folder)
    except OSError as err:
        return err.strerror or type(err).__name__
    os.close(fd)
    os.unlink(name)
    return None


def _cannot_write(where: str, err: OSError, tmp: Path) -> OutputError:
    name = err.filename if isinstance(err.filename, str) else ""
    inner = ""
    if name:
        try:
            rel = Path(name).resolve().relative_to(tmp.resolve())
            inner = f" ({rel})" if str(rel) != "." else ""
        except (ValueError, OSError, RuntimeError):
            pass
    return OutputError(where, f"cannot write{inner}: {err.strerror or err.__class__.__name__}")


def write_text_atomically(path: PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` so that a reader, or a crash, sees the old file or the new one.

    For files a tool keeps for itself (journals, state) and outputs already checked: no policy check here.
    The text goes to a temporary file in the same directory, is synced, then moved over ``path``.

    Raises:
        OSError: it cannot be written; the error names ``path``, never the temporary file.
    """
    with _temporary_file(Path(path)) as tmp:
        with open(tmp, "w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())


def _new_file_beside(target: Path) -> Path:
    """A new empty file ``.<name>.XXXX.tmp`` beside ``target``, with the mode open() would give it.

    Raises:
        OSError: the folder cannot be written (naming ``target``, not the temporary name).
    """
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.absolute().parent)
    except OSError as err:
        raise OSError(err.errno, err.strerror, str(target)) from None
    umask = os.umask(0o022)  # mkstemp makes the file 0600
    os.umask(umask)
    os.chmod(fd, 0o666 & ~umask)
    os.close(fd)
    return Path(name)


@contextmanager
def _temporary_file(target: Path) -> Iterator[Path]:
    tmp = _new_file_beside(target)
    try:
        yield tmp
        os.replace(tmp, target)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        if err.filename == str(tmp):  # the user's file is what could not be written
            raise OSError(err.errno, err.strerror, str(target)) from None
        raise
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_file(path: PathLike, force: bool = False, *, option: str = "--out", inputs: Iterable[PathLike] = (),
                output: Output | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it is renamed to ``path``, on failure removed.

    The policy of :func:`check_output` is applied first and again before the rename (against every input
    read meanwhile). A failure to write is an :class:`OutputError` naming ``option`` and ``path``.
    """
    inputs = list(inputs)
    target = check_output(path, force, option=option, inputs=inputs, output=output)
    where = f"{option} {target}"
    try:
        tmp = _new_file_beside(target)
    except OSError as err:
        raise _cannot_write(where, err, target.absolute().parent) from None
    try:
        try:
            yield tmp
        except OSError as err:
            if err.filename and str(tmp) in str(err.filename):
                raise _cannot_write(where, err, tmp.parent) from None
            raise
        check_output(path, force, option=option, inputs=inputs, output=output)
        try:
            os.replace(tmp, target)
        except OSError as err:
            raise _cannot_write(where, err, tmp.parent) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_dir(path: PathLike, force: bool = False, *, option: str = "--out", inputs: Iterable[PathLike] = (),
               output: Output | None = None) -> Iterator[Path]:
    """Yield a new temporary folder beside ``path``; on success it replaces ``path``, on failure it is removed.

    The policy of :func:`check_output` is applied first and again before the replacement; the folder gets
    the :data:`MARKER` naming ``output.tool`` (default: the executable's name), and the old folder is
    removed only once the new one is in place. A failure to write is an :class:`OutputError` naming
    ``option`` and ``path`` (the file inside it too), never the temporary folder.
    """
    output = output or Output(tool_name())
    inputs = list(inputs)
    target = check_output(path, force, folder=True, option=option, inputs=inputs, output=output)
    where = f"{option} {target}"
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.absolute().parent))
    except OSError as err:
        raise _cannot_write(where, err, target.absolute().parent) from None
    try:
        try:
            (tmp / MARKER).write_text(f"{output.tool}\n", encoding="utf-8")
            yield tmp
        except OSError as err:
            if err.filename and str(tmp.name) in str(err.filename):
                raise _cannot_write(where, err, tmp) from None
            raise
        check_output(path, force, folder=True, option=option, inputs=inputs, output=output)
        old = None
        try:
            if target.exists() or target.is_symlink():
                old = target.with_name(f".{target.name}.{os.getpid()}.old")
                os.replace(target, old)
            os.replace(tmp, target)
        except OSError as err:
            if old is not None and not target.exists():
                os.replace(old, target)  # put the old output back
            raise _cannot_write(where, err, tmp) from None
        if old is not None:
            shutil.rmtree(old, ignore_errors=True) if old.is_dir() and not old.is_symlink() else old.unlink()
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
