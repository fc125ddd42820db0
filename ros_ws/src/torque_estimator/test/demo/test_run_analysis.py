"""The demo's live figures: trusted estimates scored, flagged ones counted apart; the set-point the rig held and
the load steps' IAE read from the record's own sample counts, not its stamps."""
from __future__ import annotations

import math

import numpy as np

from torque_estimator.demo.run_analysis import analyse_run, recorded_load_steps, setpoints_in_force
from torque_estimator.evaluation.scenario import Segment
from worm_rig_driver.robot.standard_outputs import FLAG_AMBIGUOUS, FLAG_TRANSIENT

SCENARIO = (Segment(2.0, 150.0, 0.1, "a"), Segment(2.0, 150.0, 0.2, "b"))
RANGE = 0.5  # [N m]


T = np.arange(0.0, 4.0, 0.01)  # [s] a 100 Hz estimate
TRUTH = np.where(T < 2.0, 0.1, 0.2)  # [N m]
SPIKE = int(np.searchsorted(T, 3.0))  # in segment b's steady part


def run(flags: np.ndarray | None):
    """The estimate 0.005 N m above the truth, but -1.3 N m (1.5 N m off) at SPIKE."""
    estimate = TRUTH + 0.005
    estimate[SPIKE] = -1.3
    speed = np.full_like(T, 150.0)
    return analyse_run(SCENARIO, T, speed, speed, T, estimate, T, TRUTH, np.ones_like(T), RANGE, flags=flags)


def test_a_flagged_spike_is_counted_not_scored() -> None:
    flags = np.zeros(len(T), int)
    flags[SPIKE] = FLAG_TRANSIENT
    flags[10] = FLAG_AMBIGUOUS  # trusted (the standard outputs carry it too)
    m = run(flags)
    assert math.isclose(m.estimate_mae_pct, 1.0) and math.isclose(m.estimate_max_pct, 1.0)
    # steady parts: 0.8-2 s and 2.8-4 s at 100 Hz
    assert m.steady_estimates == 240 and m.steady_flagged == 1
    assert math.isclose(m.flagged_max_pct, 100 * 1.5 / RANGE)


def test_without_flags_every_estimate_is_scored() -> None:
    m = run(None)
    assert m.steady_flagged == 0 and math.isnan(m.flagged_max_pct)
    # segment b's steady part holds 120 estimates, one of them the spike (1.5 N m off)
    assert math.isclose(m.estimate_max_pct, 100 * (119 * 0.005 + 1.5) / 120 / RANGE)


def test_the_set_point_counts_from_the_sample_the_rig_took_it_not_from_its_stamp() -> None:
    # a 1 kHz rig; the reversal is computed from sample 100 and stamped at 0.101 s, but the busy graph delivers
    # it late: the rig takes it at sample 160. Sample 40 names command 25, which the record lacks.
    t = np.arange(300) * 1e-3
    named = np.where(t < 0.005, 0, np.where(t < 0.160, 1, 100)).astype(float)
    named[40] = 25
    held = setpoints_in_force(t, named, [0.002, 0.101], [150.0, -150.0], [1, 100])
    assert np.all(held[5:160] == 150.0) and np.all(held[160:] == -150.0)
    assert held[0] == 150.0 and held[40] == 150.0  # none named / not recorded: the one stamped last before
    # by the stamps alone, 59 samples of the old speed would count as a 300 rad/s error
    by_stamp = setpoints_in_force(t, np.zeros(300), [0.002, 0.101], [150.0, -150.0], [1, 100])
    assert np.sum(by_stamp != held) == 59


def test_a_gap_in_the_record_adds_nothing_to_a_load_step() -> None:
    t = np.arange(4000) * 1e-3  # [s] 1 kHz
    load = np.where(t < 1.0, 0.0, 0.2)
    error = np.where(t >= 1.0, 2.0 * np.exp(-(t - 1.0) / 0.05), 0.0)  # [rad/s] the dip after the step
    setpoint = np.full_like(t, 150.0)
    (whole,) = recorded_load_steps(t, load, t, setpoint - error, setpoint)
    assert math.isclose(whole.iae, 0.1, rel_tol=0.02)  # 2 rad/s x 0.05 s
    kept = (t < 1.01) | (t >= 1.5)  # 490 ms of samples not recorded, the first one 1.2 rad/s off
    (gapped,) = recorded_load_steps(t[kept], load[kept], t[kept], (setpoint - error)[kept], setpoint[kept])
    assert gapped.peak_dip == whole.peak_dip and gapped.iae <= whole.iae
