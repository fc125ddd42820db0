"""What sim_node and driver_node share: the rig's topics, and the commands they take.

Every name is relative: a rig started in a namespace (``--ros-args -r __ns:=/arm/joint2``) puts all
of them there, and with none they are /rig/samples, ... Out (sensor-data QoS):
  rig/samples       worm_msgs/RigSamples   every sample, ``batch_size`` per message (the graph's stream)
  rig/sample        worm_msgs/RigSample    every sample one by one, only while someone subscribes
                                           (``ros2 topic echo``, a foreign stack); costs nothing otherwise
  rig/currents, rig/joint_states, rig/encoders   every ``channel_decimation``-th sample, only while
                                           someone subscribes. JointState follows ROS's convention: the
                                           gear joint's effort is the torque the load applies to the gear
                                           shaft in its positive direction, -tau_load (RigSample's
                                           tau_load is positive OPPOSING positive rotation)
  torque_estimate, torque_estimate/joint_states, torque_estimate/wrench   the load estimate of the
                                           rig's feedforward estimator (``feedforward_estimator``) for
                                           each batch's newest sample, right before the batch, as
                                           estimator_node publishes its own (estimate_topics): the
                                           estimate the graph sees is the one fed forward
                                           (``publish_estimate``: RigEstimate)
  sim_node adds the simulator's ground truth (when ``publish_truth``, only while someone subscribes):
  sim/truth_samples   worm_msgs/SimTruths  every sample, in batches aligned with rig/samples' (same
                                           first_seq, stamp and length: see opens_batch / pending)
  sim/truth           worm_msgs/SimTruth   every ``channel_decimation``-th sample
In:
  rig/speed_command   worm_msgs/SpeedCommand  the rig's own speed loop (drive.rig_loop), sensor-data QoS
  rig/drive_command   worm_msgs/DriveCommand  a voltage to hold, sensor-data QoS
                      (speed and drive commands from one publisher at a time: CommandGate)
  rig/release_command std_msgs/Empty          frees the command claim at once
  rig/load_command    worm_msgs/LoadCommand   any publisher reaches it; a latched value reaches a rig
                                              that (re)starts later (worm_model.ros.commands)

Why batches: a 1 kHz topic costs rclpy ~12-15 % of a core per endpoint, whatever the
message holds; five samples per message cut that five-fold, and the speed loop, the
only thing that needs every sample at once, runs in the rig's own process. The
batch is published the moment its last sample is taken, so the newest sample
reaches the graph as fast as a single one would.

Called from the rig's sampling thread (sim_node's clock, driver_node's reader):
rclpy publishers may be used from a thread other than the executor's.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Empty
from worm_msgs.msg import DriveCommand, EncoderCounts, LoadCommand, MotorCurrents, RigSamples, SpeedCommand
from worm_msgs.msg import RigSample as RigSampleMsg

from worm_model.physics.parameters import Rig
from worm_model.rig_data.samples import FIELDS, RigSample
from worm_model.ros.commands import subscribe_command
from worm_model.ros.parameters import declare, declare_option
from worm_model.ros.qos import STREAM

from worm_rig_driver.drive.command_owner import CommandOwner
from worm_rig_driver.drive.feedforward_plugin import load_rig_feedforward
from worm_rig_driver.errors import FeedforwardUnavailable
from worm_rig_driver.drive.rig_node_options import FEEDFORWARD_CALIBRATION, FEEDFORWARD_ESTIMATOR, PUBLISH_ESTIMATE
from worm_rig_driver.drive.rig_loop import RigFeedforward, voltage_problem
from worm_rig_driver.drive.rig_loop import SpeedCommand as LoopCommand
from worm_rig_driver.nodes.estimate_topics import EstimateTopics

#: RigSamples' per-sample columns: RigSample's fields (rig_data.samples.FIELDS) and the command in force
_BATCHED = (*FIELDS, "command_seq")


@dataclass
class _Batch:
    first_seq: int = 0
    first_stamp_ns: int = 0
    columns: dict[str, list] = field(default_factory=lambda: {name: [] for name in _BATCHED})

    def __len__(self) -> int:
        return len(self.columns["command_seq"])


class RigTopics:
    """Publishers of one rig's samples (see module docstring).

    Args:
        node: the node that owns the publishers.
        frame_id: of every header.
        sample_period: [s] of the rig's clock.
        batch_size: samples per /rig/samples message.
        decimation: the per-channel topics carry every decimation-th sample.
        counts_per_rev: encoder counts per revolution (EncoderCounts).
    """

    def __init__(self, node: Node, frame_id: str, sample_period: float, batch_size: int, decimation: int,
                 counts_per_rev: int) -> None:
        self.frame_id = frame_id
        self.sample_period = sample_period
        self.batch_size = batch_size
        self.decimation = decimation
        self.counts_per_rev = counts_per_rev
        self.pub_samples = node.create_publisher(RigSamples, "rig/samples", STREAM)
        self.pub_sample = node.create_publisher(RigSampleMsg, "rig/sample", STREAM)
        self.pub_currents = node.create_publisher(MotorCurrents, "rig/currents", STREAM)
        self.pub_joints = node.create_publisher(JointState, "rig/joint_states", STREAM)
        self.pub_encoders = node.create_publisher(EncoderCounts, "rig/encoders", STREAM)
        self._batch = _Batch()
        self._single = False  # rig/sample has subscribers (asked when a batch opens)
        self.published = 0  # samples published on /rig/samples

    def add(self, sample: RigSample) -> None:
        """One sample; publishes the batch once it is full, and the per-sample topics that have subscribers."""
        batch, seq = self._batch, sample.seq
        if len(batch) and seq != batch.first_seq + len(batch):
            self.flush()  # a gap (lost telemetry): a batch holds consecutive samples only
            batch = self._batch
        if not len(batch):
            batch.first_seq, batch.first_stamp_ns = seq, sample.stamp_ns
            # asked once a batch, not every sample (a few microseconds each at 1 kHz): a subscriber that
            # appears mid-batch gets rig/sample from the next batch on
            self._single = self.pub_sample.get_subscription_count() > 0
        columns = batch.columns
        for name in _BATCHED:
            columns[name].append(getattr(sample, name))
        single = self._single
        channels = seq % self.decimation == 0 and (self.pub_currents.get_subscription_count()
                                                   or self.pub_joints.get_subscription_count()
                                                   or self.pub_encoders.get_subscription_count())
        if single or channels:
            self._publish_single(sample, single, channels)
        if len(batch) >= self.batch_size:
            self.flush()

    def opens_batch(self, seq: int) -> bool:
        """Whether ``add(seq)`` starts a new /rig/samples batch (none is open, or seq does not follow it):
        a stream batched alongside (sim_node's truth) starts its own batch there too."""
        batch = self._batch
        return not len(batch) or seq != batch.first_seq + len(batch)

    def closes_batch(self, seq: int) -> bool:
        """Whether ``add(seq)`` publishes a full batch (a rig node publishes its estimate of that sample first)."""
        return (0 if self.opens_batch(seq) else len(self._batch)) + 1 >= self.batch_size

    @property
    def pending(self) -> int:
        """Samples of the open batch, not yet published (0 right after add() published a full batch)."""
        return len(self._batch)

    def flush(self) -> None:
        """Publish what the batch holds (nothing if empty)."""
        batch, self._batch = self._batch, _Batch()
        if not len(batch):
            return
        msg = RigSamples(first_seq=batch.first_seq, sample_period=self.sample_period, **batch.columns)
        msg.header.stamp = Time(nanoseconds=batch.first_stamp_ns).to_msg()
        msg.header.frame_id = self.frame_id
        self.pub_samples.publish(msg)
        self.published += len(batch)

    def _publish_single(self, sample: RigSample, single: bool, channels: bool) -> None:
        s = RigSampleMsg(seq=sample.seq, **{name: getattr(sample, name) for name in FIELDS})
        s.header.stamp = Time(nanoseconds=sample.stamp_ns).to_msg()
        s.header.frame_id = self.frame_id
        if single:
            self.pub_sample.publish(s)
        if not channels:
            return
        if self.pub_currents.get_subscription_count():
            self.pub_currents.publish(MotorCurrents(header=s.header, drive=s.current_drive, load_1=s.current_load_1,
                                                    load_2=s.current_load_2))
        if self.pub_joints.get_subscription_count():
            self.pub_joints.publish(JointState(header=s.header, name=["worm", "gear"],
                                               position=[s.theta_worm, s.theta_gear],
                                               velocity=[s.omega_worm, s.omega_gear],
                                               effort=[math.nan, -s.tau_load]))  # see the docstring
        if self.pub_encoders.get_subscription_count():
            self.pub_encoders.publish(EncoderCounts(header=s.header, drive=s.count_drive, load_1=s.count_load_1,
                                                    load_2=s.count_load_2, counts_per_rev=self.counts_per_rev))


def speed_command_from_msg(msg: SpeedCommand) -> LoopCommand:
    """The rig loop's view of a worm_msgs/SpeedCommand (RigLoop.command_speed checks it)."""
    return LoopCommand(setpoint=msg.speed_setpoint, feedforward=msg.feedforward_torque, kp=msg.kp, ki=msg.ki,
                       voltage_limit=msg.voltage_limit, source_seq=msg.sample_seq, at_rig=msg.feedforward_at_rig)


def declare_rig_feedforward(node: Node, rig: Rig, sample_period: float) -> RigFeedforward | None:
    """The estimator the rig runs beside its speed loop, from the node's parameters feedforward_estimator and
    feedforward_calibration (None when feedforward_estimator is empty).

    Raises:
        ValueError: it cannot be built (one line naming the parameter; run_node exits 2 with it).
    """
    method = declare_option(node, FEEDFORWARD_ESTIMATOR)
    calibration = declare_option(node, FEEDFORWARD_CALIBRATION)
    if not method:
        return None
    try:
        source = load_rig_feedforward(method, calibration, rig, sample_period)
    except FeedforwardUnavailable as err:
        raise ValueError(f"parameter feedforward_estimator={method!r} (feedforward_calibration="
                         f"{calibration!r}): {err}") from None
    node.get_logger().info(f"feedforward at the rig: {method} estimator"
                           + (f" on the calibration {calibration}" if calibration else " without a calibration"))
    return source


class RigEstimate:
    """The rig's feedforward estimate on the graph (module docstring): with each batch of rig/samples (just
    before it), the estimate of its newest sample, on estimate_topics' single-joint topics.

    Args:
        node: the rig's node (declares ``publish_estimate``, ``joint_name``, ``wrench_frame``).
        rig: its rig (the plausibility bound of the standard outputs: 1.5 x max_load_torque).
        feedforward: the rig's feedforward estimator (None: nothing is published).
        frame_id: of the TorqueEstimate headers (the samples').
    """

    def __init__(self, node: Node, rig: Rig, feedforward: RigFeedforward | None, frame_id: str) -> None:
        publish = declare_option(node, PUBLISH_ESTIMATE)
        joint_name = declare(node, "joint_name", "gear", "Name of the joint in torque_estimate/joint_states.")
        wrench_frame = declare(node, "wrench_frame", "gear_output",
                               "frame_id of torque_estimate/wrench: its z axis is the output shaft, positive "
                               "rotation about +z.")
        self.frame_id = frame_id
        self.topics = (EstimateTopics(node, feedforward.method, [joint_name], [1.5 * rig.max_load_torque],
                                      sample_period=1.0 / rig.sensors.sample_rate_hz, wrench_frame=wrench_frame)
                       if feedforward is not None and publish else None)

    def after_sample(self, seq: int, stamp_ns: int, closes_batch: bool, estimate: Any) -> None:
        """Sample ``seq`` (stamped ``stamp_ns``) went to the feedforward, which returned ``estimate`` (None: no
        feedforward): judge it for the standard outputs, and publish it if the sample closes a batch of
        rig/samples (``RigTopics.closes_batch``). Called before that batch is published: the estimate is what
        the controller waits for."""
        if self.topics is None or estimate is None:
            return
        self.topics.observe(0, estimate.flags, estimate.torque)
        if closes_batch:
            self.topics.publish(stamp_ns, self.frame_id, [(seq, estimate)])

    def report(self) -> dict[str, int]:
        """For /diagnostics: what the standard outputs carried and withheld."""
        return self.topics.report() if self.topics is not None else {}


class CommandGate:
    """The rig's speed and drive commands from one node at a time (drive.command_owner: the first one takes
    the motor, another's commands are refused and counted until the owner has been silent for ``timeout``
    [s], or the claim is released at once by a std_msgs/Empty on rig/release_command, e.g.
    ``ros2 topic pub --once rig/release_command std_msgs/msg/Empty``). A command's node is found from the
    GID rclpy hands with each message (Kilted and newer) in the ROS graph, once per publisher (a node's
    speed and drive publishers are one claimant; a publisher the graph does not know yet is its GID until
    it does). Where rclpy hands no GID (Jazzy), every command is taken and the gate says so once."""

    TOPICS = {"speed": "rig/speed_command", "drive": "rig/drive_command"}

    def __init__(self, node: Node, timeout: float, on_speed: Callable[[SpeedCommand], str],
                 on_drive: Callable[[DriveCommand], str], drive_problem: Callable[[float], str | None]) -> None:
        self.node = node
        #: why the rig would refuse a command, without acting on it: a bad command from a node that does not hold
        #: the motor is refused with that reason (the more useful one to its sender), not for the claim
        self.problems: dict[str, Callable[[Any], str | None]] = {
            "speed": lambda msg: speed_command_from_msg(msg).problem(),
            "drive": lambda msg: drive_problem(msg.voltage)}
        self.owner = CommandOwner(timeout)
        self.nodes: dict[bytes, str] = {}  # publisher GID -> its node's full name
        self.without_gid = 0  # commands taken with no publisher GID to judge them by
        node.create_subscription(SpeedCommand, self.TOPICS["speed"],
                                 lambda msg, info: self._take("speed", msg, info, on_speed), STREAM)
        node.create_subscription(DriveCommand, self.TOPICS["drive"],
                                 lambda msg, info: self._take("drive", msg, info, on_drive), STREAM)
        subscribe_command(node, Empty, "rig/release_command", self._release)

    def _take(self, kind: str, msg: Any, info: Any, handler: Callable[[Any], str]) -> None:
        """Hand ``msg`` to the rig's ``handler`` (which acts on it, or refuses it and returns why) if its
        publisher may drive the motor; a command the rig refuses (non-finite, beyond a limit) neither takes
        nor keeps the claim."""
        gid = info.get("publisher_gid") if isinstance(info, dict) else None
        if gid is None:
            if not self.without_gid:
                self.node.get_logger().warning("this rclpy hands no publisher GID with a message: commands from "
                                               "every publisher are taken (no one-master rule)")
            self.without_gid += 1
            handler(msg)
            return
        claimant, now = self._claimant(kind, bytes(gid["data"])), time.monotonic()
        if self.owner.allows(claimant, now):
            if not handler(msg):
                self.owner.offer(claimant, now)
            return
        if self.problems[kind](msg):
            handler(msg)  # refused there with its own reason, and counted
            return
        self.owner.offer(claimant, now)  # refused and counted
        log_refusal(self.node, kind, f"the motor is {self.owner.owner}'s; {claimant}'s commands are refused until "
                                     f"its owner's stop for {self.owner.timeout:g} s or rig/release_command frees it")

    def _release(self, _msg: Any) -> None:
        if self.owner.owner is not None:
            self.node.get_logger().info(f"command claim of {self.owner.owner} released")
        self.owner.release()

    def _claimant(self, kind: str, publisher: bytes) -> str:
        """The full name of the node whose publisher has this GID (the ROS graph's view), else the GID in hex."""
        if publisher in self.nodes:
            return self.nodes[publisher]
        try:
            for info in self.node.get_publishers_info_by_topic(self.node.resolve_topic_name(self.TOPICS[kind])):
                # a participant whose node list has not arrived yet names its endpoints _NODE_NAME_UNKNOWN_
                if bytes(info.endpoint_gid)[:len(publisher)] == publisher and not info.node_name.startswith("_"):
                    name = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                    self.nodes[publisher] = name
                    if self.owner.owner == publisher.hex():  # it claimed before the graph knew it
                        self.owner.owner = name
                    return name
        except Exception:  # noqa: BLE001 - a graph query that fails leaves the GID itself as the claimant
            pass
        return publisher.hex()

    def report(self) -> dict[str, Any]:
        """For /diagnostics: which node holds the motor, and whose commands were refused (how many)."""
        out: dict[str, Any] = {"command_owner": self.owner.owner or "nobody", "command_claims": self.owner.claims,
                               "refused_commands": self.owner.refused_total}
        if self.owner.refused:
            out["refused_from"] = ", ".join(f"{who} ({n})" for who, n in self.owner.refused.items())
        if self.without_gid:
            out["commands_without_publisher_gid"] = self.without_gid
        return out


def subscribe_commands(node: Node, on_speed: Callable[[SpeedCommand], str],
                       on_drive: Callable[[DriveCommand], str], on_load: Callable[[LoadCommand], None],
                       command_timeout: float, drive_problem: Callable[[float], str | None] = voltage_problem
                       ) -> CommandGate:
    """The rig's command subscriptions, with the QoS every rig uses: speed and drive commands through one
    CommandGate (one publisher at a time, its claim passing after ``command_timeout`` [s] of silence; each
    handler returns why it refused the command, '' if it took it; ``drive_problem`` says why the rig refuses a
    drive voltage [V], as on_drive would), load commands from anyone (the load is the test bench's, not the
    motor's drive)."""
    gate = CommandGate(node, command_timeout, on_speed, on_drive, drive_problem)
    subscribe_command(node, LoadCommand, "rig/load_command", on_load)
    return gate


def log_refusal(node: Node, what: str, reason: str) -> None:
    """Warn that a ``what`` ("speed", "drive", "load") command was refused, at most once a second per kind.

    One call site per kind: rclpy throttles per call site, so a refused speed command must not
    silence a refused drive command. (.warning, not .warn: rclpy keys a call site's throttle filter on
    its caller, and .warn (deprecated) is one caller for every site; a throttled .warn followed by
    another .warn made this rclpy's logger raise.)
    """
    text, log = f"rejected {what} command: {reason}", node.get_logger()
    if what == "speed":
        log.warning(text, throttle_duration_sec=1.0)
    elif what == "drive":
        log.warning(text, throttle_duration_sec=1.0)
    else:
        log.warning(text, throttle_duration_sec=1.0)


__all__ = ["CommandGate", "RigEstimate", "RigTopics", "declare_rig_feedforward", "log_refusal",
           "speed_command_from_msg", "subscribe_commands"]
