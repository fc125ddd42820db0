"""A node's parameters as data: each :class:`Option` row is declared by the node
(worm_model.ros.parameters.declare_option: default, description, range) and read, without
rclpy and without starting the node, by an offline tool that stands in for it (replay fills
in what a parameter file leaves out from the same rows). No ROS.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

#: the default of a string-array parameter that has none (rclpy cannot infer a type from an empty list)
STRING_ARRAY = "string[]"


@dataclass(frozen=True)
class Option:
    """One parameter: its name, default, description and range (``low``/``high`` for numbers,
    ``choices`` for strings). ``default`` :data:`STRING_ARRAY`: a string array, unset by default."""

    name: str
    default: Any
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] | None = None

    @property
    def value(self) -> Any:
        """The value a node holds when nothing sets the parameter (an unset string array: [])."""
        return [] if self.default == STRING_ARRAY else self.default


#: the rig file every node that models a rig declares (one row, so its name, default and words agree)
RIG_FILE = Option("rig_file", "", "Rig parameter YAML (worm_model format); empty = bundled NMRV030 rig.")


def defaults(rows: Iterable[Option]) -> dict[str, Any]:
    """name -> the value each row's parameter holds when nothing sets it."""
    return {row.name: row.value for row in rows}


__all__ = ["RIG_FILE", "STRING_ARRAY", "Option", "defaults"]
