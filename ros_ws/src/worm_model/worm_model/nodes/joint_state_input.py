"""A node's JointState input, its parameters declared once: model_node and estimator_node read a robot's
sensor_msgs/JointState (as ros2_control's joint_state_broadcaster publishes it) the same way.

``joint_state_topic`` (relative: in the node's namespace), ``joint_names`` (found by name in every message, any
order), ``joint_side`` (the shaft of its position and velocity) and ``effort_is`` (what its effort is); the
conversion itself is worm_model.rig_data.joint_states'.
"""
from __future__ import annotations

from typing import NamedTuple

from rclpy.node import Node

from worm_model.rig_data.joint_states import JOINT_STATE_OPTIONS
from worm_model.ros.parameters import declare_option


class JointStateInput(NamedTuple):
    """The declared values: topic, the joints' names, their shaft (``output`` or ``motor``), the effort's kind."""

    topic: str
    names: list[str]
    side: str
    effort_is: str


def declare_joint_state_input(node: Node) -> JointStateInput:
    """Declare the JointState input's parameters (rig_data.joint_states.JOINT_STATE_OPTIONS) on ``node`` and return
    their values."""
    topic, names, side, effort_is = (declare_option(node, row) for row in JOINT_STATE_OPTIONS)
    return JointStateInput(topic, list(names), side, effort_is)


__all__ = ["JointStateInput", "declare_joint_state_input"]
