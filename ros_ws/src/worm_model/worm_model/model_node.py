"""model_node: the gearbox's internal forces for every rig sample (paper Eqs 21-23).

Subscribes /rig/sample (worm_msgs/RigSample), publishes /gearbox/forces
(worm_msgs/GearboxForces), sensor-data QoS both. The input torque at the worm
is the drive motor's torque less its declared drags (Eq. 29); the gear shaft
carries the measured load torque plus the load motors' declared drag; the
worm acceleration comes from the filtered tachogenerator speed. Everything
numeric is in worm_model's plain core; this node only wires it to topics.
"""
from __future__ import annotations

import math

import numpy as np
from rclpy.node import Node
from worm_msgs.msg import GearboxForces, RigSample

from .filters import FilteredDerivative
from .gear_side import gear_side_load, no_load_switching_torque
from .internal_forces import internal_forces
from .modes import classify_mode, motion_sign
from .motor import shaft_torque
from .nodes.diagnostics import OK, WARN, Diagnostics
from .nodes.lifecycle import run_node
from .nodes.parameters import declare
from .nodes.qos import STREAM
from .parameters import load_rig


class ModelNode(Node):
    def __init__(self) -> None:
        super().__init__("model_node")
        rig_file = declare(self, "rig_file", "", "Rig parameter YAML (worm_model format); empty = bundled NMRV030 rig.")
        self.use_acceleration = declare(self, "use_acceleration", True,
                                        "Use the worm acceleration (Eqs 19-20); false = quasi-static (a_w = 0).")
        tau = declare(self, "acceleration_filter", 0.01,
                      "Time constant [s] of the low-pass on speed and acceleration.", low=0.0, high=1.0)
        self.rig = load_rig(rig_file or None)
        self.derivative = FilteredDerivative(tau, 1.0 / self.rig.sensors.sample_rate_hz)
        self.pub = self.create_publisher(GearboxForces, "/gearbox/forces", STREAM)
        self.create_subscription(RigSample, "/rig/sample", self.on_sample, STREAM)
        self.received = 0
        self.invalid = 0
        self.mu_out_of_bound = 0
        Diagnostics(self, self.report)

    def on_sample(self, sample: RigSample) -> None:
        self.received += 1
        rig = self.rig
        omega = sample.omega_worm
        _omega_f, alpha = self.derivative.update(omega)
        alpha = alpha if self.use_acceleration else 0.0
        tau_in = float(shaft_torque(rig.drive_motor, sample.current_drive, omega))
        gear_load = float(gear_side_load(rig, sample.tau_load, omega))
        tau_sw = float(no_load_switching_torque(rig, omega))
        # tau_in is taken before the rotor's inertia, so the shafts' total inertias apply.
        f = internal_forces(rig.gearbox, tau_in, gear_load, omega, alpha,
                            worm_inertia=rig.total_worm_inertia, gear_inertia=rig.total_gear_inertia)
        mode = classify_mode(motion_sign(omega) * sample.tau_load, tau_sw)

        msg = GearboxForces(header=sample.header, seq=sample.seq,
                            normal_force=float(f.normal_force), friction_force=float(f.friction_force),
                            mu=float(f.mu), mu_max=rig.gearbox.mu_engagement_max, switching_torque=tau_sw,
                            tau_load=sample.tau_load, tau_in=tau_in, mode=int(mode), flank=int(f.flank))
        flags = 0
        if not all(math.isfinite(v) for v in (omega, sample.current_drive, sample.tau_load)):
            flags |= GearboxForces.FLAG_INVALID_INPUT
            self.invalid += 1
        elif not bool(np.all(f.valid)):
            flags |= GearboxForces.FLAG_STANDSTILL
        if not bool(np.all(f.mu_valid)) and not flags:
            flags |= GearboxForces.FLAG_MU_OUT_OF_BOUND
            self.mu_out_of_bound += 1
        msg.flags = flags
        self.pub.publish(msg)

    def report(self) -> tuple[bytes, str, dict]:
        level = WARN if self.invalid else OK
        return level, ("invalid inputs seen" if self.invalid else "running"), {
            "samples": self.received, "invalid_inputs": self.invalid, "mu_out_of_bound": self.mu_out_of_bound}


def main(args=None) -> int:
    return run_node(ModelNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
