"""joint_state_merger: several rigs as one robot's sensor_msgs/JointState, one message per sample tick.

Subscribes each joint's rig stream, ``<rig_namespaces[k]>/rig/samples`` (worm_msgs/RigSamples of a
sim_node or driver_node started in that namespace), and publishes ``joint_states`` (relative: in
this node's namespace; /joint_states without one) as ros2_control's joint_state_broadcaster
publishes a robot: every joint of ``joint_names`` in one message per tick of the rigs' sample
period (1 kHz), one header stamp, position, velocity and effort of each joint at that tick
(worm_rig_driver.robot.joint_states: how ticks are formed, when a joint is left out). What a
joint reports is set by ``joint_side`` (output: the gear shaft through the rig file's ratio, as a
transmission reports a robot's joint; motor: the worm) and ``effort_is`` (current [A], or
motor_torque K_t i [N m]): estimator_node reads the same parameters back.

The simulated drives of a graph of several drives (torque_estimator/config/three_drives.yaml)
reach a robot's estimator through this, exactly as a real robot's joints would. /diagnostics:
ticks published, and per joint how many ticks went out without it.
"""
from __future__ import annotations

from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time import Time
from sensor_msgs.msg import JointState
from worm_msgs.msg import RigSamples

from worm_model.physics.parameters import load_rig
from worm_model.rig_data.joint_states import EFFORT_KINDS, JOINT_SIDES, JointConversion
from worm_model.rig_data.samples import batch_problem
from worm_model.ros.diagnostics import OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare
from worm_model.ros.qos import STREAM

from worm_rig_driver.robot.joint_states import JointStateMerger


class JointStateMergerNode(Node):
    def __init__(self) -> None:
        super().__init__("joint_state_merger")
        names = declare(self, "joint_names", Parameter.Type.STRING_ARRAY,
                        "The joints, one per rig, in the order of the published message.") or []
        namespaces = declare(self, "rig_namespaces", Parameter.Type.STRING_ARRAY,
                             "Per joint (parallel to joint_names), the namespace its rig runs in "
                             "(its samples: <namespace>/rig/samples).") or []
        rig_files = declare(self, "rig_files", Parameter.Type.STRING_ARRAY,
                            "Per joint, its rig file (ratio and K_t; '' or none: the bundled rig).") or []
        side = declare(self, "joint_side", "output", "Shaft the positions and velocities are reported on: output "
                       "(the gear shaft) or motor (the worm).", choices=JOINT_SIDES)
        effort_is = declare(self, "effort_is", "current", "What the effort reports: current (the drive current "
                            "[A]) or motor_torque (K_t i [N m]).", choices=EFFORT_KINDS)
        rate = declare(self, "sample_rate", 1000.0, "The rigs' sample rate [Hz]: one message per period.",
                       low=1.0, high=100000.0)
        max_wait = declare(self, "max_wait", 0.05, "Longest wait [s] of a tick for a rig that sent nothing after "
                           "it; then it goes out without that joint.", low=0.0, high=10.0)
        self.frame_id = declare(self, "frame_id", "", "frame_id of the published headers.")
        if not names or len(namespaces) != len(names) or (rig_files and len(rig_files) != len(names)):
            raise ValueError(f"parameters joint_names {list(names)}, rig_namespaces {list(namespaces)}, rig_files "
                             f"{list(rig_files)}: one entry per joint (rig_files may be empty)")
        files = list(rig_files) or [""] * len(names)
        joints = [JointConversion.from_rig(name, load_rig(file or None), side, effort_is)
                  for name, file in zip(names, files)]
        self.merger = JointStateMerger(joints, 1.0 / rate, max_wait)
        self.pub = self.create_publisher(JointState, "joint_states", STREAM)
        self.malformed = 0
        for k, namespace in enumerate(namespaces):
            topic = f"{namespace.rstrip('/')}/rig/samples" if namespace.strip("/") else "rig/samples"
            self.create_subscription(RigSamples, topic, lambda msg, k=k: self.on_samples(k, msg), STREAM)
        Diagnostics(self, self.report)
        self.get_logger().info(f"joints {', '.join(names)} from {', '.join(namespaces)} ({side} side, effort as "
                               f"{effort_is}) -> {self.resolve_topic_name('joint_states')}")

    def on_samples(self, joint: int, batch: RigSamples) -> None:
        if batch_problem(batch, ("omega_worm", "current_drive", "theta_worm")):
            self.malformed += 1
            return
        start = Time.from_msg(batch.header.stamp).nanoseconds
        step = batch.sample_period * 1e9
        self.merger.add(joint, ((start + int(round(k * step)), theta, omega, current) for k, (theta, omega, current)
                                in enumerate(zip(batch.theta_worm, batch.omega_worm, batch.current_drive))))
        for tick in self.merger.ready():
            msg = JointState(name=tick.names, position=tick.position, velocity=tick.velocity, effort=tick.effort)
            msg.header.stamp = Time(nanoseconds=tick.stamp_ns).to_msg()
            msg.header.frame_id = self.frame_id
            self.pub.publish(msg)

    def report(self) -> tuple[bytes, str, dict]:
        absent = dict(zip((j.name for j in self.merger.joints), self.merger.absent))
        level = WARN if any(absent.values()) or self.malformed else OK
        return level, "merging", {"ticks": self.merger.ticks, "malformed_batches": self.malformed,
                                  **{f"{name}.absent_ticks": n for name, n in absent.items()}}


def main(args=None) -> int:
    return run_node(JointStateMergerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
