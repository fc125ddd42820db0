"""Declare node parameters with a description and a range, the way every node here does; list them; and
refuse the ones a node does not declare (a misspelt name) with the closest declared name.

:func:`declare` declares one parameter. :func:`declared_parameters` gets a node's declarations
without starting it (for ``--help``): the node's constructor runs against a stand-in for rclpy's
Node that records every ``declare_parameter`` and stops at the first call into rcl (a publisher,
subscription, timer, a graph query, ...), in a temporary working folder that is removed afterwards. No rclpy
context, no DDS participant, nothing written where the user is. :func:`help_text` formats them.
"""
from __future__ import annotations

import math
import os
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any
from unittest import mock

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.exceptions import InvalidTopicNameException
from rclpy.parameter import Parameter
from rclpy.validate_full_topic_name import validate_full_topic_name

from worm_model.errors import InputError
from worm_model.cli.node_options import STRING_ARRAY, Option
from worm_model.cli.options import article, nearest
from worm_model.files.reading import load_parameter_file, parameter_kind, parse_yaml, ros_arguments


def declare(node: Node, name: str, default: Any, description: str, *,
            low: float | None = None, high: float | None = None, read_only: bool = False,
            choices: tuple[str, ...] | None = None) -> Any:
    """Declare one parameter and return its value (from the params file or the default).

    Numeric parameters get a FloatingPointRange/IntegerRange from low..high, so
    `ros2 param describe` shows it and out-of-range values are refused by rclpy.
    String parameters with choices are checked here, naming the parameter; so is a non-finite double
    (ValueError: the node's run_node turns it into one line and exit code 2).
    """
    descriptor = ParameterDescriptor(description=description, read_only=read_only)
    if choices:
        descriptor.additional_constraints = _CHOICES + ", ".join(choices)
    if low is not None or high is not None:
        lo = float("-inf") if low is None else low
        hi = float("inf") if high is None else high
        if isinstance(default, bool):
            raise TypeError(f"parameter {name}: a bool has no range")
        if isinstance(default, int):
            descriptor.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi),
                                                                  step=0.0)]
    value = node.declare_parameter(name, default, descriptor).value
    # rclpy's range check lets inf through a half-open range and NaN through any; no quantity here is either.
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"parameter {name}: {value!r} is not a finite number")
    if choices and value not in choices:
        raise ValueError(f"parameter {node.get_name()}.{name}={value!r} is not one of {choices}")
    return value


def declare_option(node: Node, option: Option, default: Any = None) -> Any:
    """Declare one Option row (worm_model.cli.node_options) on ``node`` and return its value; ``default``
    replaces the row's (a node whose default depends on another parameter). An unset string array: []."""
    value = option.default if default is None else default
    declared = declare(node, option.name, Parameter.Type.STRING_ARRAY if value == STRING_ARRAY else value,
                       option.description, low=option.low, high=option.high, choices=option.choices)
    return [] if declared is None and value == STRING_ARRAY else declared


@dataclass(frozen=True)
class DeclaredParameter:
    """One parameter as a node declares it."""

    node: str
    name: str
    type: str
    default: Any
    range: str
    description: str
    bounds: tuple[float, float] | None = None
    """[low, high] of a numeric parameter, None without a range."""
    choices: tuple[str, ...] = ()
    """The values a string parameter may take (declare's ``choices``), () for any."""


class _Quiet:
    """A logger that says nothing (the node is not really starting)."""

    def __getattr__(self, name: str) -> Callable[..., None]:
        return lambda *args, **kwargs: None


_QUIET = _Quiet()


class _Declared(Exception):
    """The node has started to make endpoints or timers: its declarations are over."""


def _type_name(value: Any) -> str:
    if isinstance(value, Parameter.Type):
        return {Parameter.Type.STRING_ARRAY: "string[]", Parameter.Type.DOUBLE_ARRAY: "double[]",
                Parameter.Type.INTEGER_ARRAY: "integer[]", Parameter.Type.BOOL_ARRAY: "bool[]"}.get(value, "string")
    if isinstance(value, (list, tuple)):
        return f"{_type_name(value[0]) if value else 'string'}[]"
    return parameter_kind(value) or "string"


def _range(descriptor: ParameterDescriptor | None) -> str:
    if descriptor is None:
        return ""
    parts = []
    for r in descriptor.floating_point_range:
        parts.append(f"[{r.from_value:g}, {r.to_value:g}]")
    for r in descriptor.integer_range:
        parts.append(f"[{r.from_value}, {r.to_value}]")
    if descriptor.additional_constraints:
        parts.append(descriptor.additional_constraints)
    return "; ".join(parts)


def _bounds(descriptor: ParameterDescriptor | None) -> tuple[float, float] | None:
    if descriptor is None:
        return None
    for r in [*descriptor.floating_point_range, *descriptor.integer_range]:
        return float(r.from_value), float(r.to_value)
    return None


_CHOICES = "one of: "


def _choices(descriptor: ParameterDescriptor | None) -> tuple[str, ...]:
    text = descriptor.additional_constraints if descriptor is not None else ""
    return tuple(c.strip() for c in text[len(_CHOICES):].split(",")) if text.startswith(_CHOICES) else ()


def declared_parameters(make_node: Callable[[], Node],
                        given: dict[str, Any] | None = None) -> list[DeclaredParameter]:
    """What ``make_node`` declares, in order, without rclpy running (see the module docstring). A node whose
    declarations depend on a choice (estimator_node's ``method`` and ``input``) sees ``given``'s value of a
    parameter with choices instead of its default, and ``given``'s list for a list declared without a default
    (the joints a choice then needs): what it declares with them."""
    found: list[DeclaredParameter] = []
    given = given or {}

    def init(self: Node, node_name: str, *args: Any, **kwargs: Any) -> None:
        self.__dict__["_help_name"] = node_name

    def declare_parameter(self: Node, name: str, value: Any = None, descriptor: ParameterDescriptor | None = None,
                          ignore_override: bool = False) -> Parameter:
        found.append(DeclaredParameter(self.__dict__["_help_name"], name, _type_name(value),
                                       None if isinstance(value, Parameter.Type) else value, _range(descriptor),
                                       descriptor.description if descriptor is not None else "",
                                       _bounds(descriptor), _choices(descriptor)))
        if isinstance(value, Parameter.Type):  # a list with no default (joint names, per-joint files)
            chosen = given.get(name)
            return Parameter(name, value=chosen if isinstance(chosen, list) else None)
        # a choice among named options (method, input) selects what else is declared; any other given value
        # (a file, a folder) could make the dry run act on it, so it keeps its default
        chosen = given.get(name, value) if _choices(descriptor) else value
        return Parameter(name, value=chosen if chosen in _choices(descriptor) else value)

    def stop(self: Node, *args: Any, **kwargs: Any) -> Any:
        raise _Declared

    here, work = os.getcwd(), tempfile.mkdtemp(prefix="node_help_")
    patches = {"__init__": init, "declare_parameter": declare_parameter,
               "get_name": lambda self: self.__dict__["_help_name"],
               "get_logger": lambda self: _QUIET,  # "Recording into ..." and the like would be untrue
               "destroy_node": lambda self: None,
               "handle": property(stop),  # every call into rcl goes through it
               # plain Python in rclpy, and a node may declare more after them (controller_node does)
               "add_on_set_parameters_callback": lambda self, *args, **kwargs: None,
               "add_post_set_parameters_callback": lambda self, *args, **kwargs: None,
               **{name: stop for name in ("create_publisher", "create_subscription", "create_timer",
                                          "create_service", "create_client", "create_guard_condition",
                                          "get_clock")}}
    try:
        os.chdir(work)
        with mock.patch.multiple(Node, **patches):
            try:
                make_node()
            except _Declared:
                pass
            except InputError:  # it refuses what the dry run gave it (knn with no calibration): declared so far
                pass
    finally:
        os.chdir(here)
        shutil.rmtree(work, ignore_errors=True)
    return found


def help_text(makers: Sequence[Callable[[], Node]], program: str) -> str:
    """``--help`` of a node executable: usage, then every parameter with type, range, default, meaning."""
    lines = [f"usage: {program} [--ros-args -p NAME:=VALUE ... | --params-file FILE]", "",
             "A ROS 2 node: starts, and runs until Ctrl-C / SIGTERM. Parameters (set with -p or a "
             "--params-file; at start-up a bad value, a parameter file rcl cannot read (YAML anchors, aliases "
             "and merge keys included) and a name the node does not declare (a misspelling: the closest "
             "declared name is given) are refused with exit code 2; names under a wildcard section such as "
             "/** are for every node, and a node ignores those it does not declare):"]
    for make_node in makers:
        declared = declared_parameters(make_node)
        if len(makers) > 1 and declared:
            lines.append(f"\n{declared[0].node}:")
        for p in declared:
            extra = f", range {p.range}" if p.range else ""
            lines.append(f"  {p.name} ({p.type}{extra}, default {p.default!r})")
            lines.append(f"      {p.description}")
    return "\n".join(lines)


def ros_value(text: str) -> Any:
    """A ``-p NAME:=VALUE`` value as rcl reads it: YAML (true, 3, 2.5, [1, 2], 'text'), else the text."""
    try:
        value = parse_yaml(text, "value") if text.strip() else ""
    except InputError:
        return text
    return value


def _as_declared(p: DeclaredParameter, value: Any) -> Any:
    """``value`` read as rcl would read it for ``p``: PyYAML leaves 1e3 a string where rcl reads a double."""
    if isinstance(value, str) and p.type in ("double", "integer"):
        try:
            number = float(value)
        except ValueError:
            return value
        return number if p.type == "double" or not number.is_integer() or "." in value else int(number)
    return value


def value_problem(p: DeclaredParameter, value: Any) -> str | None:
    """Why the node would refuse ``value`` for ``p`` (type, range, choices), or None."""
    value = _as_declared(p, value)
    kind = _type_name(value) if not isinstance(value, list) or value else p.type
    if value is None or kind != p.type:
        shown = "nothing" if value is None else f"{value!r} ({kind})"
        return f"expected {article(p.type)} like its default {p.default!r}, got {shown}"
    if p.bounds is not None and isinstance(value, (int, float)) and not p.bounds[0] <= value <= p.bounds[1]:
        return f"{value!r} is out of range: must be in {p.range.split(';')[0]}"
    if p.choices and value not in p.choices:
        return f"{value!r} is not one of {', '.join(p.choices)}"
    return None


def parameters_problem(node: str, declared: Sequence[DeclaredParameter],
                       values: dict[str, Any]) -> tuple[str, str] | None:
    """(name, why) ``node`` (declaring ``declared``) would refuse one of ``values`` (name -> value) at start,
    or None: a name it does not declare (the closest one named), or a value of the wrong type, out of range
    or not one of its choices. What a node checks when it starts, checked before anything is started."""
    table = {p.name: p for p in declared}
    for name, value in values.items():
        p = table.get(name)
        if p is None:
            return name, f"{node} declares no such parameter{nearest(name, table)}; see {node} --help"
        problem = value_problem(p, value)
        if problem:
            return name, problem
    return None


def wildcard_names(argv: Sequence[str]) -> set[str]:
    """Parameter names set in a wildcard section (``/**``, ``/*``...) of the ``--params-file`` arguments: they
    are for every node of a graph, and a node ignores those it does not declare."""
    names: set[str] = set()
    for flag, value in ros_arguments(list(argv)):
        if flag != "--params-file":
            continue
        try:
            sections = load_parameter_file(value)
        except InputError:
            continue  # refused before (lifecycle.start_problem)
        for node, values in sections.items():
            if "*" in node:
                names |= set(values)
    return names


#: parameters rclpy declares in every node itself (and the QoS overrides it declares for an endpoint that
#: allows them): never "undeclared" to the check before the node is built
ROS_PARAMETERS = frozenset({"use_sim_time", "start_type_description_service"})


def _ros_own(name: str) -> bool:
    return name in ROS_PARAMETERS or name.startswith("qos_overrides.")


def given_values(argv: Sequence[str], node: str) -> dict[str, tuple[str, Any]]:
    """The parameters the arguments give the node named ``node``: name -> (where: "-p" or the file, value):
    the ``-p NAME:=VALUE`` ones (all nodes of the process, or ``-p node:NAME:=VALUE``) and those of the
    parameter files' sections for it (``node``, ``/node``, ``/ns/node``; wildcard sections are for every
    node). A name given twice keeps its last value, as rcl does (-p after the files)."""
    given: dict[str, tuple[str, Any]] = {}
    for flag, value in ros_arguments(list(argv)):
        if flag == "-p":
            assignment, _, text = value.partition(":=")
            target, _, name = assignment.rpartition(":")
            if not target or target.split("/")[-1] == node:
                given[name] = ("-p", ros_value(text))
            continue
        try:
            sections = load_parameter_file(value)
        except InputError:
            continue  # refused before (lifecycle.start_problem)
        for section, values in sections.items():
            if "*" not in section and section.split("/")[-1] == node:
                for name, setting in values.items():
                    given[name] = (f"--params-file {value}", setting)
    return given


def given_names(argv: Sequence[str], node: str) -> dict[str, str]:
    """The parameter names the arguments give the node ``node`` -> where (:func:`given_values`)."""
    return {name: where for name, (where, _value) in given_values(argv, node).items()}


def _topic_problem(value: Any) -> str | None:
    """Why ``value`` (a topic name, or a list of them) is no valid ROS topic name, or None."""
    for topic in value if isinstance(value, list) else [value]:
        if not isinstance(topic, str) or not topic:
            continue  # a type problem (rclpy names it) or empty (the node's default)
        try:
            validate_full_topic_name(topic if topic.startswith(("/", "~")) else "/" + topic)
        except InvalidTopicNameException as err:
            why = [line for line in str(err).splitlines() if line.strip()][0].partition(": ")[2].rstrip(":")
            return f"{topic!r} is not a valid topic name ({why})"
    return None


def undeclared_problem(makers: Sequence[Callable[[], Node]], argv: Sequence[str]) -> str | None:
    """A parameter the arguments give a node that it does not declare (the nodes' declarations as --help
    reads them), or a topic parameter (``*topic``, ``*topics``) that is no valid ROS name, found before
    anything starts, or None: ``parameter <name> (<where>): ...``."""
    declared: dict[str, set[str]] = {}
    for make_node in makers:
        try:
            found = declared_parameters(make_node)
            if found:  # again with the values given: what it declares may depend on them (method, input)
                values = {name: value for name, (_where, value) in given_values(argv, found[0].node).items()}
                found = declared_parameters(make_node, values) if values else found
        except Exception:  # noqa: BLE001 - cannot tell now; check_undeclared tells once the node is built
            return None
        if found:
            declared[found[0].node] = {p.name for p in found}
    everywhere = set().union(*declared.values()) if declared else set()
    exempt = wildcard_names(argv)
    for node, names in declared.items():
        for name, (where, value) in given_values(argv, node).items():
            if name not in everywhere and name not in exempt and not _ros_own(name):
                return (f"parameter {name} ({where}): {node} declares no such parameter{nearest(name, names)}; "
                        f"see {node} --help")
            if name.endswith(("topic", "topics")) and (problem := _topic_problem(value)):
                return f"parameter {name} ({where}): {problem}"
    return None


def check_undeclared(nodes: Sequence[Node], exempt: set[str] = frozenset()) -> None:
    """Refuse a parameter given to a node (by -p or its section of a parameter file) that it does not declare.

    A misspelt name (``sampel_rate``, ``methd``) would otherwise be ignored without a word and the node
    run on the default. Names declared by another node of the same process, and ``exempt`` ones (a
    parameter file's wildcard sections), pass.

    Raises:
        ValueError: ``parameter <name>: <node> declares no such parameter (did you mean '<closest>'?)``.
    """
    declared_anywhere = {name for node in nodes for name in node._parameters}  # noqa: SLF001 - rclpy's table
    for node in nodes:
        declared = set(node._parameters)  # noqa: SLF001
        given = getattr(node, "_parameter_overrides", {})
        for name in sorted(given):
            if name in declared or name in declared_anywhere or name in exempt:
                continue
            raise ValueError(f"parameter {name}: {node.get_name()} declares no such parameter"
                             f"{nearest(name, declared)}; see {node.get_name()} --help")


def wants_help(argv: Sequence[str]) -> bool:
    """``-h``/``--help`` among the arguments before ``--ros-args`` (ROS's own arguments come after it)."""
    own = list(argv)[: list(argv).index("--ros-args")] if "--ros-args" in argv else list(argv)
    return "-h" in own or "--help" in own
