"""The check's reference run: under 30 s, both directions, every load at every speed, ends stopped."""
from __future__ import annotations

import pytest

from worm_model.physics.parameters import load_rig
from torque_estimator.health.reference import LOADS, MAX_DURATION, SPEEDS, reference_run, total_duration

RIG = load_rig()


def test_the_default_run_fits_in_the_rig_time_allowed() -> None:
    timeline = reference_run(RIG)
    assert total_duration(timeline) == pytest.approx(28.5) and total_duration(timeline) <= MAX_DURATION
    held = [s for s in timeline if s.speed_start == s.speed_end and s.load_start == s.load_end and s.speed_start]
    pairs = {(s.speed_start, round(s.load_start / RIG.max_load_torque, 6)) for s in held}
    assert pairs == {(d * w, f) for d in (1.0, -1.0) for w in SPEEDS for f in LOADS}
    assert timeline[-1].speed_end == 0.0 and timeline[-1].load_end == 0.0
    # no load step larger than one level: the loads snake up at one speed and down at the next
    loads = [s.load_start for s in timeline]
    steps = [abs(b - a) for a, b in zip(loads, loads[1:]) if a and b]
    assert max(steps) <= 0.6 * RIG.max_load_torque + 1e-12
    # the change of direction is unloaded
    reversal = next(s for s in timeline if s.speed_start > 0 > s.speed_end)
    assert reversal.load_start == reversal.load_end == 0.0


def test_a_robot_without_load_motors_runs_it_unloaded() -> None:
    timeline = reference_run(RIG, loads=(0.0,))
    assert {s.load_start for s in timeline} == {0.0}
    with pytest.raises(ValueError):
        reference_run(RIG, loads=(1.5,))
    with pytest.raises(ValueError):
        reference_run(RIG, speeds=(0.0,))
