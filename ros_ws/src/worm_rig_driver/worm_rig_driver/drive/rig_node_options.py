"""The parameters sim_node and driver_node both declare, as data (worm_model.cli.node_options rows): the rig file,
the feedforward estimator the rig runs beside its speed loop and whether its estimate is the graph's. The nodes
declare them (nodes/rig_topics.py, sim_node, driver_node); replay reads their defaults for what a parameter file
leaves out. No ROS.
"""
from __future__ import annotations

from worm_model.cli.node_options import RIG_FILE, Option

FEEDFORWARD_ESTIMATOR = Option(
    "feedforward_estimator", "",
    "Load-torque estimator run beside the speed loop on every sample, whose feedforward drives the very next "
    "period for speed commands with feedforward_at_rig (the controller_node parameter of that name): a method of "
    "torque_estimator (observer, knn, extended_model). Empty: none; commands bring their own feedforward_torque.")
FEEDFORWARD_CALIBRATION = Option(
    "feedforward_calibration", "",
    "Calibration database of that estimator (the file `calibrate` writes); empty: none (observer and "
    "extended_model work from the rig file alone).")
PUBLISH_ESTIMATE = Option(
    "publish_estimate", True,
    "Publish the feedforward estimator's estimate of each batch's newest sample as the graph's estimate: "
    "torque_estimate (worm_msgs/TorqueEstimate), torque_estimate/joint_states and torque_estimate/wrench, as "
    "estimator_node does (nothing without feedforward_estimator). False: leave those topics to an estimator_node.")

#: what a rig node's estimate depends on (replay runs the rig's feedforward estimator as the graph's live one)
RIG_NODE_OPTIONS: tuple[Option, ...] = (RIG_FILE, FEEDFORWARD_ESTIMATOR, FEEDFORWARD_CALIBRATION, PUBLISH_ESTIMATE)

__all__ = ["FEEDFORWARD_CALIBRATION", "FEEDFORWARD_ESTIMATOR", "PUBLISH_ESTIMATE", "RIG_NODE_OPTIONS"]
