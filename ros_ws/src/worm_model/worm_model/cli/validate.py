"""Bad input, said once: option types, file readers, plausibility, outputs that never half-exist.

Every command-line tool of the project refuses bad input the same way: one line
on stderr, ``tool: where: what is wrong``, and exit code 2 (:data:`EXIT_BAD_INPUT`);
no traceback reaches the user, and a refused or failed run leaves no output behind.
The pieces:

* :class:`InputError` - ``where`` (an option, a file, ``file: line 7, column 'x'``)
  and ``what``. The loaders' own errors (ParameterError, CalibrationError, RigDataError,
  ...) are ValueErrors with the same ``where: what`` message and count as bad input too.
* :func:`number` / :func:`integer` - argparse types: finite, inside a physical range,
  the unit in the message. :func:`check_number` is the same check for values read
  from files, so option and file agree on what is allowed.
* :class:`Parser` - an ArgumentParser whose errors are that one line.
* :func:`read_text`, :func:`load_yaml`, :func:`load_json` - a file as UTF-8 text, YAML
  or JSON, refusing directories, binary files, duplicate keys and NaN/Infinity.
* :class:`Envelope` - what a rig can physically do (from its rig file), with a margin:
  a measured value far outside it is named with its place, not folded into a metric.
* :func:`check_output`, :func:`atomic_file`, :func:`atomic_dir`, :func:`write_text_atomically`
  - nothing a user made is replaced without ``--force``; outputs are written to a
  temporary beside the target and renamed at the end.
* :func:`run_tool` - wraps a tool's main: bad input -> the one line and exit 2,
  Ctrl-C -> 130, anything else -> one line saying it is a bug, the traceback saved to a file.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
import traceback
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import yaml

EXIT_BAD_INPUT: Final = 2
EXIT_INTERRUPTED: Final = 130
#: largest file the text readers accept [bytes]: a rig, effects, graph or calibration file is far smaller
MAX_TEXT_BYTES: Final = 64 * 1024 * 1024


class InputError(ValueError):
    """Bad input: ``where`` it is (option, file, line, column) and ``what`` is wrong with it."""

    def __init__(self, where: str, what: str) -> None:
        self.where = str(where)
        self.what = what
        super().__init__(f"{self.where}: {what}" if self.where else what)


# --- numbers -----------------------------------------------------------------------------------------

def _bound(low: float | None, high: float | None, open_low: bool, open_high: bool, unit: str) -> str:
    u = f" {unit}" if unit else ""
    lo, hi = (str(x) if isinstance(x, int) else f"{x:g}" for x in (low, high))
    if low is not None and high is not None:
        return f"in {'(' if open_low else '['}{lo}, {hi}{')' if open_high else ']'}{u}"
    if low is not None:
        return f"{'>' if open_low else '>='} {lo}{u}"
    return f"{'<' if open_high else '<='} {hi}{u}"


def check_number(value: Any, where: str, unit: str = "", low: float | None = None, high: float | None = None, *,
                 open_low: bool = False, open_high: bool = False, integer: bool = False) -> float:
    """``value`` as a finite number inside [low, high] (ends open where asked), else InputError naming ``where``.

    Args:
        unit: shown with the number and the range ("" for dimensionless).
        integer: also require an integral value (returned as int).
    """
    u = f" {unit}" if unit else ""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(where, f"{value!r} is not a number{' [' + unit + ']' if unit else ''}")
    try:
        number = int(value) if integer and isinstance(value, str) and value.strip().lstrip("+-").isdigit() \
            else float(value)
    except (ValueError, OverflowError):
        raise InputError(where, f"{value!r} is not a number{' [' + unit + ']' if unit else ''}") from None
    if isinstance(number, float) and not math.isfinite(number):
        raise InputError(where, f"{value!r} is not a finite number{' [' + unit + ']' if unit else ''}")
    if integer:
        if isinstance(number, float):
            if not number.is_integer():
                raise InputError(where, f"{value!r} is not a whole number")
            number = int(number)
    too_low = low is not None and (number <= low if open_low else number < low)
    too_high = high is not None and (number >= high if open_high else number > high)
    if too_low or too_high:
        shown = f"{number}" if integer else f"{number:g}"
        raise InputError(where, f"{shown}{u} is out of range: must be {_bound(low, high, open_low, open_high, unit)}")
    return number


def number(unit: str = "", low: float | None = None, high: float | None = None, *, open_low: bool = False,
           open_high: bool = False, what: str = "") -> Callable[[str], float]:
    """An argparse ``type``: a finite float inside the range, the unit (and ``what`` it is) in the message."""
    def parse(text: str) -> float:
        try:
            return float(check_number(text, "", unit, low, high, open_low=open_low, open_high=open_high))
        except InputError as err:
            raise argparse.ArgumentTypeError(f"{what} {err.what}" if what else err.what) from None
    parse.__name__ = "number"
    return parse


def integer(low: int | None = None, high: int | None = None, unit: str = "", what: str = "") -> Callable[[str], int]:
    """An argparse ``type``: a whole number inside [low, high]."""
    def parse(text: str) -> int:
        try:
            return int(check_number(text, "", unit, low, high, integer=True))
        except InputError as err:
            raise argparse.ArgumentTypeError(f"{what} {err.what}" if what else err.what) from None
    parse.__name__ = "integer"
    return parse


def existing_file(text: str) -> Path:
    """An argparse ``type``: a path that is an existing file (not a folder)."""
    path = Path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text}: no such file")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a folder, expected a file")
    return path


# --- the parser ----------------------------------------------------------------------------------------

class Parser(argparse.ArgumentParser):
    """argparse, with every error as one line ``prog: --option: what`` and exit code 2 (no usage block)."""

    def _get_values(self, action: argparse.Action, arg_strings: list[str]) -> Any:
        # "--opt=--": argparse drops the "--" and hands the option an empty list instead of a value
        if action.nargs is None and action.option_strings and not [a for a in arg_strings if a != "--"]:
            self.error(f"argument {'/'.join(action.option_strings)}: expected a value")
        return super()._get_values(action, arg_strings)

    def error(self, message: str) -> None:  # type: ignore[override]
        where, what = "", message
        if message.startswith("argument "):
            where, _, what = message[len("argument "):].partition(": ")
            where = where.split("/")[-1]  # "-n/--count" -> "--count"
        elif message.startswith("the following arguments are required: "):
            where, what = message.split(": ", 1)[1], "required"
        elif message.startswith("unrecognized arguments: "):
            where, what = message.split(": ", 1)[1], f"unknown option (see {self.prog} --help)"
        print(f"{self.prog}: {where + ': ' if where else ''}{what}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


# --- files ---------------------------------------------------------------------------------------------

def read_text(path: str | os.PathLike[str], what: str = "file") -> str:
    """The whole file as UTF-8 text.

    Raises:
        InputError: missing, a folder, unreadable, larger than MAX_TEXT_BYTES, or not UTF-8 text
            (the message gives the offset of the first bad byte).
    """
    file = Path(path)
    a = f"{'an' if what[:1] in 'aeiou' else 'a'} {what}"
    try:
        if file.is_dir():
            raise InputError(str(file), f"is a folder, expected {a}")
        size = file.stat().st_size
        if size > MAX_TEXT_BYTES:
            raise InputError(str(file), f"{size} bytes: too large for {a} (at most {MAX_TEXT_BYTES})")
        data = file.read_bytes()
    except FileNotFoundError:
        raise InputError(str(file), f"cannot read: no such file (expected {a})") from None
    except OSError as err:
        raise InputError(str(file), f"cannot read: {err.strerror or err}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(str(file), f"not UTF-8 text (byte 0x{data[err.start]:02x} at offset {err.start}): "
                                    f"expected {a}") from None


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses a key given twice in one mapping (PyYAML keeps the last one silently)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == "tag:yaml.org,2002:merge":
                continue  # a merge key (<<) may be overridden; non-scalar keys SafeLoader reports itself
            key = self.construct_object(key_node)  # type: ignore[no-untyped-call]
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first on line {seen[key] + 1})", key_node.start_mark)
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep)


def parse_yaml(text: str, source: str) -> Any:
    """YAML text -> data, refusing duplicate keys; InputError with the line and column."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f"{source}: line {mark.line + 1}, column {mark.column + 1}" if mark else source
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise InputError(where, f"not valid YAML: {problem}") from None


def load_yaml(path: str | os.PathLike[str], what: str = "YAML file") -> Any:
    """A YAML file (see :func:`read_text`, :func:`parse_yaml`)."""
    return parse_yaml(read_text(path, what), str(path))


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    result: dict[str, Any] = {}
    for key, value in pairs:
        if key in result:
            raise ValueError(f"duplicate key {key!r}")
        result[key] = value
    return result


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a finite number")


def parse_json(text: str, source: str) -> Any:
    """JSON text -> data, refusing duplicate keys and NaN/Infinity; InputError with line and column."""
    try:
        return json.loads(text, object_pairs_hook=_no_duplicates, parse_constant=_no_constant)
    except json.JSONDecodeError as err:
        raise InputError(f"{source}: line {err.lineno}, column {err.colno}", f"not valid JSON: {err.msg}") from None
    except (ValueError, RecursionError) as err:
        raise InputError(source, f"not valid JSON: {err}") from None


def load_json(path: str | os.PathLike[str], what: str = "JSON file") -> Any:
    """A JSON file (see :func:`read_text`, :func:`parse_json`)."""
    return parse_json(read_text(path, what), str(path))


# --- what a rig can physically do ---------------------------------------------------------------------

#: a measured value beyond MARGIN times what the rig file says the rig can do is refused as implausible
MARGIN: Final = 2.0
#: largest unwrapped angle accepted [rad]
MAX_ANGLE: Final = 1e12


@dataclass(frozen=True)
class Envelope:
    """Largest magnitude of each rig-data channel the rig can produce, from its rig file, times MARGIN.

    ``omega_worm``: no-load speed at the supply voltage, V/K_e [rad/s]; ``current_drive``: stall current
    V/R [A]; ``tau_load``: what the load motors make at stall, count K_t V/R [N m]; ``current_load``:
    their summed stall current [A]; ``voltage_drive``: the supply [V]; ``temperature`` [degC]: -60..250;
    unwrapped angles [rad]: MAX_ANGLE (the no-load speed for some 80 years). Times are only required
    to be finite.
    """

    limits: dict[str, tuple[float, str]]
    rig_name: str = ""

    @classmethod
    def of(cls, rig: Any, margin: float = MARGIN) -> "Envelope":
        v, d, load = rig.supply_voltage, rig.drive_motor, rig.load_motor
        return cls({
            "omega_worm": (margin * v / d.back_emf_constant, "rad/s"),
            "omega_gear": (margin * v / d.back_emf_constant * rig.gearbox.ratio, "rad/s"),
            "current_drive": (margin * v / d.resistance, "A"),
            "tau_load": (margin * rig.load_motor_count * load.torque_constant * v / load.resistance, "N m"),
            "current_load": (margin * rig.load_motor_count * v / load.resistance, "A"),
            "voltage_drive": (margin * v, "V"),
            "temperature": (250.0, "degC"),
            "theta_worm": (MAX_ANGLE, "rad"),
            "theta_gear": (MAX_ANGLE, "rad"),
        }, getattr(rig, "name", ""))

    def problem(self, column: str, value: float) -> str | None:
        """Why ``value`` of ``column`` is implausible, or None (NaN passes: a missing optional value)."""
        if column not in self.limits or math.isnan(value):
            return None
        limit, unit = self.limits[column]
        if column == "temperature":
            if -60.0 <= value <= limit:
                return None
            return f"{value:g} {unit} is outside -60..{limit:g} {unit}"
        if math.isfinite(value) and abs(value) <= limit:
            return None
        rig = f"rig '{self.rig_name}'" if self.rig_name else "the rig"
        return (f"{value:g} {unit} is far outside what {rig} can do (|value| <= {limit:.4g} {unit}, "
                f"{MARGIN:g} x its rig-file limit)")

    def first_outside(self, column: str, values: Any) -> int | None:
        """Index of the first implausible value of a column (an array), or None."""
        import numpy as np

        if column not in self.limits:
            return None
        arr = np.asarray(values, dtype=float)
        limit = self.limits[column][0]
        if column == "temperature":
            bad = (arr < -60.0) | (arr > limit)
        else:
            with np.errstate(invalid="ignore"):
                bad = ~np.isnan(arr) & ~(np.abs(arr) <= limit)
        hits = np.flatnonzero(bad)
        return int(hits[0]) if hits.size else None


# --- outputs -------------------------------------------------------------------------------------------

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


# --- running a tool ------------------------------------------------------------------------------------

def one_line(err: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(err).split()) or type(err).__name__


def run_tool(tool: str, main: Callable[[], int], bad_input: Sequence[type[BaseException]] = ()) -> int:
    """Run a tool's ``main`` and turn what escapes it into an exit code and one stderr line.

    InputError and the loaders' errors the tool names in ``bad_input`` -> exit 2;
    KeyboardInterrupt -> 130; OSError (disk full, ...) -> exit 1; any other exception is a bug: one line saying so, the traceback
    written to a file named in that line, exit 1.
    """
    try:
        return main()
    except (InputError, *bad_input) as err:
        print(f"{tool}: {one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"{tool}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `... | head`
        sys.stderr.close()
        return 0
    except OSError as err:  # the machine, not the input: a full disk, a folder gone meanwhile
        print(f"{tool}: {one_line(err)}", file=sys.stderr)
        return 1
    except Exception as err:  # noqa: BLE001 - reported as a bug, with its traceback kept
        fd, name = tempfile.mkstemp(prefix=f"{tool}-traceback-", suffix=".txt")
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(f"{tool} {' '.join(sys.argv[1:])}\n\n{traceback.format_exc()}")
        print(f"{tool}: internal error (a bug, please report it): {type(err).__name__}: {one_line(err)}; "
              f"traceback in {name}", file=sys.stderr)
        return 1


__all__ = ["EXIT_BAD_INPUT", "EXIT_INTERRUPTED", "InputError", "check_number", "number", "integer",
           "existing_file", "Parser", "read_text", "parse_yaml", "load_yaml", "parse_json", "load_json",
           "Envelope", "MARGIN", "check_output", "write_text_atomically", "atomic_file", "atomic_dir",
           "one_line", "run_tool"]
