"""The standard outputs carry a load only where the estimator trusts it, NaN from the first untrusted sample until
the estimate has settled, and a consumer that thresholds the effort (a collision detector) never fires on an
untrusted sample."""
from __future__ import annotations

import math

from worm_msgs.msg import TorqueEstimate

from worm_rig_driver.robot.standard_outputs import (FLAG_AMBIGUOUS, FLAG_INVALID_INPUT, FLAG_OUT_OF_CALIBRATION,
                                                    FLAG_STANDSTILL, FLAG_TRANSIENT, UNTRUSTED, StandardEffort)


def test_the_flags_are_torque_estimates() -> None:
    """(The estimators' EstimateFlags against these: torque_estimator's test_standard_outputs.)"""
    assert (FLAG_OUT_OF_CALIBRATION, FLAG_AMBIGUOUS, FLAG_INVALID_INPUT, FLAG_TRANSIENT, FLAG_STANDSTILL) == (
        TorqueEstimate.FLAG_OUT_OF_CALIBRATION, TorqueEstimate.FLAG_AMBIGUOUS, TorqueEstimate.FLAG_INVALID_INPUT,
        TorqueEstimate.FLAG_TRANSIENT, TorqueEstimate.FLAG_STANDSTILL)
    assert UNTRUSTED == FLAG_OUT_OF_CALIBRATION | FLAG_AMBIGUOUS | FLAG_INVALID_INPUT | FLAG_TRANSIENT | FLAG_STANDSTILL


def feed(effort: StandardEffort, stream: list[tuple[float, int]]) -> list[float]:
    """Every sample observed and published (what the standard outputs carry for each)."""
    out = []
    for tau, flags in stream:
        effort.observe(flags, tau)
        out.append(effort.effort(tau))
    return out


def test_untrusted_estimates_and_their_edges_go_out_as_nan() -> None:
    effort = StandardEffort(max_load=0.4, sample_period=1e-3, settle=0.003, start=0.005)
    out = feed(effort, [(0.1, 0)] * 8)
    assert [math.isnan(x) for x in out] == [True] * 5 + [False] * 3  # the start: 5 samples, then trusted
    assert out[-1] == -0.1
    for flags in (FLAG_TRANSIENT, FLAG_INVALID_INPUT, FLAG_OUT_OF_CALIBRATION, FLAG_AMBIGUOUS, FLAG_STANDSTILL):
        out = feed(effort, [(0.1, flags)] + [(0.1, 0)] * 4)
        assert [math.isnan(x) for x in out] == [True] * 4 + [False], flags  # NaN, then 3 samples settling
    out = feed(effort, [(0.5, 0)] + [(0.1, 0)] * 4)  # implausible: beyond max_load
    assert [math.isnan(x) for x in out] == [True] * 4 + [False]
    effort.restart()  # a new rig session
    assert all(math.isnan(x) for x in feed(effort, [(0.1, 0)] * 5))
    assert effort.carried + effort.withheld == 8 + 25 + 5 + 5


def test_a_sample_not_published_is_judged_too() -> None:
    effort = StandardEffort(max_load=0.4, sample_period=1e-3, settle=0.003, start=0.0)
    for flags in (0, 0, 0, 0, FLAG_TRANSIENT, 0):  # a flagged sample between two published ones
        effort.observe(flags, 0.1)
    assert math.isnan(effort.effort(0.1))


def test_a_thresholding_consumer_sees_no_load_that_was_not_trusted() -> None:
    """A collision detector fires when |effort| exceeds its limit. Fed a stream whose untrusted samples are
    spikes (a reversal read as a 6 N m load) with an unflagged but wrong sample at their edge, it fires on
    the true load step only."""
    limit = 0.25  # [N m]
    effort = StandardEffort(max_load=0.4, sample_period=1e-3, settle=0.01, start=0.0)
    stream = [(0.1, 0)] * 20 + [(6.0, FLAG_TRANSIENT), (-14.0, FLAG_TRANSIENT | FLAG_OUT_OF_CALIBRATION)] * 3 \
        + [(0.37, 0)] + [(0.1, 0)] * 30 + [(0.3, 0)] * 5  # an unflagged 0.37 at the edge; a real 0.3 N m load
    fired = [k for k, x in enumerate(feed(effort, stream)) if abs(x) > limit]
    assert fired == list(range(57, 62))
