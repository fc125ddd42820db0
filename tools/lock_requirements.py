#!/usr/bin/env python3
"""Write requirements.lock from what is installed in this interpreter's environment.

Only real distributions (dist-info) are pinned: the ros-* wheels also install
inner egg-info entries (rclpy, std_msgs, ...) that are not PyPI projects.
"""
from __future__ import annotations

import importlib.metadata as metadata
from pathlib import Path

HEADER = """# Every Python dependency of the project, pinned to exact versions (one file).
# ROS 2 Kilted from the ros-* wheels with rmw_fastrtps_cpp as the RMW, colcon,
# numpy/scipy/matplotlib, pyserial, rosbags (+ mcap readers), pytest, hypothesis.
# Regenerate: tools/lock_requirements.py (keeps real distributions only; the
# ros-* wheels also carry inner egg-info entries that are not on PyPI).
"""


def pinned_distributions() -> list[str]:
    pins = set()
    for dist in metadata.distributions():
        path = Path(str(getattr(dist, "_path", "")))
        name = dist.metadata["Name"]
        if path.suffix == ".dist-info" and name.lower() != "pip":
            pins.add(f"{name}=={dist.version}")
    return sorted(pins, key=str.lower)


if __name__ == "__main__":
    target = Path(__file__).resolve().parent.parent / "requirements.lock"
    target.write_text(HEADER + "\n".join(pinned_distributions()) + "\n", encoding="utf-8")
    print(f"wrote {target}")
