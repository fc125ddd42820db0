"""The demo's live estimation figures: trusted estimates scored, flagged ones counted apart."""
from __future__ import annotations

import math

import numpy as np

from torque_estimator.demo.run_analysis import analyse_run
from torque_estimator.evaluation.scenario import Segment
from worm_rig_driver.robot.standard_outputs import FLAG_AMBIGUOUS, FLAG_TRANSIENT

SCENARIO = (Segment(2.0, 150.0, 0.1, "a"), Segment(2.0, 150.0, 0.2, "b"))
RANGE = 0.5  # [N m]


def run(flags: np.ndarray | None):
    """A 100 Hz estimate 0.005 N m above the truth, with one 1.5 N m spike in segment b's steady part."""
    t = np.arange(0.0, 4.0, 0.01)
    truth = np.where(t < 2.0, 0.1, 0.2)
    estimate = truth + 0.005
    spike = int(np.searchsorted(t, 3.0))
    estimate[spike] = -1.3
    return analyse_run(SCENARIO, t, np.full_like(t, 150.0), np.full_like(t, 150.0), t, estimate, t, truth,
                       np.ones_like(t), RANGE, flags=flags), spike, len(t)


def test_a_flagged_spike_is_counted_not_scored() -> None:
    flags = np.zeros(400, int)
    _, spike, _ = run(None)
    flags[spike] = FLAG_TRANSIENT
    flags[10] = FLAG_AMBIGUOUS  # trusted (the standard outputs carry it too)
    m, _, _ = run(flags)
    assert math.isclose(m.estimate_mae_pct, 1.0) and math.isclose(m.estimate_max_pct, 1.0)
    # steady parts: 0.8-2 s and 2.8-4 s at 100 Hz
    assert m.steady_estimates == 240 and m.steady_flagged == 1
    assert math.isclose(m.flagged_max_pct, 100 * 1.5 / RANGE)


def test_without_flags_every_estimate_is_scored() -> None:
    m, _, _ = run(None)
    assert m.steady_flagged == 0 and math.isnan(m.flagged_max_pct)
    # segment b's steady part holds 120 estimates, one of them the spike (1.5 N m off)
    assert math.isclose(m.estimate_max_pct, 100 * (119 * 0.005 + 1.5) / 120 / RANGE)
