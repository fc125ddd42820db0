"""model_node: the gearbox's internal forces for every rig sample (paper Eqs 21-23).

Subscribes /rig/samples (worm_msgs/RigSamples, batches of consecutive samples)
and runs the model on every sample; publishes /gearbox/forces
(worm_msgs/GearboxForces) for the newest sample every ``publish_period``
(50 Hz by default), sensor-data QoS both. The batches are queued as they come
and processed on that timer, all at once: the forces are for watching (plots,
recordings, other stacks), not for the rig's control path, which in a composed
graph shares this process's executor and must not wait behind them. The per-sample work is
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
        period = declare(self, "publish_period", 0.02,
                         "Period [s] of the processing of the queued samples and of the forces published for "
                         "the newest.", low=0.001, high=10.0)
        self.rig = load_rig(rig_file or None)
        self.model = LiveModel(self.rig, use_acceleration, tau)
        self.pub = self.create_publisher(GearboxForces, "gearbox/forces", STREAM)
        self.create_subscription(RigSamples, "rig/samples", self.on_samples, STREAM)
        self.queue: list[RigSamples] = []
        self.create_timer(period, self.process)
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
        if len(batch.omega_worm):
            self.queue.append(batch)

    def process(self) -> None:
        """Run the model over every queued sample; publish the forces of the newest."""
        if not self.queue:
            return
        batches, self.queue = self.queue, []
        columns = [[v for b in batches for v in getattr(b, name)] for name in ("omega_worm", "current_drive",
                                                                              "tau_load")]
        self.received += len(columns[0])
        for f in self.model.update_batch(*columns):
            if f.flags & _INVALID_INPUT:
                self.invalid += 1
            if f.flags & _MU_OUT_OF_BOUND:
                self.mu_out_of_bound += 1
        last = batches[-1]
        n = len(last.omega_worm)
        msg = GearboxForces(
            seq=last.first_seq + n - 1, normal_force=f.normal_force, friction_force=f.friction_force,
            mu=f.mu, mu_max=f.mu_max, switching_torque=f.switching_torque, tau_load=f.tau_load, tau_in=f.tau_in,
            mode=f.mode, flank=f.flank, flags=f.flags)
        stamp = Time.from_msg(last.header.stamp).nanoseconds + int(round((n - 1) * last.sample_period * 1e9))
        msg.header.stamp = Time(nanoseconds=stamp).to_msg()
        msg.header.frame_id = last.header.frame_id
        self.pub.publish(msg)

    def report(self) -> tuple[bytes, str, dict]:
        level = WARN if self.invalid else OK
        return level, ("invalid inputs seen" if self.invalid else "running"), {
            "samples": self.received, "invalid_inputs": self.invalid, "mu_out_of_bound": self.mu_out_of_bound}


def main(args=None) -> int:
    return run_node(ModelNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
