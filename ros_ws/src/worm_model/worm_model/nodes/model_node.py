"""model_node: the gearbox's internal forces for every sample (paper Eqs 21-23), of a rig or a robot's joints.

Input (``input``), every topic relative to the node's namespace:

* ``rig_samples`` (default): rig/samples (worm_msgs/RigSamples, batches of consecutive samples);
  publishes gearbox/forces (worm_msgs/GearboxForces) for the newest sample every
  ``publish_period`` (50 Hz by default). The gear shaft's load is the rig's measured tau_load.
* ``joint_state``: a robot's sensor_msgs/JointState on ``joint_state_topic``, the joints of
  ``joint_names`` (worm_model.rig_data.joint_states: found by name in every message,
  ``joint_side`` and ``effort_is`` converted by each joint's rig file of ``rig_files``, stamps
  checked, refusals counted); publishes gearbox/forces/<joint> per joint. A robot measures no
  load: the gear shaft's load is the newest estimate of estimator_node for that joint
  (torque_estimate/<joint>, worm_msgs/TorqueEstimate: tau_d), NaN (forces flagged INVALID_INPUT)
  until one arrives; forces so computed are the model's view of the estimated load.

Sensor-data QoS. The samples are queued as they come and processed on the ``publish_period``
timer, all at once: the forces are for watching (plots, recordings, other stacks), not for the
rig's control path, which in a composed graph shares this process's executor and must not wait
behind them. The per-sample work is live_model.LiveModel (the same class the offline replay runs):
the input torque at the worm is the drive motor's torque less its declared drags (Eq. 29); the gear
shaft carries the load plus the load motors' declared drag; the worm acceleration comes from the
filtered tachogenerator speed. This node only wires it to parameters and topics and counts the flags
for /diagnostics.
"""
from __future__ import annotations

import math

from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState
from worm_msgs.msg import GearboxForces, RigSamples, TorqueEstimate

from worm_model.live.live_model import ForceFlags, LiveForces, LiveModel
from worm_model.live.model_node_options import MODEL_NODE_JOINT_STATE_OPTIONS, MODEL_NODE_OPTIONS
from worm_model.rig_data.joint_states import JointConversion, JointStateReader
from worm_model.rig_data.samples import batch_problem
from worm_model.ros.diagnostics import OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.nodes.joint_state_input import declare_joint_state_input
from worm_model.ros.parameters import declare_option
from worm_model.ros.qos import STREAM
from worm_model.physics.parameters import load_rig

_INVALID_INPUT, _MU_OUT_OF_BOUND = int(ForceFlags.INVALID_INPUT), int(ForceFlags.MU_OUT_OF_BOUND)


class _Joint:
    """One joint's model, queue and counts (input joint_state)."""

    def __init__(self, name: str, model: LiveModel, pub) -> None:
        self.name = name
        self.model = model
        self.pub = pub
        self.queue: list[tuple[int, int, float, float, float]] = []  # (seq, stamp_ns, omega, current, tau_load)
        self.load = math.nan  # [N m] the newest estimate of the gear shaft's load
        self.invalid = 0
        self.mu_out_of_bound = 0


class ModelNode(Node):
    def __init__(self) -> None:
        super().__init__("model_node")
        self.input, rig_file, use_acceleration, tau, period = (declare_option(self, row)
                                                                for row in MODEL_NODE_OPTIONS)
        self.received = 0
        self.malformed = 0  # rig/samples messages refused
        self.invalid = 0
        self.mu_out_of_bound = 0
        if self.input == "joint_state":
            self._start_joint_state(rig_file, use_acceleration, tau)
        else:
            self.rig = load_rig(rig_file or None)
            self.model = LiveModel(self.rig, use_acceleration, tau)
            self.pub = self.create_publisher(GearboxForces, "gearbox/forces", STREAM)
            self.create_subscription(RigSamples, "rig/samples", self.on_samples, STREAM)
            self.queue: list[RigSamples] = []
        self.create_timer(period, self.process)
        Diagnostics(self, self.report)

    def _start_joint_state(self, rig_file: str, use_acceleration: bool, tau: float) -> None:
        topic, names, side, effort_is = declare_joint_state_input(self)
        rig_files, rate = (declare_option(self, row) for row in MODEL_NODE_JOINT_STATE_OPTIONS)
        if not names or (rig_files and len(rig_files) != len(names)):
            raise ValueError(f"parameters joint_names {list(names)} and rig_files {list(rig_files)}: name the joints, "
                             "and one rig file per joint or none")
        files = list(rig_files) or [rig_file] * len(names)
        rigs = [load_rig(f or None) for f in files]
        self.reader = JointStateReader([JointConversion.from_rig(n, r, side, effort_is) for n, r in zip(names, rigs)],
                                       1.0 / rate)
        self.joints = [_Joint(n, LiveModel(r, use_acceleration, tau, 1.0 / rate),
                              self.create_publisher(GearboxForces, f"gearbox/forces/{n}", STREAM))
                       for n, r in zip(names, rigs)]
        for joint in self.joints:
            self.create_subscription(TorqueEstimate, f"torque_estimate/{joint.name}",
                                     lambda msg, j=joint: setattr(j, "load", msg.torque), STREAM)
        self.create_subscription(JointState, topic, self.on_joint_state, STREAM)

    # --- input -------------------------------------------------------------------------------------
    def on_samples(self, batch: RigSamples) -> None:
        problem = batch_problem(batch, ("omega_worm", "current_drive", "tau_load"))
        if problem:
            self.malformed += 1
            self.get_logger().warning(f"ignored a rig/samples message (first_seq {batch.first_seq}): {problem}",
                                      throttle_duration_sec=1.0)
            return
        if len(batch.omega_worm):
            self.queue.append(batch)

    def on_joint_state(self, msg: JointState) -> None:
        stamp = Time.from_msg(msg.header.stamp).nanoseconds
        for joint, sample in zip(self.joints, self.reader.read(stamp, msg.name, msg.position, msg.velocity,
                                                               msg.effort)):
            if sample is not None:
                joint.queue.append((sample.seq, stamp, sample.omega_worm, sample.current_drive, joint.load))

    # --- processing --------------------------------------------------------------------------------
    def process(self) -> None:
        """Run the model over every queued sample; publish the forces of the newest."""
        if self.input == "joint_state":
            for joint in self.joints:
                self._process_joint(joint)
            return
        if not self.queue:
            return
        batches, self.queue = self.queue, []
        columns = [[v for b in batches for v in getattr(b, name)] for name in ("omega_worm", "current_drive",
                                                                              "tau_load")]
        self.received += len(columns[0])
        f = self._count(self.model.update_batch(*columns), self)
        last = batches[-1]
        n = len(last.omega_worm)
        stamp = Time.from_msg(last.header.stamp).nanoseconds + int(round((n - 1) * last.sample_period * 1e9))
        self._publish(self.pub, f, last.first_seq + n - 1, stamp, last.header.frame_id)

    def _process_joint(self, joint: _Joint) -> None:
        if not joint.queue:
            return
        queue, joint.queue = joint.queue, []
        self.received += len(queue)
        f = self._count(joint.model.update_batch(*([q[k] for q in queue] for k in (2, 3, 4))), joint)
        seq, stamp = queue[-1][0], queue[-1][1]
        self._publish(joint.pub, f, seq, stamp, joint.name)

    @staticmethod
    def _count(forces: list[LiveForces], counts) -> LiveForces:
        for f in forces:
            if f.flags & _INVALID_INPUT:
                counts.invalid += 1
            if f.flags & _MU_OUT_OF_BOUND:
                counts.mu_out_of_bound += 1
        return forces[-1]

    @staticmethod
    def _publish(pub, f: LiveForces, seq: int, stamp_ns: int, frame_id: str) -> None:
        msg = GearboxForces(
            seq=seq, normal_force=f.normal_force, friction_force=f.friction_force,
            mu=f.mu, mu_max=f.mu_max, switching_torque=f.switching_torque, tau_load=f.tau_load, tau_in=f.tau_in,
            mode=f.mode, flank=f.flank, flags=f.flags)
        msg.header.stamp = Time(nanoseconds=stamp_ns).to_msg()
        msg.header.frame_id = frame_id
        pub.publish(msg)

    def report(self) -> tuple[bytes, str, dict]:
        if self.input == "joint_state":
            values = {"samples": self.received, "malformed_messages": self.reader.malformed_messages}
            for joint in self.joints:
                values.update({f"{joint.name}.{k}": v for k, v in self.reader.refused(joint.name).items()})
                values.update({f"{joint.name}.invalid_inputs": joint.invalid,
                               f"{joint.name}.mu_out_of_bound": joint.mu_out_of_bound})
            bad = self.reader.refused_total() or any(j.invalid for j in self.joints)
            return (WARN if bad else OK), ("refused or invalid joint samples seen" if bad else "running"), values
        level = WARN if self.invalid else OK
        return level, ("invalid inputs seen" if self.invalid else "running"), {
            "samples": self.received, "invalid_inputs": self.invalid, "mu_out_of_bound": self.mu_out_of_bound}


def main(args=None) -> int:
    return run_node(ModelNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
