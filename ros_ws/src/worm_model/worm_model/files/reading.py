"""Reading a user's file: UTF-8 text, YAML or JSON, refusing folders, binary files, duplicate keys and
NaN/Infinity, every refusal an InputError naming the file (and the line and column where there is one).
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Final

import yaml

from worm_model.cli.errors import InputError

#: largest file the text readers accept [bytes]: a rig, effects, graph or calibration file is far smaller
MAX_TEXT_BYTES: Final = 64 * 1024 * 1024


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
