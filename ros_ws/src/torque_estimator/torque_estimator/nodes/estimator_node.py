"""estimator_node: the load torque tau_d without a torque sensor, from a rig's samples or a robot's JointState.

Input (``input``), every topic relative to the node's namespace (``-r __ns:=/arm/joint2``):

* ``rig_samples`` (default): rig/samples (worm_msgs/RigSamples, batches of consecutive samples),
  the estimator run on every sample; one estimate published per batch (its newest sample: the
  rig's batch rate, 200 Hz by default), on the topics of worm_rig_driver.nodes.estimate_topics:
  torque_estimate (worm_msgs/TorqueEstimate), and while someone subscribes
  torque_estimate/joint_states (one joint, ``joint_name``) and torque_estimate/wrench
  (``wrench_frame``). A rig node that runs an estimator for its feedforward publishes that estimate
  on the same topics (sim_node / driver_node ``publish_estimate``): the shipped graph runs no
  estimator_node; run one beside such a rig only with the rig's ``publish_estimate`` false, or in
  a namespace of its own.
* ``joint_state``: a robot's sensor_msgs/JointState on ``joint_state_topic`` (default
  joint_states: what ros2_control's joint_state_broadcaster publishes), one estimator per joint of
  ``joint_names`` (found by name in every message, any order; joints.settings: per-joint rig,
  model and calibration files as lists parallel to joint_names), positions and velocities on the
  ``joint_side`` shaft, effort as ``effort_is`` (worm_model.rig_data.joint_states: the rig file's
  ratio and K_t convert; stamps from the header, ``sample_rate`` the publisher's rate). What must
  not be estimated from (a joint absent, a missing field, NaN, a repeated, earlier or early
  stamp) is refused and counted per joint on /diagnostics. The message stamped at every
  ``publish_every``-th sample period (a phase of the stamps' clock) gives, per joint ``j``,
  torque_estimate/<j> (TorqueEstimate, frame_id ``j``) and while subscribed
  torque_estimate/<j>/wrench, and one torque_estimate/joint_states with every joint's effort. A
  method that reads the drive voltage (the observer) needs ``voltage_topics`` (std_msgs/Float64
  [V], the newest value used, per joint); without them the node refuses to start (exit 2). The
  method defaults to joints.settings.JOINT_STATE_METHOD there.

The estimator is the parameter ``method`` (estimation.registry), built from the node's parameters by
estimation.settings (as replay, ``estimate`` and the rig feedforward build theirs), and fed every
sample by estimation.live.LiveEstimator:

* ``observer``: a Kalman filter on the rig's model (Eqs 28-30, estimation/observer/) fed each
  sample's drive voltage, current, speed and encoder angle, with a load-step detector; its noise
  model is the rig file's sensors section. It needs no calibration; with one, it adds the model's
  error measured at the calibration's points. Model: ``model_file`` (an identified rig) or
  ``rig_file``.
* ``knn`` (the paper's k-NN map over a calibration database, Eqs 33-34) and ``extended_model``
  (inverts the identified model's quasi-static current): a quasi-static map behind a disturbance
  observer. Speed and current pass through the same low-pass (``input_filter``), the current that
  accelerates the inertia is removed (``inertia_compensation``, quasi_static.py), the result is
  smoothed (``estimate_filter``) except while a change is detected (``change_threshold``), then the
  map gives tau_d with an uncertainty and flags; a sample taken while the worm accelerates faster
  than ``transient_acceleration`` is flagged TRANSIENT. These options (and knn's ``k`` and
  ``weighting``) are declared only for the methods that read them.

A parameter set for this node (parameter file or -p) that it does not declare (an option of another
method or input, or no option at all) is reported at start, one warning line each naming it, and
ignored.

The standard outputs' effort (JointState) and torque.z (WrenchStamped) are the torque the load
applies to the joint in its positive direction, -tau_d, for trusted estimates only: NaN for one
flagged INVALID_INPUT, TRANSIENT or OUT_OF_CALIBRATION, or beyond 1.5 x the rig file's
max_load_torque (worm_rig_driver.robot.standard_outputs: what and why). TorqueEstimate carries
every estimate with its flags.

A calibration, model or rig file that is named but cannot be used (missing, damaged, implausible
for the rig) stops the node at start: one line, exit code 2. So does a method that needs a
calibration (knn) with none named: a node that cannot do its job with the parameters it was given
does not start (the shipped observer needs none, so a graph runs before it is calibrated).
"""
from __future__ import annotations

from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from worm_msgs.msg import RigSamples

from worm_model.rig_data.samples import batch_problem
from worm_model.ros.diagnostics import OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.nodes.joint_state_input import declare_joint_state_input
from worm_model.rig_data.joint_states import JOINT_STATE_OPTIONS
from worm_model.ros.parameters import declare_option
from worm_model.ros.qos import STREAM
from worm_rig_driver.nodes.estimate_topics import EstimateTopics

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.errors import CalibrationError
from torque_estimator.estimation.registry import METHODS
from torque_estimator.estimation.settings import (ALL_OPTIONS, INPUT_OPTIONS, RIG_SAMPLES_OPTIONS, SETTINGS_OPTIONS,
                                                  EstimatorSettings, build_estimator)
from torque_estimator.joints.estimators import JointEstimators
from torque_estimator.joints.settings import JOINT_STATE_ESTIMATOR_OPTIONS, JOINT_STATE_METHOD, joint_setups

#: each input's own parameters (a parameter of the other input is reported as not read)
INPUT_PARAMETERS = {"rig_samples": tuple(o.name for o in RIG_SAMPLES_OPTIONS),
                    "joint_state": tuple(o.name for o in JOINT_STATE_OPTIONS + JOINT_STATE_ESTIMATOR_OPTIONS)}


class EstimatorNode(Node):
    def __init__(self) -> None:
        super().__init__("estimator_node")
        self.input, rate = (declare_option(self, row) for row in INPUT_OPTIONS)
        joint_state = self.input == "joint_state"
        values = {o.name: declare_option(self, o, JOINT_STATE_METHOD if joint_state and o.name == "method" else None)
                  for o in SETTINGS_OPTIONS}
        self.method = values["method"]
        values.update({o.name: declare_option(self, o) for o in METHODS[self.method].options})
        self.period = 1.0 / rate
        self.flag_counts = {flag.name: 0 for flag in EstimateFlags if flag}
        self.received = 0
        self.malformed = 0  # rig/samples messages refused
        self.topics: EstimateTopics | None = None
        if joint_state:
            self._start_joint_state(values)
        else:
            self._start_rig_samples(values)
        Diagnostics(self, self.report)
        self._warn_undeclared()

    # --- start-up ----------------------------------------------------------------------------------
    def _start_rig_samples(self, values: dict) -> None:
        joint_name, wrench_frame = (declare_option(self, row) for row in RIG_SAMPLES_OPTIONS)
        self.settings = EstimatorSettings.from_parameters(values)
        try:
            built = build_estimator(self.settings)
            self.estimator = built.live(self.period)
            self.topics = EstimateTopics(self, self.method, [joint_name], [1.5 * built.rig.max_load_torque],
                                         sample_period=self.period, wrench_frame=wrench_frame)
            self.get_logger().info(
                f"{self.method} estimator on {len(built.database)} calibration points from "
                f"{self.settings.calibration_file}" if built.database is not None else
                f"{self.method} estimator without a calibration (ranges from the "
                f"{getattr(built.estimator, 'ranges_from', None) or 'rig'})")
        except CalibrationError as err:
            if self.settings.calibration_file:
                raise  # a file the user named cannot be used: stop (exit 2)
            # a method that cannot run on what it was given: stop too, saying which parameter to set
            raise CalibrationError(f"parameter calibration_file: {err}; set calibration_file, or a method that "
                                   "needs none (observer, momentum, extended_model)") from None
        self.create_subscription(RigSamples, "rig/samples", self.on_samples, STREAM)

    def _start_joint_state(self, values: dict) -> None:
        topic, names, side, effort_is = declare_joint_state_input(self)
        volts, *lists, self.publish_every = (declare_option(self, row) for row in JOINT_STATE_ESTIMATOR_OPTIONS)
        files = dict(zip((row.name for row in JOINT_STATE_ESTIMATOR_OPTIONS[1:-1]), lists))
        self.period_ns = self.period * 1e9
        setups = joint_setups(values, names, volts, files)  # ValueError: one line, exit 2
        try:
            self.joints = JointEstimators(setups, self.period, side, effort_is)
            self.topics = EstimateTopics(self, self.method, [s.name for s in setups], self.joints.max_loads,
                                         sample_period=self.period, per_joint=True)
            self.get_logger().info(f"{self.method} estimators for joints {', '.join(s.name for s in setups)} of "
                                   f"{self.resolve_topic_name(topic)} ({side} side, effort as {effort_is})")
        except CalibrationError as err:
            if any(s.settings.calibration_file for s in setups):
                raise  # a file the user named cannot be used: stop (exit 2)
            raise CalibrationError(f"parameter calibration_files: {err}; name each joint's calibration, or a "
                                   "method that needs none (extended_model, momentum)") from None
        self.voltages: dict[str, float] = {}
        for setup in setups:
            if setup.voltage_topic:
                self.create_subscription(Float64, setup.voltage_topic,
                                         lambda msg, joint=setup.name: self.voltages.__setitem__(joint, msg.data),
                                         STREAM)
        self.messages = 0
        self.create_subscription(JointState, topic, self.on_joint_state, STREAM)

    def _warn_undeclared(self) -> None:
        """One warning per parameter given to this node that it did not declare: rclpy keeps such an override
        and never reads it, so a file setting, say, input_filter for the observer would otherwise be ignored
        without a word. (rclpy has no public accessor for a node's overrides.)"""
        for name in sorted(n for n in self._parameter_overrides if not self.has_parameter(n)):
            readers = [m for m, row in METHODS.items() if any(o.name == name for o in row.options)]
            inputs = [i for i, names in INPUT_PARAMETERS.items() if name in names]
            why = (f"method {self.method} does not read it (read by {', '.join(readers)} only)" if name in ALL_OPTIONS
                   else f"input {self.input} does not read it (input {inputs[0]} does)" if inputs
                   else "estimator_node has no such parameter")
            self.get_logger().warning(f"parameter {name} is set but {why}: ignored")

    # --- input -------------------------------------------------------------------------------------
    def on_samples(self, batch: RigSamples) -> None:
        problem = batch_problem(batch, ("omega_worm", "current_drive", "voltage_drive", "theta_worm"))
        if problem:
            self.malformed += 1
            self.get_logger().warning(f"ignored a rig/samples message (first_seq {batch.first_seq}): {problem}",
                                      throttle_duration_sec=1.0)
            return
        n = len(batch.omega_worm)
        self.received += n
        if not n:
            return
        omega, current, voltage, theta = batch.omega_worm, batch.current_drive, batch.voltage_drive, batch.theta_worm
        restarts = self.estimator.restarts
        for k in range(n):
            est = self.estimator.update(omega[k], current[k], voltage_drive=voltage[k], theta_worm=theta[k],
                                        seq=batch.first_seq + k)
            if self.estimator.restarts != restarts:
                self.topics.restart(0)
            self.topics.observe(0, est.flags, est.torque)
            if est.flags:
                for flag in EstimateFlags(est.flags):
                    self.flag_counts[flag.name] += 1
        if self.estimator.restarts != restarts:
            self.get_logger().info(f"rig sample stream started again at seq {batch.first_seq} (a restarted rig "
                                   "or driver): estimator state reset")
        last = n - 1
        stamp = Time.from_msg(batch.header.stamp).nanoseconds + int(round(last * batch.sample_period * 1e9))
        self.topics.publish(stamp, batch.header.frame_id, [(batch.first_seq + last, est)])

    def on_joint_state(self, msg: JointState) -> None:
        self.messages += 1
        stamp = Time.from_msg(msg.header.stamp).nanoseconds
        # the messages at every publish_every-th period of the stamps' clock: a phase of the clock, not of
        # this node's start, so every estimator of one JointState publishes the same stamps
        publish = round(stamp / self.period_ns) % self.publish_every == self.publish_every - 1
        estimates = self.joints.update(stamp, msg.name, msg.position, msg.velocity, msg.effort, self.voltages,
                                       estimate=publish)
        for k, (flags, torque) in enumerate(self.joints.judged):
            if flags is not None:  # the joint had a sample in this message
                if self.joints.restarted[k]:
                    self.topics.restart(k)
                self.topics.observe(k, flags, torque)
        if publish:
            self.topics.publish(stamp, msg.header.frame_id, estimates)

    # --- health ------------------------------------------------------------------------------------
    def report(self) -> tuple[bytes, str, dict]:
        outputs = self.topics.report() if self.topics is not None else {}
        if self.input == "joint_state":
            values = {**self.joints.report(), **outputs}
            refused = self.joints.reader.refused_total()
            invalid = sum(c["INVALID_INPUT"] for c in self.joints.flag_counts)
            return (WARN if refused or invalid else OK), (
                f"estimating {len(self.joints.names)} joints" + (f"; {refused} joint samples refused" if refused
                                                                 else "")), values
        level = WARN if self.flag_counts["INVALID_INPUT"] else OK
        e = self.estimator
        return level, "estimating", {"samples": self.received, "malformed_batches": self.malformed,
                                     "seq_gaps": e.gaps, "samples_lost": e.lost, "stream_restarts": e.restarts,
                                     **self.flag_counts, **outputs}


def main(args=None) -> int:
    return run_node(EstimatorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
