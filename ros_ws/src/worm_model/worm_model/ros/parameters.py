"""Declare node parameters with a description and a range, the way every node here does; and list them.

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
from rclpy.parameter import Parameter


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
        descriptor.additional_constraints = "one of: " + ", ".join(choices)
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


@dataclass(frozen=True)
class DeclaredParameter:
    """One parameter as a node declares it."""

    node: str
    name: str
    type: str
    default: Any
    range: str
    description: str


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
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "double"
    if isinstance(value, (list, tuple)):
        return f"{_type_name(value[0]) if value else 'string'}[]"
    return "string"


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


def declared_parameters(make_node: Callable[[], Node]) -> list[DeclaredParameter]:
    """What ``make_node`` declares, in order, without rclpy running (see the module docstring)."""
    found: list[DeclaredParameter] = []

    def init(self: Node, node_name: str, *args: Any, **kwargs: Any) -> None:
        self.__dict__["_help_name"] = node_name

    def declare_parameter(self: Node, name: str, value: Any = None, descriptor: ParameterDescriptor | None = None,
                          ignore_override: bool = False) -> Parameter:
        found.append(DeclaredParameter(self.__dict__["_help_name"], name, _type_name(value),
                                       None if isinstance(value, Parameter.Type) else value, _range(descriptor),
                                       descriptor.description if descriptor is not None else ""))
        return Parameter(name, value=None if isinstance(value, Parameter.Type) else value)

    def stop(self: Node, *args: Any, **kwargs: Any) -> Any:
        raise _Declared

    here, work = os.getcwd(), tempfile.mkdtemp(prefix="node_help_")
    patches = {"__init__": init, "declare_parameter": declare_parameter,
               "get_name": lambda self: self.__dict__["_help_name"],
               "get_logger": lambda self: _QUIET,  # "Recording into ..." and the like would be untrue
               "destroy_node": lambda self: None,
               "handle": property(stop),  # every call into rcl goes through it
               **{name: stop for name in ("create_publisher", "create_subscription", "create_timer",
                                          "create_service", "create_client", "create_guard_condition",
                                          "add_on_set_parameters_callback", "add_post_set_parameters_callback",
                                          "get_clock")}}
    try:
        os.chdir(work)
        with mock.patch.multiple(Node, **patches):
            try:
                make_node()
            except _Declared:
                pass
    finally:
        os.chdir(here)
        shutil.rmtree(work, ignore_errors=True)
    return found


def help_text(makers: Sequence[Callable[[], Node]], program: str) -> str:
    """``--help`` of a node executable: usage, then every parameter with type, range, default, meaning."""
    lines = [f"usage: {program} [--ros-args -p NAME:=VALUE ... | --params-file FILE]", "",
             "A ROS 2 node: starts, and runs until Ctrl-C / SIGTERM. Parameters (set with -p or a "
             "--params-file; a bad value at start-up is refused with exit code 2):"]
    for make_node in makers:
        declared = declared_parameters(make_node)
        if len(makers) > 1 and declared:
            lines.append(f"\n{declared[0].node}:")
        for p in declared:
            extra = f", range {p.range}" if p.range else ""
            lines.append(f"  {p.name} ({p.type}{extra}, default {p.default!r})")
            lines.append(f"      {p.description}")
    return "\n".join(lines)


def wants_help(argv: Sequence[str]) -> bool:
    """``-h``/``--help`` among the arguments before ``--ros-args`` (ROS's own arguments come after it)."""
    own = list(argv)[: list(argv).index("--ros-args")] if "--ros-args" in argv else list(argv)
    return "-h" in own or "--help" in own
