"""Several rigs as the joints of one robot: their sample streams onto one sensor_msgs/JointState per tick.

What a robot's estimator is fed (estimator_node ``input: joint_state``) is what ros2_control's
joint_state_broadcaster publishes: every joint of the robot in one message per controller tick,
one stamp, position/velocity/effort read at that tick. Simulated drives each run their own
1 kHz clock (sim_node, one per namespace) and publish batches of samples; this merges them as a
controller manager would read them: on a tick grid of the sample period (whole periods of the
stamps' clock), each joint's value at tick t is its newest sample stamped at or before t, if that
sample is less than a period old (else the joint is left out of that tick's message: absent).
A tick goes out once every joint has a sample stamped after it (so its newest one before it is
known), or once it is ``max_wait`` older than the newest sample of any joint (a stalled rig does
not hold the others back; it is absent from those ticks).

Each joint's entries are what a drive reports (worm_model.rig_data.joint_states.JointConversion,
inverted): position and velocity on the output shaft (the rig file's ratio: θ_w·i, ω_w·i) or the
motor's, effort the drive current [A] or the motor torque K_t·i [N m]. Plain Python.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from worm_model.rig_data.joint_states import JointConversion


@dataclass(frozen=True)
class MergedTick:
    """One tick's message: its stamp [ns] and the joints present, with their entries."""

    stamp_ns: int
    names: list[str]
    position: list[float]
    velocity: list[float]
    effort: list[float]


class JointStateMerger:
    """Rig samples in (per joint, in stamp order), one :class:`MergedTick` per tick out (module docstring).

    Args:
        joints: each joint's conversion (its name, its rig's ratio and K_t, the side and effort reported).
        sample_period: [s] the tick grid (the rigs' sample period).
        max_wait: [s] how long a tick waits for a joint that has sent nothing after it.
    """

    def __init__(self, joints: Sequence[JointConversion], sample_period: float, max_wait: float = 0.05) -> None:
        if not joints or not sample_period > 0 or max_wait < 0:
            raise ValueError(f"need joints, sample_period > 0, max_wait >= 0; got {len(joints)}, {sample_period}, "
                             f"{max_wait}")
        self.joints = list(joints)
        self.period_ns = int(round(sample_period * 1e9))
        self.max_wait_ns = int(round(max_wait * 1e9))
        self._pending: list[deque[tuple[int, float, float, float]]] = [deque() for _ in joints]
        self._held: list[tuple[int, float, float, float] | None] = [None] * len(joints)
        self._newest = [-1] * len(joints)  # [ns] newest stamp received per joint
        self._next_tick: int | None = None
        self.ticks = 0
        self.absent = [0] * len(joints)  # ticks published without each joint

    def add(self, joint: int, samples: Iterable[tuple[int, float, float, float]]) -> None:
        """Samples of joint index ``joint``: (stamp [ns], θ_w [rad], ω_w [rad/s], drive current [A]) each,
        in stamp order."""
        queue = self._pending[joint]
        for sample in samples:
            if sample[0] > self._newest[joint]:
                queue.append(sample)
                self._newest[joint] = sample[0]
        if self._next_tick is None and all(n >= 0 for n in self._newest):
            # the first tick: the first grid point at or after every joint's first sample
            first = max(q[0][0] for q in self._pending if q)
            self._next_tick = -(-first // self.period_ns) * self.period_ns

    def ready(self) -> list[MergedTick]:
        """The ticks that can go out now (module docstring), oldest first."""
        if self._next_tick is None:
            return []
        horizon = max(min(self._newest) - 1, max(self._newest) - self.max_wait_ns)
        out = []
        while self._next_tick <= horizon:
            out.append(self._tick(self._next_tick))
            self._next_tick += self.period_ns
        return out

    def _tick(self, t: int) -> MergedTick:
        tick = MergedTick(t, [], [], [], [])
        for k, joint in enumerate(self.joints):
            queue = self._pending[k]
            while queue and queue[0][0] <= t:
                self._held[k] = queue.popleft()
            held = self._held[k]
            if held is None or held[0] <= t - self.period_ns:
                self.absent[k] += 1
                continue
            _stamp, theta, omega, current = held
            ratio = joint.ratio if joint.joint_side == "output" else 1.0
            tick.names.append(joint.name)
            tick.position.append(theta * ratio)
            tick.velocity.append(omega * ratio)
            tick.effort.append(current * joint.torque_constant if joint.effort_is == "motor_torque" else current)
        self.ticks += 1
        return tick


__all__ = ["JointStateMerger", "MergedTick"]
