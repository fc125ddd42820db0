"""Decoded messages as YAML, the way ``ros2 topic echo`` prints them (no rclpy).

``ros2 topic echo`` turns a message into an ordered mapping of its fields
(nested messages as nested mappings, arrays as lists) and dumps it with
PyYAML in block style, one message after another, each followed by a
``---`` line. Here the messages are the dataclasses ``rosbags`` decodes
(field order as in the ``.msg``; primitive arrays are numpy arrays), turned
into the same structure.
"""

from __future__ import annotations

import sys
from collections import OrderedDict
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np
import yaml

__all__ = ['message_to_ordered', 'message_to_yaml']


class _Dumper(yaml.SafeDumper):
    """SafeDumper that writes OrderedDicts as plain mappings, in order."""


def _represent_ordered(dumper: yaml.SafeDumper, data: OrderedDict[str, Any]) -> yaml.Node:
    return dumper.represent_mapping('tag:yaml.org,2002:map', data.items())


_Dumper.add_representer(OrderedDict, _represent_ordered)


def _is_constant(annotation: object) -> bool:
    """rosbags declares a message's constants as ``ClassVar`` (as a string annotation)."""
    return str(annotation).startswith(('ClassVar', 'typing.ClassVar'))


def message_to_ordered(message: Any) -> Any:
    """A decoded message as nested OrderedDicts / lists / Python scalars."""
    if is_dataclass(message) and not isinstance(message, type):
        return OrderedDict(
            (f.name, message_to_ordered(getattr(message, f.name)))
            for f in fields(message)
            if not f.name.startswith('_') and not _is_constant(f.type)
        )
    if isinstance(message, np.ndarray):
        return [message_to_ordered(v) for v in message.tolist()]
    if isinstance(message, (list, tuple)):
        return [message_to_ordered(v) for v in message]
    if isinstance(message, np.generic):
        return message.item()
    if isinstance(message, (bytes, bytearray)):
        return list(message)
    return message


def message_to_yaml(message: Any) -> str:
    """YAML text of one message (block style, ends with a newline)."""
    return yaml.dump(message_to_ordered(message), Dumper=_Dumper, allow_unicode=True,
                     width=sys.maxsize, default_flow_style=False, sort_keys=False)
