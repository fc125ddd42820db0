"""The rig's topics a session with it uses (relative names: a namespace moves them all)."""
from __future__ import annotations

from typing import Final

#: what a session listens to (the rig's samples, controller_node's speed commands) and commands (the set-point
#: controller_node follows, the rig's load)
TOPICS: Final[dict[str, str]] = {"samples": "rig/samples", "speed_command": "rig/speed_command",
                                 "speed_setpoint": "controller/speed_setpoint", "load_command": "rig/load_command"}

__all__ = ["TOPICS"]
