"""The recorder's plain-Python part (no rclpy): which topics it records, the Python class and the offered QoS
it stores for each, and what it reports lost. ``nodes/recorder_node.py`` is the ROS shell over it (subscriptions,
discovery, the executor, parameters); the bag itself is written by :mod:`worm_model.bags.writer`, into the folder
:mod:`worm_rig_driver.recording.bag_folder` chooses.
"""
from __future__ import annotations

import importlib
from collections.abc import Iterable
from typing import Any, TypeVar

from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)

from worm_model.bags.seq_check import DeliveryCheck, StreamCheck
from worm_model.bags.topic_names import topic_name_problem
from worm_model.errors import BagRecordingError

_QosEnum = TypeVar('_QosEnum', QosHistory, QosReliability, QosDurability, QosLiveliness)


def message_class(type_name: str) -> type:
    """Import the Python class of ``pkg/msg/Name`` (as rosidl_runtime_py does).

    Raises:
        BagRecordingError: The package or class cannot be imported.

    """
    package, kind, name = type_name.split('/')
    try:
        cls: type = getattr(importlib.import_module(f'{package}.{kind}'), name)
    except (ImportError, AttributeError) as err:
        msg = f'Cannot import the Python class of {type_name!r}: {err}'
        raise BagRecordingError(msg) from err
    return cls


def _seconds_nanos(duration_ns: int) -> QosTime:
    """Split a duration (ns) into rosbag2's (sec, nsec)."""
    sec, nsec = divmod(duration_ns, 1_000_000_000)
    return QosTime(sec, nsec)


def bag_qos(profile: Any) -> Qos:
    """Convert an rclpy QoS profile (``rclpy.qos.QoSProfile``, read by attribute) to rosbags' (the rmw enum
    values agree)."""

    def convert(enum: type[_QosEnum], value: int) -> _QosEnum:
        try:
            return enum(value)
        except ValueError:
            return enum.UNKNOWN

    return Qos(
        history=convert(QosHistory, int(profile.history)),
        depth=profile.depth,
        reliability=convert(QosReliability, int(profile.reliability)),
        durability=convert(QosDurability, int(profile.durability)),
        deadline=_seconds_nanos(profile.deadline.nanoseconds),
        lifespan=_seconds_nanos(profile.lifespan.nanoseconds),
        liveliness=convert(QosLiveliness, int(profile.liveliness)),
        liveliness_lease_duration=_seconds_nanos(profile.liveliness_lease_duration.nanoseconds),
        avoid_ros_namespace_conventions=profile.avoid_ros_namespace_conventions,
    )


#: what recording every topic leaves out by default: each rig's per-sample copy of its rig/samples
DEFAULT_EXCLUDE: tuple[str, ...] = ('rig/sample',)


def is_excluded(topic: str, exclude: Iterable[str]) -> bool:
    """Whether the full name ``topic`` is one of ``exclude``: an absolute name is that topic, a relative one
    (``rig/sample``) that topic in any namespace (/rig/sample, /arm/joint2/rig/sample, ...)."""
    return any(topic == name if name.startswith('/') else topic == f'/{name}' or topic.endswith(f'/{name}')
               for name in exclude)


def is_hidden(topic: str) -> bool:
    """Whether a name part of ``topic`` starts with ``_`` (ROS hidden topic)."""
    return any(part.startswith('_') for part in topic.split('/'))


def check_topic_name(topic: str) -> None:
    """Refuse a topic name ROS cannot subscribe to, before anything is created (worm_model.bags.topic_names).

    Raises:
        ValueError: naming the topic and what is wrong with it.
    """
    if (problem := topic_name_problem(topic)) is not None:
        raise ValueError(f'parameter topics/exclude: {topic!r} is not a valid topic name ({problem})')


def loss_report(deliveries: DeliveryCheck, sequences: StreamCheck, dropped_after_close: int = 0
                ) -> tuple[int, list[str]]:
    """Messages a recorder lost (gaps in the DDS numbers of ``deliveries``, and messages that arrived after
    its bag was closed), one line per topic and check (``sequences``: the seq fields), and a verdict."""
    lost = deliveries.lost + dropped_after_close
    lines = deliveries.report()
    lines += [f'{line} (seq field)' for line in sequences.report()]
    if dropped_after_close:
        lines.append(f'{dropped_after_close} messages arrived after the bag was closed')
    publishers = sum(len(p) for p in deliveries.trackers.values())
    if lost:
        lines.append(f'recorder: LOST {lost} messages (gaps in the DDS sequence numbers of '
                     f'{publishers} publisher(s); see the lines above)')
    else:
        lines.append(f'recorder: lost nothing: no gap in the DDS sequence numbers of '
                     f'{publishers} publisher(s) on {len(deliveries.trackers)} topic(s)')
    return lost, lines
