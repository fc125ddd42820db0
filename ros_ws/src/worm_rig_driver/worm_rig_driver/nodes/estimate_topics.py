"""The topics of a node's load estimates: worm_msgs/TorqueEstimate and the standard outputs.

Every publisher of an estimate publishes it the same way (estimator_node, and a rig node that
publishes the estimate it feeds forward: sim_node, driver_node). Names are relative (a drive's
graph in a namespace takes its estimate with it). One joint (a rig's gear shaft):

  torque_estimate               worm_msgs/TorqueEstimate   every estimate published, with its flags
  torque_estimate/joint_states  sensor_msgs/JointState     the joint's effort (only while subscribed)
  torque_estimate/wrench        geometry_msgs/WrenchStamped  torque.z (only while subscribed)

Several joints of a robot (estimator_node on a JointState): per joint ``j``
``torque_estimate/<j>`` (TorqueEstimate, header.frame_id the joint's name) and
``torque_estimate/<j>/wrench`` (WrenchStamped, frame_id the joint's name: its z axis the joint's
axis), and one ``torque_estimate/joint_states`` carrying every joint's effort.

Effort and torque.z are the torque the load applies in the joint's positive direction, -tau_d, for
trusted estimates only: NaN otherwise (worm_rig_driver.robot.standard_outputs says which and why;
every sample's estimate is judged, published or not: :meth:`EstimateTopics.observe`).
TorqueEstimate carries every estimate as it is, flags included. Sensor-data QoS.
Publishers may be used from the rig's sample thread (rclpy allows it).
"""
from __future__ import annotations

import re
from collections.abc import Sequence

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState
from worm_msgs.msg import TorqueEstimate

from worm_model.rig_data.estimate import Estimate
from worm_model.ros.qos import STREAM

from worm_rig_driver.robot.standard_outputs import StandardEffort

#: what a ROS name token is (a joint name becomes one in the per-joint topics)
_TOKEN = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def joint_topic_problem(name: str) -> str:
    """Why joint ``name`` cannot name its topics ('' if it can): a ROS name token, letters, digits, '_'."""
    return "" if _TOKEN.match(name) else (f"joint name {name!r} cannot be part of a topic name (letters, digits "
                                           "and '_', starting with a letter)")


class EstimateTopics:
    """The publishers of one node's estimates (module docstring).

    Args:
        node: the node that owns them.
        method: the estimator's name (TorqueEstimate.method).
        joints: the joints' names (one for a rig's gear shaft).
        max_loads: per joint, the |tau_d| [N m] beyond which an estimate is implausible (StandardEffort).
        sample_period: [s] between the samples observed.
        per_joint: per-joint TorqueEstimate and wrench topics (several joints of a robot); False: the
            single joint's topics without its name.
        wrench_frame: frame_id of the single joint's wrench (per joint: the joint's name).
    """

    def __init__(self, node: Node, method: str, joints: Sequence[str], max_loads: Sequence[float], *,
                 sample_period: float = 1e-3, per_joint: bool = False, wrench_frame: str = "gear_output") -> None:
        if len(joints) != len(max_loads) or not joints or (len(joints) > 1 and not per_joint):
            raise ValueError(f"joints {list(joints)} and max_loads {list(max_loads)}: one each, several only per joint")
        if per_joint:
            for name in joints:
                if problem := joint_topic_problem(name):
                    raise ValueError(problem)
        self.method = method
        self.per_joint = per_joint
        self.joints = list(joints)
        self.efforts = [StandardEffort(m, sample_period) for m in max_loads]
        self.frames = list(joints) if per_joint else [wrench_frame]
        self.pub_estimates = [node.create_publisher(TorqueEstimate, f"torque_estimate/{j}" if per_joint
                                                    else "torque_estimate", STREAM) for j in joints]
        self.pub_wrenches = [node.create_publisher(WrenchStamped, f"torque_estimate/{j}/wrench" if per_joint
                                                   else "torque_estimate/wrench", STREAM) for j in joints]
        self.pub_joints = node.create_publisher(JointState, "torque_estimate/joint_states", STREAM)

    def observe(self, joint: int, flags: int, torque: float | None = None) -> None:
        """Every sample's estimate of joint index ``joint`` (its flags, and tau_d [N m] where computed; None:
        not), published or not: what the standard outputs trust (StandardEffort.observe)."""
        self.efforts[joint].observe(flags, torque)

    def restart(self, joint: int) -> None:
        """Joint index ``joint``'s estimator started again (a new rig session): StandardEffort.restart."""
        self.efforts[joint].restart()

    def publish(self, stamp_ns: int, frame_id: str, estimates: Sequence[tuple[int, Estimate] | None]) -> None:
        """Publish one estimate per joint (``(seq, estimate)``, None for a joint without one now: NaN in the
        joint states) stamped ``stamp_ns`` (the sample's), each observed already (:meth:`observe`); frame_id
        of the single joint's TorqueEstimate (per joint: its name)."""
        stamp = Time(nanoseconds=stamp_ns).to_msg()
        efforts = []
        listening = self.pub_joints.get_subscription_count() > 0
        for k, entry in enumerate(estimates):
            if entry is None:
                efforts.append(float("nan"))
                continue
            seq, est = entry
            msg = TorqueEstimate(seq=seq, torque=est.torque, uncertainty=est.uncertainty, method=self.method,
                                 omega_worm=est.omega_worm, current_drive=est.current_drive, flags=est.flags)
            msg.header.stamp = stamp
            msg.header.frame_id = self.joints[k] if self.per_joint else frame_id
            self.pub_estimates[k].publish(msg)
            wrench_listening = self.pub_wrenches[k].get_subscription_count() > 0
            if not (listening or wrench_listening):
                efforts.append(float("nan"))
                continue
            effort = self.efforts[k].effort(est.torque)
            efforts.append(effort)
            if wrench_listening:
                wrench = WrenchStamped()
                wrench.header.stamp, wrench.header.frame_id = stamp, self.frames[k]
                wrench.wrench.torque.z = effort
                self.pub_wrenches[k].publish(wrench)
        if listening:
            joint = JointState(name=self.joints, effort=efforts)
            joint.header.stamp = stamp
            joint.header.frame_id = frame_id
            self.pub_joints.publish(joint)

    def report(self) -> dict[str, int]:
        """For /diagnostics: estimates the standard outputs carried as a load and withheld (NaN), summed."""
        return {"standard_outputs_carried": sum(e.carried for e in self.efforts),
                "standard_outputs_withheld": sum(e.withheld for e in self.efforts)}


__all__ = ["Estimate", "EstimateTopics", "joint_topic_problem"]
