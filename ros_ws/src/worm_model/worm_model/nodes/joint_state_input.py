"""A node's JointState input, its parameters declared once: model_node and estimator_node read a robot's
sensor_msgs/JointState (as ros2_control's joint_state_broadcaster publishes it) the same way.

``joint_state_topic`` (relative: in the node's namespace), ``joint_names`` (found by name in every message, any
order), ``joint_side`` (the shaft of its position and velocity) and ``effort_is`` (what its effort is); the
conversion itself is worm_model.rig_data.joint_states'.
"""
from __future__ import annotations

from typing import NamedTuple

from rclpy.node import Node
from rclpy.parameter import Parameter

from worm_model.rig_data.joint_states import EFFORT_KINDS, JOINT_SIDES
from worm_model.ros.parameters import declare


class JointStateInput(NamedTuple):
    """The declared values: topic, the joints' names, their shaft (``output`` or ``motor``), the effort's kind."""

    topic: str
    names: list[str]
    side: str
    effort_is: str


def declare_joint_state_input(node: Node) -> JointStateInput:
    """Declare the JointState input's parameters on ``node`` and return their values."""
    topic = declare(node, "joint_state_topic", "joint_states",
                    "Topic of the robot's sensor_msgs/JointState (relative: in this node's namespace).")
    names = declare(node, "joint_names", Parameter.Type.STRING_ARRAY,
                    "The joints, by their names in the JointState (any order there).") or []
    side = declare(node, "joint_side", "output", "Shaft of the JointState's position and velocity: output (the "
                   "gear shaft, as a robot's joint) or motor (the worm); the rig file's ratio converts.",
                   choices=JOINT_SIDES)
    effort_is = declare(node, "effort_is", "current", "What the JointState's effort is: current (the drive "
                        "current [A]) or motor_torque (K_t i [N m]; the rig file's K_t converts).",
                        choices=EFFORT_KINDS)
    return JointStateInput(topic, list(names), side, effort_is)


__all__ = ["JointStateInput", "declare_joint_state_input"]
