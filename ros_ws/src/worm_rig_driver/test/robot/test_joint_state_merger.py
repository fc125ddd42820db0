"""Rigs on their own clocks become one JointState per tick: each joint's newest sample at the tick, a stalled
rig left out after max_wait, and the reader of worm_model gets every rig's samples back exactly."""
from __future__ import annotations

import pytest

from worm_model.physics.parameters import load_rig
from worm_model.rig_data.joint_states import JointConversion, JointStateReader

from worm_rig_driver.robot.joint_states import JointStateMerger

MS = 1_000_000
RIG = load_rig(None)
I15 = load_rig("package://worm_model/data/nmrv030_i15_rig.yaml")


def joints(side: str = "output", effort: str = "current") -> list[JointConversion]:
    return [JointConversion.from_rig("a", RIG, side, effort), JointConversion.from_rig("b", I15, side, effort)]


def samples(offset_ns: int, first: int, count: int, scale: float) -> list[tuple[int, float, float, float]]:
    """Samples k = first..first+count-1: stamp offset + k ms, θ = k·scale, ω = 10·k·scale, i = k·scale/100."""
    return [(offset_ns + k * MS, k * scale, 10 * k * scale, k * scale / 100) for k in range(first, first + count)]


def test_ticks_carry_each_joints_newest_sample_and_read_back_exactly() -> None:
    merger = JointStateMerger(joints(), 0.001)
    merger.add(0, samples(300_000, 0, 5, 1.0))  # rig a's clock 0.3 ms after the grid
    assert merger.ready() == []  # b has sent nothing
    merger.add(1, samples(700_000, 0, 5, 2.0))
    ticks = merger.ready()
    # first tick: the grid point after both first samples (0.7 ms) -> 1 ms; ready up to b's newest - 1 ns
    assert [t.stamp_ns for t in ticks] == [1 * MS, 2 * MS, 3 * MS, 4 * MS]
    first = ticks[0]
    assert first.names == ["a", "b"]
    # at 1 ms: a's sample 0.3 ms (k=1 at 1.3 ms is later), b's 0.7 ms (k=0)
    assert first.velocity == pytest.approx([10 * 0 * RIG.gearbox.ratio, 0.0])
    assert ticks[2].velocity == pytest.approx([10 * 2 * RIG.gearbox.ratio, 10 * 2 * 2.0 * I15.gearbox.ratio])
    reader = JointStateReader(joints(), 0.001)
    back = [reader.read(t.stamp_ns, t.names, t.position, t.velocity, t.effort) for t in ticks]
    assert [s.omega_worm for s, _ in back] == pytest.approx([0.0, 10.0, 20.0, 30.0], rel=1e-12)
    assert [s.current_drive for _, s in back] == pytest.approx([0.0, 0.02, 0.04, 0.06], rel=1e-12)
    assert [s.seq for s, _ in back] == [0, 1, 2, 3]


def test_a_stalled_rig_is_left_out_after_max_wait() -> None:
    merger = JointStateMerger(joints(), 0.001, max_wait=0.01)
    merger.add(0, samples(0, 0, 5, 1.0))
    merger.add(1, samples(0, 0, 5, 1.0))
    assert len(merger.ready()) == 4  # 0..3 ms (b's newest is 4 ms)
    merger.add(0, samples(0, 5, 30, 1.0))  # a runs on to 34 ms, b stops at 4 ms
    ticks = merger.ready()
    assert [t.stamp_ns for t in ticks] == [k * MS for k in range(4, 25)]  # up to a's newest - max_wait
    assert ticks[0].names == ["a", "b"] and all(t.names == ["a"] for t in ticks[1:])
    assert merger.absent == [0, 20]


def test_motor_side_and_motor_torque() -> None:
    merger = JointStateMerger(joints("motor", "motor_torque"), 0.001)
    merger.add(0, [(0, 1.0, 100.0, 2.0), (MS, 1.1, 100.0, 2.0)])
    merger.add(1, [(0, 3.0, 50.0, 1.0), (MS, 3.1, 50.0, 1.0)])
    (tick,) = merger.ready()
    assert tick.position == [1.0, 3.0] and tick.velocity == [100.0, 50.0]
    assert tick.effort == pytest.approx([2.0 * RIG.drive_motor.torque_constant, 1.0 * I15.drive_motor.torque_constant])
