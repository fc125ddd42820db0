"""A JointState becomes each configured joint's rig sample exactly, and what must not be estimated from is
refused and counted: absent joints, missing fields, NaN, repeated / out-of-order / early stamps."""
from __future__ import annotations

import math

import pytest

from worm_model.physics.parameters import load_rig
from worm_model.rig_data.joint_states import REFUSALS, JointConversion, JointStateReader

RIG = load_rig(None)
MS = 1_000_000  # [ns]


def reader(side: str = "motor", effort: str = "current", names=("a", "b")) -> JointStateReader:
    return JointStateReader([JointConversion.from_rig(n, RIG, side, effort) for n in names], 0.001)


def test_joints_are_found_by_name_in_any_order() -> None:
    r = reader()
    a, b = r.read(5 * MS, ["c", "b", "a"], [0.3, 0.2, 0.1], [30.0, 20.0, 10.0], [3.0, 2.0, 1.0],
                  voltage={"a": 12.0})
    assert (a.omega_worm, a.current_drive, a.theta_worm, a.voltage_drive) == (10.0, 1.0, 0.1, 12.0)
    assert (b.omega_worm, b.current_drive, b.theta_worm) == (20.0, 2.0, 0.2) and math.isnan(b.voltage_drive)
    assert a.stamp_ns == b.stamp_ns == 5 * MS and a.seq == b.seq == 0


def test_the_output_side_and_a_motor_torque_go_through_the_rig_file() -> None:
    ratio, k_t = RIG.gearbox.ratio, RIG.drive_motor.torque_constant
    (a,) = reader("output", "motor_torque", ("a",)).read(0, ["a"], [0.5], [2.5], [0.02])
    assert a.omega_worm == pytest.approx(2.5 / ratio, rel=1e-15)
    assert a.theta_worm == pytest.approx(0.5 / ratio, rel=1e-15)
    assert a.current_drive == pytest.approx(0.02 / k_t, rel=1e-15)
    assert RIG.gearbox.ratio < 1  # the worm turns faster than the joint


def test_a_missing_position_leaves_the_angle_unknown_only() -> None:
    (a,) = reader(names=("a",)).read(0, ["a"], [], [1.0], [0.5])
    assert a.theta_worm is None and a.omega_worm == 1.0
    (a,) = reader(names=("a",)).read(0, ["a"], [math.nan], [1.0], [0.5])
    assert a.theta_worm is None


def test_refusals_are_counted_per_joint_and_never_become_samples() -> None:
    r = reader()
    ok = [1.0, 1.0]
    assert r.read(0, ["a"], [0.0], [1.0], [1.0])[1] is None  # b absent; a's first sample
    a, b = r.read(1 * MS, ["a", "b"], [], [1.0], ok)  # velocity has a's entry only
    assert a is not None and b is None
    assert r.read(2 * MS, ["a", "b"], [], [math.nan, 1.0], [1.0, math.inf]) == [None, None]
    assert all(r.read(3 * MS, ["b", "a"], [], ok, ok))
    assert r.read(3 * MS, ["a", "b"], [], ok, ok) == [None, None]  # the same stamp again
    assert r.read(2 * MS, ["a", "b"], [], ok, ok) == [None, None]  # earlier
    assert r.read(3 * MS + 400_000, ["a", "b"], [], ok, ok) == [None, None]  # 0.4 ms later: not the next sample
    assert r.refused("a") == {"absent": 0, "missing_field": 0, "not_finite": 1, "repeated": 1, "out_of_order": 1,
                              "early": 1}
    assert r.refused("b") == {"absent": 1, "missing_field": 1, "not_finite": 1, "repeated": 1, "out_of_order": 1,
                              "early": 1}
    assert r.samples("a") == 3 and r.samples("b") == 1
    assert r.read(4 * MS, ["a"], [0.0, 1.0], [1.0], [1.0]) == [None, None]  # an array longer than the names
    assert r.malformed_messages == 1 and r.refused_total() == 1 + 4 + 6
    assert set(REFUSALS) == set(r.refused("a"))
    a, b = r.read(5 * MS, ["a", "b"], [], ok, ok)
    assert (a.seq, b.seq) == (5, 2)  # each joint counts from its own first sample (a: 0 ms, b: 3 ms)


def test_seqs_follow_the_stamps_across_gaps_and_jitter() -> None:
    r = reader(names=("a",))
    stamps = [0, 1 * MS + 200_000, 2 * MS - 100_000, 5 * MS, 6 * MS]  # jitter, then 2 messages lost
    seqs = [r.read(s, ["a"], [], [1.0], [1.0])[0].seq for s in stamps]
    assert seqs == [0, 1, 2, 5, 6]


def test_bad_conversions_are_refused_with_the_joint_named() -> None:
    with pytest.raises(ValueError, match="joint j: joint_side 'worm'"):
        JointConversion("j", 0.1, 0.02, "worm")
    with pytest.raises(ValueError, match="joint names repeat"):
        reader(names=("a", "a"))
