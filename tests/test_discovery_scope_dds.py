"""docs/security.md's discovery scopes, run: who on this host hears a publisher.

Two processes, a publisher and a subscriber of std_msgs/Float64, with the environment the page
shows: the same ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST hear each other; another
domain does not; ROS_AUTOMATIC_DISCOVERY_RANGE=OFF hears nothing, even with this host as a static peer.
"""
from __future__ import annotations

import os
import random
import subprocess
import sys

import pytest

PROGRAM = """
import sys, time, rclpy
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node("scope_" + sys.argv[1])
if sys.argv[1] == "pub":
    pub = node.create_publisher(Float64, "scope_probe", 10)
    end = time.monotonic() + float(sys.argv[2])
    while time.monotonic() < end:
        pub.publish(Float64(data=1.0))
        rclpy.spin_once(node, timeout_sec=0.05)
else:
    heard = []
    node.create_subscription(Float64, "scope_probe", lambda msg: heard.append(msg), 10)
    end = time.monotonic() + float(sys.argv[2])
    while not heard and time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    print("heard" if heard else "silent")
"""


def heard(publisher: dict[str, str], subscriber: dict[str, str], listen: float) -> bool:
    """Whether a subscriber with ``subscriber``'s environment hears a publisher with ``publisher``'s within
    ``listen`` [s] (the publisher publishes 2 s longer)."""
    base = {k: v for k, v in os.environ.items() if not k.startswith("ROS_")}
    pub = subprocess.Popen([sys.executable, "-c", PROGRAM, "pub", str(listen + 2.0)], env={**base, **publisher},
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        sub = subprocess.run([sys.executable, "-c", PROGRAM, "sub", str(listen)], env={**base, **subscriber},
                             capture_output=True, text=True, timeout=listen + 60)
    finally:
        pub.kill()
        pub.wait()
    assert sub.returncode == 0, sub.stderr
    return sub.stdout.strip() == "heard"


@pytest.fixture(scope="module")
def domain() -> str:
    return str(os.environ.get("ROS_DOMAIN_ID") or random.randint(100, 230))


def test_localhost_on_one_domain_is_heard(domain: str) -> None:
    env = {"ROS_DOMAIN_ID": domain, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    assert heard(env, env, 30.0)


def test_another_domain_and_discovery_off_are_not(domain: str) -> None:
    """Silence is judged over 6 s: on this host two processes of one domain find each other in well under 1 s
    (the test above)."""
    env = {"ROS_DOMAIN_ID": domain, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    other = {**env, "ROS_DOMAIN_ID": str((int(domain) + 1) % 233)}
    assert not heard(env, other, 6.0)
    off = {"ROS_DOMAIN_ID": domain, "ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF", "ROS_STATIC_PEERS": "127.0.0.1"}
    assert not heard(off, off, 6.0)
