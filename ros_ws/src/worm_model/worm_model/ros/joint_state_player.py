"""Play recorded joint states on ``/joint_states`` as ros2_control's joint_state_broadcaster publishes them.

A stand-in robot for the system tests and benchmarks (the nodes do not use it): a node named
``joint_state_broadcaster`` publishes sensor_msgs/JointState on ``/joint_states`` (reliable, volatile,
depth 10: the broadcaster's defaults), one message per row of the file, paced by the monotonic clock at
``--period``, each stamped ``base + k * period`` on the system clock. The joints go out in the file's
order, every message carrying every joint (position, velocity, effort), as the broadcaster does.

    python -m worm_model.ros.joint_state_player FILE.npz [--period 0.001] [--wait 2.0] [--tail 0.0]

FILE.npz holds ``names`` (joints,), ``position``, ``velocity`` and ``effort`` (rows, joints) in the units
the robot publishes, and optionally ``base_ns``, the first stamp [ns] (default: now, whole milliseconds).
It prints ``publishing <rows> messages`` on stderr once a subscriber has matched and ``--wait`` has passed,
and ``done`` on stdout after the last message; it exits 0 after ``--tail`` more seconds (so a subscriber
can still report, e.g. on /diagnostics).
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m worm_model.ros.joint_state_player",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("file", help="the .npz of joint states (module docstring)")
    parser.add_argument("--period", type=float, default=1e-3, help="seconds between messages (default 0.001)")
    parser.add_argument("--wait", type=float, default=2.0,
                        help="seconds to wait after the first subscriber matched, for its side of the match "
                             "(default 2.0)")
    parser.add_argument("--tail", type=float, default=0.0, help="seconds to stay up after the last message")
    args = parser.parse_args(argv)

    import rclpy
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.time import Time
    from sensor_msgs.msg import JointState

    data = np.load(args.file)
    names = [str(n) for n in data["names"]]
    position, velocity, effort = (np.asarray(data[k], float).tolist() for k in ("position", "velocity", "effort"))
    period_ns = int(round(args.period * 1e9))
    rclpy.init()
    node = rclpy.create_node("joint_state_broadcaster")
    try:
        pub = node.create_publisher(JointState, "/joint_states", QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.VOLATILE))
        while not pub.get_subscription_count():
            time.sleep(0.05)
        time.sleep(args.wait)
        base = int(data["base_ns"]) if "base_ns" in data else time.time_ns() // 1_000_000 * 1_000_000
        print(f"publishing {len(position)} messages", file=sys.stderr, flush=True)
        start = time.monotonic()
        for k, row in enumerate(zip(position, velocity, effort)):
            msg = JointState(name=names, position=row[0], velocity=row[1], effort=row[2])
            msg.header.stamp = Time(nanoseconds=base + k * period_ns).to_msg()
            pub.publish(msg)
            delay = start + (k + 1) * args.period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        print("done", flush=True)
        time.sleep(args.tail)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
