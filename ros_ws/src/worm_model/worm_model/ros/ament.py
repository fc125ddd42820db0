"""Where a ROS 2 install keeps things: the ament prefixes and the executables `ros2 run` finds.

Plain Python (no rclpy, no ament_index_python), so the bag tools, the graph
runner, the tests and the benchmarks all look things up the same way.
"""
from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path


def ament_prefixes(environ: Mapping[str, str] | None = None) -> list[Path]:
    """The prefixes of ``AMENT_PREFIX_PATH``, in search order (``os.environ`` when None)."""
    value = (os.environ if environ is None else environ).get("AMENT_PREFIX_PATH", "")
    return [Path(entry) for entry in value.split(os.pathsep) if entry]


def find_executable(name: str, prefixes: Sequence[str | Path] | None = None) -> Path:
    """``<prefix>/lib/<pkg>/<name>`` for the first prefix that has it, as `ros2 run` looks.

    Raises:
        FileNotFoundError: no executable of that name under any prefix (the message lists them).
    """
    search = [str(p) for p in (ament_prefixes() if prefixes is None else prefixes)]
    for prefix in search:
        for candidate in sorted(Path(prefix, "lib").glob(f"*/{name}")):
            if os.access(candidate, os.X_OK):
                return candidate
    raise FileNotFoundError(f"no executable '{name}' under lib/<pkg>/ of AMENT_PREFIX_PATH={':'.join(search)}")
