"""The excitation: at most 90 s of rig time, both directions, the whole speed and load range, steps, ramps,
reversals."""
from __future__ import annotations

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig

from torque_estimator.identification.excitation import (MAX_DURATION, default_excitation, sampled, setpoints,
                                                        total_duration)
from torque_estimator.session.recording import ExcitationRun, Journal, run_settings

RIG = load_rig()


def test_default_excitation_covers_the_range_within_90_s() -> None:
    timeline = default_excitation(RIG)
    assert total_duration(timeline) <= MAX_DURATION
    _index, speed, load = sampled(timeline, 1e-3)
    assert speed.max() >= 340 and speed.min() <= -340  # both directions, the grid's top speed
    assert np.any((np.abs(speed) > 15) & (np.abs(speed) <= 25))  # and its lowest
    top = 0.9 * RIG.max_load_torque
    assert load.max() == pytest.approx(top) and load.min() == pytest.approx(-top)  # both signs: all three modes
    for level in (20, 60, 110, 170, 230, 290, 340):  # load swept across the range at every speed level, both ways
        for sign in (1, -1):
            at = np.abs(speed - sign * level) < 1e-9
            assert load[at].max() > 0.8 * top and load[at].min() < -0.8 * top, (sign, level)
    jumps = np.abs(np.diff(speed))
    assert np.sum(jumps > 20) >= 5, "speed steps"
    assert any(s.speed_start * s.speed_end < 0 for s in timeline), "a reversal within a segment"
    assert setpoints(timeline, total_duration(timeline) + 1) is None
    assert timeline[-1].speed_end == 0 and timeline[-1].load_end == 0  # ends stopped


def test_scaled_and_checked() -> None:
    assert total_duration(default_excitation(RIG, 12.0)) == pytest.approx(12.0)
    with pytest.raises(ValueError):
        default_excitation(RIG, 0.0)


def test_run_counts_the_timeline_on_the_sample_clock() -> None:
    timeline = default_excitation(RIG, 3.0)
    run = ExcitationRun(timeline, Journal(run_settings(timeline, {}, "test")), 1e-3)
    index, speed, load = sampled(timeline, 1e-3)
    assert run.total_samples == len(speed)
    k = 0
    while (target := run.setpoints()) is not None:
        assert target == pytest.approx((speed[k], load[k]))
        run.add({"current_drive": 0.1, "omega_worm": target[0], "theta_worm": 0.0, "tau_load": target[1]})
        k += 1
    assert k == len(speed) and run.finished
    data = run.journal.data("test")
    assert len(data) == k and np.all(np.diff(data.t) > 0)
