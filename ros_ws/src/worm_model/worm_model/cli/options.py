"""Command-line options and numbers read from files, checked alike: finite, inside a physical range,
the unit named in the message; input and output paths (:func:`input_path`, ``existing_file``,
``existing_bag``, :func:`output_path`); :func:`nearest` for a misspelt name; :class:`Parser`, an
ArgumentParser whose errors are one line and exit 2.
"""
from __future__ import annotations

import argparse
import difflib
import math
import os
import stat
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from worm_model.cli.errors import EXIT_BAD_INPUT
from worm_model.errors import InputError


def _bound(low: float | None, high: float | None, open_low: bool, open_high: bool, unit: str) -> str:
    u = f" {unit}" if unit else ""
    lo, hi = (str(x) if isinstance(x, int) or x is None else f"{x:g}" for x in (low, high))
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


_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def article(what: str) -> str:
    """``what`` with its indefinite article ("an effects file")."""
    return f"{'an' if what[:1] in 'aeiou' else 'a'} {what}"


def input_problem(path: str | os.PathLike[str], what: str = "file", folder: bool = False) -> str | None:
    """Why ``path`` cannot be read as ``what`` (missing, a folder, a FIFO, a device, ...), or None.

    The path is only stat-ed, never opened: opening a FIFO waits for a writer that may never come.
    ``folder``: a folder is fine too (a bag folder).
    """
    if not str(path):
        return f"empty path, expected {article(what)} (an unset shell variable?)"
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return f"cannot read: no such file (expected {article(what)})"
    except OSError as err:
        return f"cannot read: {err.strerror or err}"
    if stat.S_ISREG(mode) or folder and stat.S_ISDIR(mode):
        return None
    kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
    return f"is {kind}, expected {article(what)}" + (" or a folder" if folder else "")


def input_path(what: str = "file", folder: bool = False) -> Callable[[str], Path]:
    """An argparse ``type``: an existing regular file (with ``folder``, or a folder), refused naming ``what``."""
    def parse(text: str) -> Path:
        problem = input_problem(text, what, folder)
        if problem:
            raise argparse.ArgumentTypeError(f"{text}: {problem}" if text else problem)
        return Path(text)
    parse.__name__ = "input_path"
    return parse


#: an argparse ``type``: an existing regular file (not a folder, FIFO or device; stat-ed, never opened)
existing_file = input_path()
#: an argparse ``type``: an existing regular file, or a folder (a bag folder)
existing_input = input_path(folder=True)
#: an argparse ``type``: a rosbag2 bag, a folder or one storage file
existing_bag = input_path("bag folder or .mcap/.db3 file", folder=True)


def output_path(text: str) -> Path:
    """An argparse ``type`` for an output: any path but an empty one (what ``--out "$UNSET"`` becomes)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty path (an unset shell variable?): name the file or folder to write")
    return Path(text)


def log_folder(text: str) -> Path:
    """An argparse ``type`` for a folder written into (created if missing): not empty, and not an existing file."""
    path = output_path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{path}: a file, not a folder (name a folder to write the logs into)")
    return path


def nearest(name: str, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the known name closest to a misspelt ``name``, or ""."""
    match = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f" (did you mean {match[0]!r}?)" if match else ""


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
