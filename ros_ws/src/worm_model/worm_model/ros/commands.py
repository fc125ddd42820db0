"""Subscribing to commands and set-points so that every publisher reaches them, and a late joiner
still gets the last latched value.

A subscription's durability decides two things at once. VOLATILE matches every
publisher (``ros2 topic pub`` offers volatile; a transient-local subscription
refuses it as incompatible and never hears it) but is handed no history: a node
that (re)starts after the last set-point was published never learns it, even
from a latched publisher. TRANSIENT_LOCAL gets that history but only from
latched publishers. So a command topic gets both (:func:`subscribe_command`):

* a reliable, volatile subscription: every publisher reaches it;
* a reliable, transient-local one with depth 1: on (re)joining it receives the
  last value a latched publisher holds. Its "incompatible QoS" event for a
  volatile publisher is expected and not logged.

A message from a latched publisher then arrives twice (once per subscription).
The callbacks here take set-points and held values, which are idempotent: the
same value twice is the same command. Publishers of commands use
``qos.COMMAND`` (reliable, transient-local).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from worm_model.ros.qos import COMMAND_IN

try:  # Iron and newer
    from rclpy.event_handler import SubscriptionEventCallbacks
except ImportError:  # Humble
    from rclpy.qos_event import SubscriptionEventCallbacks  # type: ignore[no-redef]

#: the late-joiner subscription: the latest latched value only
LATCHED_IN = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


def subscribe_command(node: Node, msg_type: Any, topic: str, callback: Callable[[Any], None]) -> list:
    """Both subscriptions of a command topic (see module docstring); returns them."""
    quiet = SubscriptionEventCallbacks(incompatible_qos=lambda _event: None)
    return [node.create_subscription(msg_type, topic, callback, COMMAND_IN),
            node.create_subscription(msg_type, topic, callback, LATCHED_IN, event_callbacks=quiet)]


__all__ = ["LATCHED_IN", "subscribe_command"]
