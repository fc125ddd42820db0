"""Declare node parameters with a description and a range, the way every node here does."""
from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node


def declare(node: Node, name: str, default: Any, description: str, *,
            low: float | None = None, high: float | None = None, read_only: bool = False,
            choices: tuple[str, ...] | None = None) -> Any:
    """Declare one parameter and return its value (from the params file or the default).

    Numeric parameters get a FloatingPointRange/IntegerRange from low..high, so
    `ros2 param describe` shows it and out-of-range values are refused by rclpy.
    String parameters with choices are checked here, naming the parameter.
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
    if choices and value not in choices:
        raise ValueError(f"parameter {node.get_name()}.{name}={value!r} is not one of {choices}")
    return value
