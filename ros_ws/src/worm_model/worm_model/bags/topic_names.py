"""Whether a name can be a ROS topic, without rclpy: what the recorder, ``bag import`` and every other writer of a
topic name refuse before anything is written.

The rules are rmw's for a fully qualified topic name (``rmw_validate_full_topic_name``; rclpy's
``validate_full_topic_name`` raises on the same names, tests/test_topic_names.py compares the two): a leading ``/``,
only ASCII letters, digits, ``_`` and ``/``, no ``//``, no trailing ``/``, no token that starts with a digit, at most
MAX_LENGTH characters. A relative name (``rig/sample``) is taken in the root namespace (``/rig/sample``).
"""
from __future__ import annotations

import re
from typing import Final

#: rmw's RMW_TOPIC_MAX_NAME_LENGTH (255 less the 8 characters DDS prefixes)
MAX_LENGTH: Final = 255 - 8
_ALLOWED = re.compile(r"[A-Za-z0-9_/]*")


def topic_name_problem(topic: str) -> str | None:
    """What is wrong with ``topic`` as a ROS topic name (a relative one taken from ``/``), or None."""
    name = topic if topic.startswith("/") else "/" + topic
    if not _ALLOWED.fullmatch(name):
        bad = next(c for c in name if not _ALLOWED.fullmatch(c))
        return f"it holds {bad!r}: only letters, digits, '_' and '/' are allowed"
    if "//" in name:
        return "it holds a repeated '/'"
    if name.endswith("/"):
        return "it ends with a '/'"
    if any(token[:1].isdigit() for token in name.split("/")):
        return "a token starts with a digit"
    if len(name) > MAX_LENGTH:
        return f"it is longer than {MAX_LENGTH} characters"
    return None


__all__ = ["MAX_LENGTH", "topic_name_problem"]
