"""model_node: the gearbox's internal forces for every rig sample (paper Eqs 21-23).

Subscribes /rig/samples (worm_msgs/RigSamples, batches of consecutive samples)
and runs the model on every sample; publishes /gearbox/forces
(worm_msgs/GearboxForces) for the newest sample of each batch (the rig's batch
rate, 200 Hz by default), sensor-data QoS both. The per-sample work is
live_model.LiveModel (the same class the offline replay runs): the input
torque at the worm is the drive motor's torque less its declared drags
(Eq. 29); the gear shaft carries the measured load torque plus the load
motors' declared drag; the worm acceleration comes from the filtered
tachogenerator speed. This node only wires it to parameters and topics and
counts the flags for /diagnostics.
"""
from __future__ import annotations

from rclpy.node import Node
from rclpy.time import Time
from worm_msgs.msg import GearboxForces, RigSamples

from worm_model.live.live_model import ForceFlags, LiveModel
from worm_model.rig_data.samples import batch_problem
from worm_model.ros.diagnostics import OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare
from worm_model.ros.qos import STREAM
from worm_model.physics.parameters import load_rig

_INVALID_INPUT, _MU_OUT_OF_BOUND = int(ForceFlags.INVALID_INPUT), int(ForceFlags.MU_OUT_OF_BOUND)


class ModelNode(Node):
    def __init__(self) -> None:
        super().__init__("model_node")
        rig_file = declare(self, "rig_file", "", "Rig parameter YAML (worm_model format); empty = bundled NMRV030 rig.")
        use_acceleration = declare(self, "use_acceleration", True,
                                   "Use the worm acceleration (Eqs 19-20); false = quasi-static (a_w = 0).")
        tau = declare(self, "acceleration_filter", 0.01,
                      "Time constant [s] of the low-pass on speed and acceleration.", low=0.0, high=1.0)
        self.rig = load_rig(rig_file or None)
        self.model = LiveModel(self.rig, use_acceleration, tau)
        self.pub = self.create_publisher(GearboxForces, "/gearbox/forces", STREAM)
        self.create_subscription(RigSamples, "/rig/samples", self.on_samples, STREAM)
        self.received = 0
        self.malformed = 0  # /rig/samples messages refused
        self.invalid = 0
        self.mu_out_of_bound = 0
        Diagnostics(self, self.report)

    def on_samples(self, batch: RigSamples) -> None:
        problem = batch_problem(batch, ("omega_worm", "current_drive", "tau_load"))
        if problem:
            self.malformed += 1
            self.get_logger().warning(f"ignored a /rig/samples message (first_seq {batch.first_seq}): {problem}",
                                      throttle_duration_sec=1.0)
            return
        n = len(batch.omega_worm)
        if not n:
            return
        self.received += n
        for f in self.model.update_batch(batch.omega_worm, batch.current_drive, batch.tau_load):
            if f.flags & _INVALID_INPUT:
                self.invalid += 1
            if f.flags & _MU_OUT_OF_BOUND:
                self.mu_out_of_bound += 1
        msg = GearboxForces(
            seq=batch.first_seq + n - 1, normal_force=f.normal_force, friction_force=f.friction_force,
            mu=f.mu, mu_max=f.mu_max, switching_torque=f.switching_torque, tau_load=f.tau_load, tau_in=f.tau_in,
            mode=f.mode, flank=f.flank, flags=f.flags)
        stamp = Time.from_msg(batch.header.stamp).nanoseconds + int(round((n - 1) * batch.sample_period * 1e9))
        msg.header.stamp = Time(nanoseconds=stamp).to_msg()
        msg.header.frame_id = batch.header.frame_id
        self.pub.publish(msg)

    def report(self) -> tuple[bytes, str, dict]:
        level = WARN if self.invalid else OK
        return level, ("invalid inputs seen" if self.invalid else "running"), {
            "samples": self.received, "invalid_inputs": self.invalid, "mu_out_of_bound": self.mu_out_of_bound}


def main(args=None) -> int:
    return run_node(ModelNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
