"""estimator_node: the load torque tau_d for every rig sample, without a torque sensor.

Subscribes /rig/samples (worm_msgs/RigSamples, batches of consecutive samples)
and runs the estimator on every sample; publishes /torque_estimate
(worm_msgs/TorqueEstimate) for the newest sample of each batch (the rig's batch
rate, 200 Hz by default), sensor-data QoS: what the controller feeds forward and
other stacks read. The per-sample work is live_estimator.LiveEstimator, a disturbance observer: speed and
current pass through the same low-pass (input_filter), the current that
accelerates the inertia is removed (quasi_static.py), the result is smoothed
(estimate_filter) except while a change is detected (change_threshold), then
the configured estimator (k-NN over the calibration database, paper Eqs
33-34) maps (omega, i) to tau_d with an uncertainty and flags. A sample taken
while the worm accelerates faster than transient_acceleration is flagged
TRANSIENT.

For other stacks the same estimate goes out in standard types, at the batch rate,
while someone subscribes: sensor_msgs/JointState on ``joint_state_topic`` (one
joint, ``joint_name``, its effort the torque the load applies to the gear shaft
in the joint's positive direction: -tau_d, the ROS convention external-torque
observers follow) and geometry_msgs/WrenchStamped on ``wrench_topic`` (torque
about +z of ``wrench_frame``, the output shaft's axis pointing so that positive
rotation is about +z: torque.z = -tau_d; force and the other torques 0).

A calibration, model or rig file that is named but cannot be used (missing,
damaged, implausible for the rig) stops the node at start: one line, exit code 2.
With none named and a method that needs a calibration (knn), the node reports it
(log + /diagnostics ERROR) and keeps running without publishing estimates, so the
rest of the graph (the controller falls back to no feedforward) carries on.
"""
from __future__ import annotations

from rclpy.node import Node
from geometry_msgs.msg import WrenchStamped
from rclpy.time import Time
from sensor_msgs.msg import JointState
from worm_msgs.msg import RigSamples, TorqueEstimate

from worm_model.rig_data.samples import batch_problem
from worm_model.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare
from worm_model.ros.qos import STREAM
from worm_model.physics.parameters import ParameterError, load_rig

from torque_estimator.estimation.database import CalibrationError, load_database
from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.registry import (CALIBRATION_OPTIONAL, ESTIMATORS, live_rig_file, make_estimator,
                                                  node_options)
from torque_estimator.estimation.live import LiveEstimator


class EstimatorNode(Node):
    def __init__(self) -> None:
        super().__init__("estimator_node")
        rig_file = declare(self, "rig_file", "", "Rig parameter YAML (worm_model format); empty = bundled NMRV030 rig.")
        self.inertia_compensation = declare(
            self, "inertia_compensation", True,
            "Remove the current that accelerates the rig's inertia (Eq. 28) before the quasi-static lookup.")
        self.calibration_file = declare(self, "calibration_file", "",
                                        "Calibration database (JSON written by `calibrate`); the observer can do "
                                        "without one (its ranges then come from the rig file); with one it also "
                                        "adds the model's error measured at its points.")
        self.method = declare(self, "method", "knn", "Estimator.", choices=tuple(ESTIMATORS))
        k = declare(self, "k", 4, "Neighbours averaged by the k-NN estimator.", low=1, high=64)
        weighting = declare(self, "weighting", "inverse_distance", "k-NN weighting of the neighbours.",
                            choices=("inverse_distance", "uniform"))
        model_file = declare(self, "model_file", "",
                             "Extended model parameter file (rig + effects, written by `identify` or `residuals`): "
                             "inverted by the extended_model estimator, its identified parameters are the "
                             "observer's model, and its identification: ranges replace a calibration's; empty = "
                             "rig_file (or the bundled rig) with no effects, the paper's model.")
        tau = declare(self, "input_filter", 0.003,
                      "Time constant [s] of each of the 3 low-pass stages speed and current pass alike.",
                      low=0.0, high=5.0)
        estimate_filter = declare(self, "estimate_filter", 0.05,
                                  "Time constant [s] of the smoothing of the compensated current (0: none).",
                                  low=0.0, high=5.0)
        change_threshold = declare(
            self, "change_threshold", 4.0,
            "Departure of the compensated current from its smoothed value, in running noise sigma, taken for a "
            "change and followed at once (0: never).", low=0.0, high=100.0)
        self.transient_acceleration = declare(
            self, "transient_acceleration", 200.0,
            "Worm acceleration [rad/s^2] above which an estimate is flagged TRANSIENT.", low=0.0, high=1e6)
        period = 1.0 / declare(self, "sample_rate", 1000.0, "Rig sample rate [Hz].", low=1.0, high=100000.0)
        joint_topic = declare(self, "joint_state_topic", "/torque_estimate/joint_states",
                              "Topic of the estimate as sensor_msgs/JointState (effort = -tau_d).")
        self.joint_name = declare(self, "joint_name", "gear", "Name of the output joint in that JointState.")
        wrench_topic = declare(self, "wrench_topic", "/torque_estimate/wrench",
                               "Topic of the estimate as geometry_msgs/WrenchStamped (torque.z = -tau_d).")
        self.wrench_frame = declare(self, "wrench_frame", "gear_output",
                                    "frame_id of that wrench: its z axis is the output shaft, positive rotation "
                                    "about +z.")

        try:  # a bad model_file is reported below, where the estimator is built from it
            self.rig = load_rig(live_rig_file(self.method, rig_file, model_file) or None)
        except ParameterError:
            self.rig = load_rig(rig_file or None)
        self.estimator: LiveEstimator | None = None
        self.problem = ""
        try:
            database = (None if not self.calibration_file and self.method in CALIBRATION_OPTIONAL
                        else load_database(self.calibration_file, self.rig))
            options = node_options(self.method, {"k": k, "weighting": weighting, "model_file": model_file,
                                                 "rig_file": rig_file})
            self.estimator = LiveEstimator(self.rig, make_estimator(self.method, database, **options),
                                           period, input_filter=tau,
                                           inertia_compensation=self.inertia_compensation,
                                           transient_acceleration=self.transient_acceleration,
                                           estimate_filter=estimate_filter, change_threshold=change_threshold)
            self.get_logger().info(f"{self.method} estimator on {len(database)} calibration points from "
                                   f"{self.calibration_file}" if database is not None else
                                   f"{self.method} estimator without a calibration (ranges from the rig file)")
        except (CalibrationError, ParameterError) as err:
            if self.calibration_file or model_file or rig_file:  # a file the user named cannot be used: stop (exit 2)
                raise
            self.problem = str(err)
            self.get_logger().error(f"no estimates: {err}")

        self.pub = self.create_publisher(TorqueEstimate, "/torque_estimate", STREAM)
        self.pub_joint = self.create_publisher(JointState, joint_topic, STREAM)
        self.pub_wrench = self.create_publisher(WrenchStamped, wrench_topic, STREAM)
        self.create_subscription(RigSamples, "/rig/samples", self.on_samples, STREAM)
        self.received = 0
        self.malformed = 0  # /rig/samples messages refused
        self.flag_counts = {flag.name: 0 for flag in EstimateFlags if flag}
        Diagnostics(self, self.report)

    def on_samples(self, batch: RigSamples) -> None:
        problem = batch_problem(batch, ("omega_worm", "current_drive", "voltage_drive", "theta_worm"))
        if problem:
            self.malformed += 1
            self.get_logger().warning(f"ignored a /rig/samples message (first_seq {batch.first_seq}): {problem}",
                                      throttle_duration_sec=1.0)
            return
        n = len(batch.omega_worm)
        self.received += n
        if self.estimator is None or not n:
            return
        omega, current, voltage, theta = batch.omega_worm, batch.current_drive, batch.voltage_drive, batch.theta_worm
        restarts = self.estimator.restarts
        for k in range(n):
            est = self.estimator.update(omega[k], current[k], voltage[k], theta[k], batch.first_seq + k)
            if est.flags:
                for flag in EstimateFlags(est.flags):
                    self.flag_counts[flag.name] += 1
        if self.estimator.restarts != restarts:
            self.get_logger().info(f"rig sample stream started again at seq {batch.first_seq} (a restarted rig "
                                   "or driver): estimator state reset")
        last = n - 1
        msg = TorqueEstimate(seq=batch.first_seq + last, torque=est.torque, uncertainty=est.uncertainty,
                             method=self.method, omega_worm=est.omega_worm, current_drive=est.current_drive,
                             flags=est.flags)
        stamp = Time.from_msg(batch.header.stamp).nanoseconds + int(round(last * batch.sample_period * 1e9))
        msg.header.stamp = Time(nanoseconds=stamp).to_msg()
        msg.header.frame_id = batch.header.frame_id
        self.pub.publish(msg)
        # standard types for other stacks, only while someone listens (each costs a publish)
        if self.pub_joint.get_subscription_count():
            joint = JointState(name=[self.joint_name], effort=[-est.torque])
            joint.header.stamp = msg.header.stamp
            joint.header.frame_id = msg.header.frame_id
            self.pub_joint.publish(joint)
        if self.pub_wrench.get_subscription_count():
            wrench = WrenchStamped()
            wrench.header.stamp, wrench.header.frame_id = msg.header.stamp, self.wrench_frame
            wrench.wrench.torque.z = -est.torque
            self.pub_wrench.publish(wrench)

    def report(self) -> tuple[bytes, str, dict]:
        if self.estimator is None:
            return ERROR, f"no calibration: {self.problem}", {"samples": self.received}
        level = WARN if self.flag_counts["INVALID_INPUT"] else OK
        e = self.estimator
        return level, "estimating", {"samples": self.received, "malformed_batches": self.malformed,
                                     "seq_gaps": e.gaps, "samples_lost": e.lost, "stream_restarts": e.restarts,
                                     **self.flag_counts}


def main(args=None) -> int:
    return run_node(EstimatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
