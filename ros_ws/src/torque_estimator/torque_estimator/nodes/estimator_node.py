"""estimator_node: the load torque tau_d for every rig sample, without a torque sensor.

Subscribes /rig/samples (worm_msgs/RigSamples, batches of consecutive samples)
and runs the estimator on every sample; publishes /torque_estimate
(worm_msgs/TorqueEstimate) for the newest sample of each batch (the rig's batch
rate, 200 Hz by default), sensor-data QoS: what the controller feeds forward and
other stacks read.

The estimator is the parameter ``method`` (estimation.registry), built from the
node's parameters by estimation.settings (as replay, ``estimate`` and the rig
feedforward build theirs), and fed every sample by estimation.live.LiveEstimator:

* ``observer`` (the shipped graph's, config/sim_graph.yaml): a Kalman filter on the
  rig's model (Eqs 28-30, estimation/observer/) fed each sample's drive voltage,
  current, speed and encoder angle, with a load-step detector; its noise model is
  the rig file's sensors section. It needs no calibration; with one, it adds the
  model's error measured at the calibration's points. Model: ``model_file`` (an
  identified rig) or ``rig_file``.
* ``knn`` (the paper's k-NN map over a calibration database, Eqs 33-34) and
  ``extended_model`` (inverts the identified model's quasi-static current): a
  quasi-static map behind a disturbance observer. Speed and current pass through the
  same low-pass (``input_filter``), the current that accelerates the inertia is
  removed (``inertia_compensation``, quasi_static.py), the result is smoothed
  (``estimate_filter``) except while a change is detected (``change_threshold``),
  then the map gives tau_d with an uncertainty and flags; a sample taken while the
  worm accelerates faster than ``transient_acceleration`` is flagged TRANSIENT.
  These options (and knn's ``k`` and ``weighting``) are declared only for the
  methods that read them.

A parameter set for this node (parameter file or -p) that it does not declare (an
option of another method, or no option at all) is reported at start, one warning
line each naming it, and ignored.

For other stacks the same estimate goes out in standard types, at the batch rate,
while someone subscribes: sensor_msgs/JointState on ``joint_state_topic`` (one
joint, ``joint_name``, its effort the torque the load applies to the gear shaft
in the joint's positive direction: -tau_d, the ROS convention external-torque
observers follow) and geometry_msgs/WrenchStamped on ``wrench_topic`` (torque
about +z of ``wrench_frame``, the output shaft's axis pointing so that positive
rotation is about +z: torque.z = -tau_d; force and the other torques 0).

A missing or broken calibration, rig or model file is reported (log +
/diagnostics ERROR) and the node keeps running without publishing estimates, so
the rest of the graph (the controller falls back to no feedforward) carries on.
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
from worm_model.physics.parameters import ParameterError

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.database import CalibrationError
from torque_estimator.estimation.live import LiveEstimator
from torque_estimator.estimation.registry import METHODS, Option
from torque_estimator.estimation.settings import ALL_OPTIONS, SETTINGS_OPTIONS, EstimatorSettings, build_estimator


class EstimatorNode(Node):
    def __init__(self) -> None:
        super().__init__("estimator_node")
        values = {o.name: self._declare(o) for o in SETTINGS_OPTIONS}
        self.method = values["method"]
        values.update({o.name: self._declare(o) for o in METHODS[self.method].options})
        period = 1.0 / declare(self, "sample_rate", 1000.0, "Rig sample rate [Hz].", low=1.0, high=100000.0)
        joint_topic = declare(self, "joint_state_topic", "torque_estimate/joint_states",
                              "Topic of the estimate as sensor_msgs/JointState (effort = -tau_d).")
        self.joint_name = declare(self, "joint_name", "gear", "Name of the output joint in that JointState.")
        wrench_topic = declare(self, "wrench_topic", "torque_estimate/wrench",
                               "Topic of the estimate as geometry_msgs/WrenchStamped (torque.z = -tau_d).")
        self.wrench_frame = declare(self, "wrench_frame", "gear_output",
                                    "frame_id of that wrench: its z axis is the output shaft, positive rotation "
                                    "about +z.")

        self.settings = EstimatorSettings.from_parameters(values)
        self.estimator: LiveEstimator | None = None
        self.problem = ""
        try:
            built = build_estimator(self.settings)
            self.estimator = built.live(period)
            self.get_logger().info(
                f"{self.method} estimator on {len(built.database)} calibration points from "
                f"{self.settings.calibration_file}" if built.database is not None else
                f"{self.method} estimator without a calibration (ranges from the rig file)")
        except (CalibrationError, ParameterError) as err:
            self.problem = str(err)
            self.get_logger().error(f"no estimates: {err}")

        self.pub = self.create_publisher(TorqueEstimate, "torque_estimate", STREAM)
        self.pub_joint = self.create_publisher(JointState, joint_topic, STREAM)
        self.pub_wrench = self.create_publisher(WrenchStamped, wrench_topic, STREAM)
        self.create_subscription(RigSamples, "rig/samples", self.on_samples, STREAM)
        self.received = 0
        self.malformed = 0  # /rig/samples messages refused
        self.flag_counts = {flag.name: 0 for flag in EstimateFlags if flag}
        Diagnostics(self, self.report)
        self._warn_undeclared()

    def _declare(self, option: Option):
        return declare(self, option.name, option.default, option.description, low=option.low, high=option.high,
                       choices=option.choices)

    def _warn_undeclared(self) -> None:
        """One warning per parameter given to this node that it did not declare: rclpy keeps such an override
        and never reads it, so a file setting, say, input_filter for the observer would otherwise be ignored
        without a word. (rclpy has no public accessor for a node's overrides.)"""
        for name in sorted(n for n in self._parameter_overrides if not self.has_parameter(n)):
            readers = [m for m, row in METHODS.items() if any(o.name == name for o in row.options)]
            why = (f"method {self.method} does not read it (read by {', '.join(readers)} only)" if name in ALL_OPTIONS
                   else "estimator_node has no such parameter")
            self.get_logger().warning(f"parameter {name} is set but {why}: ignored")

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
