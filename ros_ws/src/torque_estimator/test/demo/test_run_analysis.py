"""The demo's live estimation figures: trusted estimates scored, flagged ones counted apart."""
from __future__ import annotations

import math

import numpy as np

from torque_estimator.demo.run_analysis import analyse_run
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
