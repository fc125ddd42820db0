"""Reading a user's file: regular files only, UTF-8 text (a byte-order mark is allowed), YAML and JSON with
limits, every refusal an InputError naming the file (and the line and column where there is one).

What is refused, and why:

* anything but a regular file where a file is expected (:func:`check_input`): a folder, a FIFO, a socket,
  a device. The path is only stat-ed, never opened: opening a FIFO waits for a writer that may never
  come. A folder is accepted where a bag folder is expected (``folder=True``).
* a file larger than the reader's limit (:data:`MAX_TEXT_BYTES`, :data:`MAX_YAML_BYTES`).
* text that is not UTF-8. A leading byte-order mark (U+FEFF, what some editors write) is dropped.
* YAML nested deeper than :data:`MAX_YAML_DEPTH` levels, or whose aliases (``*name``) expand it to more
  than :data:`MAX_YAML_NODES` nodes (a "billion laughs" file: a few lines that stand for 10^9 values);
  a key given twice in one mapping (PyYAML would keep the last one silently). Anchors, aliases and
  merge keys (``&name``, ``*name``, ``<<: *name``) are otherwise read as YAML defines them: the bundled
  rig file shares its motor section that way.
* JSON nested deeper than Python's parser can go, a key given twice, NaN or Infinity.
* a ROS 2 parameter file (:func:`load_parameter_file`) that rcl, which reads it in every node, would
  refuse with a traceback: anchors, aliases and merge keys (rcl does not read them), a value beside
  ``ros__parameters``, a list mixing types.

Every file read through here is remembered (:func:`inputs_read`) so that an output about to replace
something can be checked against the inputs of the run (worm_model.files.writing).
"""
from __future__ import annotations

import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Final

import yaml

from worm_model.errors import InputError
from worm_model.cli.options import article, input_problem

#: largest file the text readers accept [bytes]: a calibration database is far smaller
MAX_TEXT_BYTES: Final = 64 * 1024 * 1024
#: largest YAML file accepted [bytes]: a rig, effects or graph file is a few kB (PyYAML reads ~1 MB/s)
MAX_YAML_BYTES: Final = 4 * 1024 * 1024
#: deepest nesting of mappings and lists accepted in a YAML file (a rig file has 4 levels)
MAX_YAML_DEPTH: Final = 64
#: most nodes a YAML document may stand for once its aliases are expanded (a rig file has ~400)
MAX_YAML_NODES: Final = 200_000

_READ: dict[Path, None] = {}


def _note(path: Path) -> None:
    try:
        _READ[path.resolve()] = None
    except (OSError, RuntimeError):  # a symlink loop: the stat before already refused it
        pass


def inputs_read() -> list[Path]:
    """Every file or folder this process read through :func:`check_input` (resolved), in reading order."""
    return list(_READ)


@contextmanager
def not_an_input(path: str | os.PathLike[str]) -> Iterator[None]:
    """Reading ``path`` inside this block does not make it an input (a tool looking at its own earlier output to
    recognise it); a path read before stays one."""
    try:
        resolved = Path(path).resolve()
    except (OSError, RuntimeError):
        resolved = None
    before = resolved in _READ
    try:
        yield
    finally:
        if resolved is not None and not before:
            _READ.pop(resolved, None)


def check_input(path: str | os.PathLike[str], what: str = "file", *, folder: bool = False,
                where: str = "") -> Path:
    """``path`` as an input: an existing regular file (or, with ``folder``, a folder), checked without opening it.

    Args:
        what: what the file should be, for the message ("rig parameter file").
        folder: a folder is accepted too (a bag folder).
        where: what names the path in the message (an option: ``--rig``); default the path itself.

    Raises:
        InputError: missing, unreadable, or a folder/FIFO/device/socket where a file is expected.
    """
    file = Path(path)
    problem = input_problem(path, what, folder)
    if problem:
        raise InputError(f"{where} {path}".strip() if where else (str(path) or "path"), problem)
    _note(file)
    return file


def read_bytes(path: str | os.PathLike[str], what: str = "file", limit: int = MAX_TEXT_BYTES) -> bytes:
    """The whole of a regular file (:func:`check_input`), at most ``limit`` bytes.

    Raises:
        InputError: not a regular file, unreadable, or larger than ``limit``.
    """
    file = check_input(path, what)
    try:
        size = file.stat().st_size
        if size > limit:
            raise InputError(str(file), f"{size} bytes: too large for {article(what)} (at most {limit})")
        with file.open("rb") as stream:
            data = stream.read(limit + 1)
    except OSError as err:
        raise InputError(str(file), f"cannot read: {err.strerror or err}") from None
    if len(data) > limit:  # grew meanwhile, or a file whose size stat does not tell
        raise InputError(str(file), f"more than {limit} bytes: too large for {article(what)}")
    return data


def decode_text(data: bytes, source: str, what: str = "file") -> str:
    """UTF-8 bytes -> text, a leading byte-order mark dropped.

    Raises:
        InputError: not UTF-8 (the offset of the first bad byte named).
    """
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise InputError(source, f"not UTF-8 text (byte 0x{data[err.start]:02x} at offset {err.start}): "
                                 f"expected {article(what)}") from None


def read_text(path: str | os.PathLike[str], what: str = "file", limit: int = MAX_TEXT_BYTES) -> str:
    """The whole file as UTF-8 text (see :func:`read_bytes`, :func:`decode_text`).

    Raises:
        InputError: missing, not a regular file, unreadable, larger than ``limit``, or not UTF-8 text.
    """
    return decode_text(read_bytes(path, what, limit), str(path), what)


class _Limit(yaml.composer.ComposerError):
    """A YAML file beyond one of the reader's limits (not malformed: too deep or too large)."""


class _NoAliases(yaml.composer.ComposerError):
    """An anchor, alias or merge key where rcl reads the file (a ROS parameter file)."""


class _LimitedLoader(yaml.SafeLoader):
    """SafeLoader with limits: nesting depth, nodes after alias expansion, and no key given twice; with
    ``anchors`` False, no anchor or alias at all."""

    def __init__(self, stream: str, anchors: bool = True) -> None:
        super().__init__(stream)
        self._depth = 0
        self._sizes: dict[int, int] = {}
        self._anchors = anchors

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        event = self.peek_event()
        if not self._anchors and (isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None)):
            shown = f"*{event.anchor}" if isinstance(event, yaml.AliasEvent) else f"&{event.anchor}"
            raise _NoAliases(None, None, f"{shown}: ROS parameter files cannot use YAML anchors, aliases or merge "
                                         "keys (&name, *name, <<): rcl, which reads them in every node, does not; "
                                         "write the values out", event.start_mark)
        if isinstance(event, yaml.AliasEvent):
            return super().compose_node(parent, index)  # its size counts where it is used, below
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise _Limit(
                    None, None, f"nested deeper than {MAX_YAML_DEPTH} levels", event.start_mark)
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
        if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
            children = [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else node.value
            size = 1 + sum(self._sizes.get(id(child), 1) for child in children)
            if size > MAX_YAML_NODES:
                raise _Limit(
                    None, None, f"its aliases (*name) expand it to more than {MAX_YAML_NODES} values "
                                "(a 'billion laughs' file?)", node.start_mark)
            self._sizes[id(node)] = size
        return node

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


def _yaml_error(err: yaml.YAMLError, source: str) -> InputError:
    mark = getattr(err, "problem_mark", None)
    where = f"{source}: line {mark.line + 1}, column {mark.column + 1}" if mark else source
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    if isinstance(err, _NoAliases):
        return InputError(where, problem)
    return InputError(where, f"refused: {problem}" if isinstance(err, _Limit) else f"not valid YAML: {problem}")


def parse_yaml(text: str, source: str, anchors: bool = True) -> Any:
    """YAML text -> data within the limits of the module docstring; InputError with the line and column.

    ``anchors`` False refuses anchors, aliases and merge keys (what rcl cannot read).
    """
    if len(text) > MAX_YAML_BYTES:
        raise InputError(source, f"{len(text)} characters: too large for a YAML file (at most {MAX_YAML_BYTES})")
    loader = None
    try:
        loader = _LimitedLoader(text, anchors)  # its reader refuses control characters already
        return loader.get_single_data()
    except yaml.YAMLError as err:
        raise _yaml_error(err, source) from None
    except RecursionError:  # a limit above should come first; this is the backstop
        raise InputError(source, f"not valid YAML: nested too deeply (at most {MAX_YAML_DEPTH} levels)") from None
    finally:
        if loader is not None:
            loader.dispose()


def check_yaml(text: str, source: str) -> None:
    """Refuse YAML text beyond the limits of the module docstring without building it (for files another
    YAML library reads: a bag's metadata.yaml); InputError with the line and column."""
    if len(text) > MAX_YAML_BYTES:
        raise InputError(source, f"{len(text)} characters: too large for a YAML file (at most {MAX_YAML_BYTES})")
    loader = None
    try:
        loader = _LimitedLoader(text)
        while loader.check_node():
            loader.get_node()
    except yaml.YAMLError as err:
        raise _yaml_error(err, source) from None
    except RecursionError:
        raise InputError(source, f"refused: nested too deeply (at most {MAX_YAML_DEPTH} levels)") from None
    finally:
        if loader is not None:
            loader.dispose()


def load_yaml(path: str | os.PathLike[str], what: str = "YAML file") -> Any:
    """A YAML file (see :func:`read_text`, :func:`parse_yaml`)."""
    return parse_yaml(read_text(path, what, MAX_YAML_BYTES), str(path))


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
    """JSON text -> data, refusing duplicate keys, NaN/Infinity and deep nesting; InputError with line and column."""
    try:
        return json.loads(text, object_pairs_hook=_no_duplicates, parse_constant=_no_constant)
    except json.JSONDecodeError as err:
        raise InputError(f"{source}: line {err.lineno}, column {err.colno}", f"not valid JSON: {err.msg}") from None
    except RecursionError:
        raise InputError(source, "not valid JSON: nested too deeply for a data file") from None
    except ValueError as err:
        raise InputError(source, f"not valid JSON: {err}") from None


def load_json(path: str | os.PathLike[str], what: str = "JSON file") -> Any:
    """A JSON file (see :func:`read_text`, :func:`parse_json`)."""
    return parse_json(read_text(path, what), str(path))


# --- ROS 2 parameter files ------------------------------------------------------------------------------

PARAMETERS_KEY: Final = "ros__parameters"


def parameter_kind(value: Any) -> str | None:
    """The ROS parameter type of a scalar (bool, integer, double, string), None for anything else."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "double"
    if isinstance(value, str):
        return "string"
    return None


def _flatten(values: Any, prefix: str, source: str, node: str, out: dict[str, Any]) -> None:
    """``ros__parameters`` -> {dotted name: value}, refusing what rcl cannot read."""
    if not isinstance(values, dict):
        raise InputError(source, f"{node}.{PARAMETERS_KEY}{prefix and '.' + prefix}: expected a mapping of "
                                 f"parameter names to values, got {type(values).__name__}")
    for key, value in values.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            _flatten(value, name, source, node, out)
            continue
        if isinstance(value, list):
            kinds = {parameter_kind(v) for v in value}
            if None in kinds or len(kinds) > 1:
                raise InputError(source, f"{node}: parameter {name}: a list must hold values of one type "
                                         f"(bool, integer, double or string), got {value!r}")
        elif value is not None and parameter_kind(value) is None:
            raise InputError(source, f"{node}: parameter {name}: {value!r} is not a parameter value")
        out[name] = value


def _sections(document: Any, source: str, namespace: str, out: dict[str, dict[str, Any]]) -> None:
    if not isinstance(document, dict):
        raise InputError(source, f"{namespace or 'top level'}: expected node names mapping to "
                                 f"'{PARAMETERS_KEY}:', got {type(document).__name__}")
    for key, body in document.items():
        name = f"{namespace}/{key}".lstrip("/") if namespace else str(key)
        if not isinstance(body, dict):
            raise InputError(source, f"{name}: expected '{PARAMETERS_KEY}:' (or a node name below a "
                                     f"namespace), got {body!r}")
        if PARAMETERS_KEY in body:
            stray = [k for k in body if k != PARAMETERS_KEY]
            if stray:
                raise InputError(source, f"{name}: {stray[0]!r} beside {PARAMETERS_KEY}: a node section holds "
                                         f"only {PARAMETERS_KEY}")
            values: dict[str, Any] = {}
            _flatten(body[PARAMETERS_KEY] if body[PARAMETERS_KEY] is not None else {}, "", source, name, values)
            out.setdefault(name, {}).update(values)
        else:
            _sections(body, source, name, out)


def load_parameter_file(path: str | os.PathLike[str]) -> dict[str, dict[str, Any]]:
    """A ROS 2 parameter file as {node name: {parameter: value}}, checked the way rcl will read it.

    Node names are as written (``estimator_node``, ``/**``, ``ns/node`` for a node below a namespace);
    nested parameter mappings are flattened to dotted names, as ROS names them.

    Raises:
        InputError: not a regular file, not UTF-8, not YAML within the limits, YAML anchors/aliases/merge
            keys, no node sections, a value beside ``ros__parameters``, a list mixing types.
    """
    source = str(path)
    document = parse_yaml(read_text(path, "ROS parameter file", MAX_YAML_BYTES), source, anchors=False)
    if not isinstance(document, dict) or not document:
        raise InputError(source, f"expected node names at the top level, each with '{PARAMETERS_KEY}:'")
    out: dict[str, dict[str, Any]] = {}
    _sections(document, source, "", out)
    return out


def ros_arguments(argv: list[str]) -> Iterator[tuple[str, str]]:
    """``(flag, value)`` of the ``--params-file FILE`` and ``-p NAME:=VALUE`` arguments after ``--ros-args``."""
    if "--ros-args" not in argv:
        return
    rest = argv[argv.index("--ros-args") + 1:]
    for k, arg in enumerate(rest):
        if arg == "--":
            return
        if arg in ("--params-file", "-p", "--param") and k + 1 < len(rest):
            yield ("--params-file" if arg == "--params-file" else "-p"), rest[k + 1]
