"""A robot's sensor_msgs/JointState as rig samples: one drive per joint, looked up by name in every message.

What a ROS 2 robot publishes for its joints (ros2_control's joint_state_broadcaster, or a motor
drive's own driver): one message per control tick, every joint of the robot in it, names in the
publisher's order, ``position`` [rad], ``velocity`` [rad/s] and ``effort`` arrays parallel to
``name`` (an array may be empty: that field is not published), the header stamp the instant the
states were read. A worm-geared joint's drive becomes a rig sample of the estimators' inputs:

* the worm (motor) shaft's speed ω_w [rad/s] and angle θ_w [rad]: ``velocity`` and ``position``
  as they are for ``joint_side`` "motor"; for "output" (the joint is the gear shaft, as a
  transmission reports it) divided by the rig file's ratio i = n/Z_g (ω_w = ω_joint / i), the
  joint's positive direction being the one positive worm rotation drives (worm-referenced sign,
  physics.md §2);
* the drive current i [A]: ``effort`` as it is for ``effort_is`` "current", divided by the rig
  file's K_t for "motor_torque" (the motor's electromagnetic torque K_t·i [N m], whichever shaft
  the joint is);
* the drive voltage [V], when the caller has one for the joint (``voltage``): NaN otherwise.

Stamps: the message header's. A joint's samples are numbered from its first one: a stamp
``n`` sample periods after the joint's last accepted stamp (rounded) is ``n`` seqs later, so a
message the publisher never sent (or DDS lost) is a seq gap the estimators bridge, and a drifting
publisher clock is followed. Refused, counted per joint and never turned into a sample: the joint
absent from the message (``absent``), its velocity or effort array missing or shorter than the
names (``missing_field``; a missing position only leaves the angle unknown), a NaN/inf velocity or
effort (``not_finite``), a stamp equal to the joint's last (``repeated``), earlier than it
(``out_of_order``), or less than half a period after it (``early``: not this rate's next sample).
A message whose arrays are longer than its names is refused whole (``malformed_messages``).

Plain Python (no rclpy): the caller hands over the message's fields; rclpy messages and the bag
reader's dataclasses alike.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from worm_model.cli.node_options import STRING_ARRAY, Option
from worm_model.physics.parameters import Rig

#: Which shaft a joint's position and velocity belong to.
JOINT_SIDES: tuple[str, ...] = ("motor", "output")
#: What a joint's effort is: the drive current [A], or the motor's torque K_t·i [N m].
EFFORT_KINDS: tuple[str, ...] = ("current", "motor_torque")

#: A node's JointState input, the parameters model_node and estimator_node declare for it
#: (worm_model.nodes.joint_state_input) and replay reads.
JOINT_STATE_OPTIONS: tuple[Option, ...] = (
    Option("joint_state_topic", "joint_states",
           "Topic of the robot's sensor_msgs/JointState (relative: in this node's namespace)."),
    Option("joint_names", STRING_ARRAY, "The joints, by their names in the JointState (any order there)."),
    Option("joint_side", "output", "Shaft of the JointState's position and velocity: output (the gear shaft, as a "
           "robot's joint) or motor (the worm); the rig file's ratio converts.", choices=JOINT_SIDES),
    Option("effort_is", "current", "What the JointState's effort is: current (the drive current [A]) or "
           "motor_torque (K_t i [N m]; the rig file's K_t converts).", choices=EFFORT_KINDS),
)
#: Per-joint counts of what was refused (module docstring), in report order.
REFUSALS: tuple[str, ...] = ("absent", "missing_field", "not_finite", "repeated", "out_of_order", "early")


@dataclass(frozen=True)
class JointConversion:
    """How one joint's JointState entries become the drive's inputs (module docstring).

    Attributes:
        name: the joint's name in the messages.
        ratio: i = n/Z_g [1] of the joint's gearbox (ω_gear = i·ω_worm).
        torque_constant: K_t [N m/A] of the joint's drive motor.
        joint_side: "motor" or "output" (JOINT_SIDES).
        effort_is: "current" or "motor_torque" (EFFORT_KINDS).
    """

    name: str
    ratio: float
    torque_constant: float
    joint_side: str = "motor"
    effort_is: str = "current"

    def __post_init__(self) -> None:
        if self.joint_side not in JOINT_SIDES:
            raise ValueError(f"joint {self.name}: joint_side {self.joint_side!r} is not one of {JOINT_SIDES}")
        if self.effort_is not in EFFORT_KINDS:
            raise ValueError(f"joint {self.name}: effort_is {self.effort_is!r} is not one of {EFFORT_KINDS}")
        if not (self.ratio > 0 and self.torque_constant > 0):
            raise ValueError(f"joint {self.name}: need ratio > 0 and torque_constant > 0, got {self.ratio}, "
                             f"{self.torque_constant}")

    @classmethod
    def from_rig(cls, name: str, rig: Rig, joint_side: str = "motor", effort_is: str = "current") -> "JointConversion":
        """The conversion of joint ``name`` driven through ``rig``'s gearbox by its drive motor."""
        return cls(name, rig.gearbox.ratio, rig.drive_motor.torque_constant, joint_side, effort_is)

    def worm(self, position: float, velocity: float) -> tuple[float, float]:
        """(θ_w [rad], ω_w [rad/s]) of the joint's position and velocity."""
        if self.joint_side == "output":
            return position / self.ratio, velocity / self.ratio
        return position, velocity

    def current(self, effort: float) -> float:
        """The drive current [A] of the joint's effort."""
        return effort / self.torque_constant if self.effort_is == "motor_torque" else effort


@dataclass(frozen=True)
class JointSample:
    """One joint's sample of one message: the estimators' inputs.

    Attributes:
        seq: the joint's sample number (from the stamps: module docstring).
        stamp_ns: the message's header stamp [ns].
        omega_worm [rad/s], current_drive [A]: finite.
        theta_worm [rad]: None without a position.
        voltage_drive [V]: NaN without a voltage.
    """

    seq: int
    stamp_ns: int
    omega_worm: float
    current_drive: float
    theta_worm: float | None
    voltage_drive: float


@dataclass
class _JointState:
    """A joint's stamp bookkeeping and refusal counts."""

    last_stamp_ns: int | None = None
    seq: int = 0
    samples: int = 0
    refused: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REFUSALS, 0))


class JointStateReader:
    """Joint states in, one :class:`JointSample` (or None: refused) per configured joint out.

    Args:
        joints: the conversions of the joints to read, in the caller's order (any order in the messages).
        sample_period: [s] between the publisher's messages (its rate's inverse).
    """

    def __init__(self, joints: Sequence[JointConversion], sample_period: float) -> None:
        names = [j.name for j in joints]
        if not names:
            raise ValueError("no joints to read")
        if len(set(names)) != len(names):
            raise ValueError(f"joint names repeat: {names}")
        if not sample_period > 0:
            raise ValueError(f"sample_period must be > 0, got {sample_period}")
        self.joints = tuple(joints)
        self.period_ns = sample_period * 1e9
        self.messages = 0
        self.malformed_messages = 0
        self._state = {j.name: _JointState() for j in self.joints}

    def read(self, stamp_ns: int, names: Sequence[str], position: Sequence[float], velocity: Sequence[float],
             effort: Sequence[float], voltage: Mapping[str, float] | None = None) -> list[JointSample | None]:
        """One message: its header stamp [ns] and arrays; ``voltage``: the drive voltage [V] per joint name
        where the caller has one. Returns one entry per configured joint, in their order."""
        self.messages += 1
        n = len(names)
        if any(len(a) > n for a in (position, velocity, effort)):
            self.malformed_messages += 1
            return [None] * len(self.joints)
        index = {name: k for k, name in enumerate(names)}
        out: list[JointSample | None] = []
        for joint in self.joints:
            state = self._state[joint.name]
            k = index.get(joint.name)
            reason = self._refusal(k, velocity, effort)
            if reason is None:
                reason, seq = self._follow(state, stamp_ns)
            if reason is not None:
                state.refused[reason] += 1
                out.append(None)
                continue
            position_k = position[k] if k < len(position) and math.isfinite(position[k]) else None
            theta, omega = joint.worm(0.0 if position_k is None else position_k, velocity[k])
            volts = (voltage or {}).get(joint.name, math.nan)
            state.samples += 1
            out.append(JointSample(seq, stamp_ns, omega, joint.current(effort[k]),
                                   None if position_k is None else theta, volts))
        return out

    @staticmethod
    def _refusal(k: int | None, velocity: Sequence[float], effort: Sequence[float]) -> str | None:
        if k is None:
            return "absent"
        if k >= len(velocity) or k >= len(effort):
            return "missing_field"
        if not (math.isfinite(velocity[k]) and math.isfinite(effort[k])):
            return "not_finite"
        return None

    def _follow(self, state: _JointState, stamp_ns: int) -> tuple[str | None, int]:
        """(refusal or None, seq) of a joint's next stamp; a refused stamp leaves the joint's clock as it was."""
        last = state.last_stamp_ns
        if last is not None:
            if stamp_ns == last:
                return "repeated", state.seq
            if stamp_ns < last:
                return "out_of_order", state.seq
            steps = round((stamp_ns - last) / self.period_ns)
            if steps < 1:
                return "early", state.seq
            state.seq += steps
        state.last_stamp_ns = stamp_ns
        return None, state.seq

    # --- what /diagnostics reports ---------------------------------------------------------------
    def samples(self, name: str) -> int:
        """Samples of joint ``name`` accepted so far."""
        return self._state[name].samples

    def refused(self, name: str) -> dict[str, int]:
        """Joint ``name``'s refusals so far, by reason (REFUSALS)."""
        return dict(self._state[name].refused)

    def refused_total(self) -> int:
        """Every joint's refusals plus the malformed messages."""
        return self.malformed_messages + sum(sum(s.refused.values()) for s in self._state.values())


__all__ = ["EFFORT_KINDS", "JOINT_SIDES", "JOINT_STATE_OPTIONS", "REFUSALS", "JointConversion", "JointSample",
           "JointStateReader"]
