"""model_node's parameters as data (worm_model.cli.node_options rows): model_node declares them, replay
reads their defaults for what a parameter file leaves out. The JointState input's own rows are
worm_model.rig_data.joint_states.JOINT_STATE_OPTIONS. No ROS.
"""
from __future__ import annotations

from worm_model.cli.node_options import RIG_FILE, STRING_ARRAY, Option

#: what model_node reads
MODEL_NODE_INPUTS: tuple[str, ...] = ("rig_samples", "joint_state")

#: every input's
MODEL_NODE_OPTIONS: tuple[Option, ...] = (
    Option("input", "rig_samples", "What the forces are computed from: rig_samples (rig/samples) or joint_state (a "
           "robot's sensor_msgs/JointState).", choices=MODEL_NODE_INPUTS),
    RIG_FILE,
    Option("use_acceleration", True, "Use the worm acceleration (Eqs 19-20); false = quasi-static (a_w = 0)."),
    Option("acceleration_filter", 0.01, "Time constant [s] of the low-pass on speed and acceleration.",
           low=0.0, high=1.0),
    Option("publish_period", 0.02, "Period [s] of the processing of the queued samples and of the forces published "
           "for the newest.", low=0.001, high=10.0),
)

#: the joint_state input's, besides JOINT_STATE_OPTIONS
MODEL_NODE_JOINT_STATE_OPTIONS: tuple[Option, ...] = (
    Option("rig_files", STRING_ARRAY, "Per joint (parallel to joint_names), its rig file ('' for none); empty: "
           "rig_file for every joint."),
    Option("sample_rate", 1000.0, "Rate [Hz] of the JointState publisher.", low=1.0, high=100000.0),
)

__all__ = ["MODEL_NODE_INPUTS", "MODEL_NODE_JOINT_STATE_OPTIONS", "MODEL_NODE_OPTIONS"]
