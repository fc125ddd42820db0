#!/usr/bin/env python3
"""Apply the known fixes the ROS 2 PyPI wheels need before colcon can build against them.

The wheels' exported CMake targets name the build host's Python paths
(/opt/python/cp311-cp311/...); a message package that depends on another
package's messages then fails at CMake generate time. This rewrites those
prefixes in <venv>/share/**/*.cmake to this interpreter's include dir and
site-packages (see shared/docs/ros2-from-pypi.md, item 4). Idempotent.
"""
from __future__ import annotations

import argparse
import sys
import sysconfig
from pathlib import Path

BUILD_HOST_INCLUDE = "/opt/python/cp311-cp311/include/python3.11"
BUILD_HOST_SITE = "/opt/python/cp311-cp311/lib/python3.11/site-packages"


def rewrite(venv: Path) -> int:
    """Rewrite the build host's paths in every CMake file under venv/share; return files changed."""
    include = sysconfig.get_paths()["include"]
    site = sysconfig.get_paths()["purelib"]
    changed = 0
    for cmake_file in (venv / "share").rglob("*.cmake"):
        text = cmake_file.read_text(encoding="utf-8", errors="surrogateescape")
        if BUILD_HOST_INCLUDE not in text and BUILD_HOST_SITE not in text:
            continue
        text = text.replace(BUILD_HOST_INCLUDE, include).replace(BUILD_HOST_SITE, site)
        cmake_file.write_text(text, encoding="utf-8", errors="surrogateescape")
        changed += 1
    return changed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--venv", type=Path, default=Path(sys.prefix),
                        help="virtual environment holding the ros-* wheels (default: this interpreter's)")
    args = parser.parse_args(argv)
    changed = rewrite(args.venv)
    print(f"fix_ros_wheels: rewrote build-host paths in {changed} CMake file(s) under {args.venv / 'share'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
