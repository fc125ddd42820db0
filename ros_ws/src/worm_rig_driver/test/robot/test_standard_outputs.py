"""The standard outputs carry a load only where the estimator trusts it, NaN at once otherwise, and a consumer
that thresholds the effort (a collision detector) never fires on an untrusted sample."""
from __future__ import annotations

import math

from worm_msgs.msg import TorqueEstimate

from worm_rig_driver.robot.standard_outputs import (FLAG_AMBIGUOUS, FLAG_INVALID_INPUT, FLAG_OUT_OF_CALIBRATION,
                                                    FLAG_TRANSIENT, UNTRUSTED, StandardEffort)


def test_the_flags_are_torque_estimates_and_the_estimators() -> None:
    from torque_estimator.estimation.base import EstimateFlags
    assert (FLAG_OUT_OF_CALIBRATION, FLAG_AMBIGUOUS, FLAG_INVALID_INPUT, FLAG_TRANSIENT) == (
        TorqueEstimate.FLAG_OUT_OF_CALIBRATION, TorqueEstimate.FLAG_AMBIGUOUS, TorqueEstimate.FLAG_INVALID_INPUT,
        TorqueEstimate.FLAG_TRANSIENT)
    assert UNTRUSTED == EstimateFlags.OUT_OF_CALIBRATION | EstimateFlags.INVALID_INPUT | EstimateFlags.TRANSIENT


def test_untrusted_estimates_go_out_as_nan_at_once_and_trusted_ones_as_minus_tau() -> None:
    effort = StandardEffort(max_load=0.4)
    assert effort.effort(0.1, 0) == -0.1
    assert effort.effort(0.1, FLAG_AMBIGUOUS) == -0.1  # the estimator's best value, its branch
    for flags in (FLAG_TRANSIENT, FLAG_INVALID_INPUT, FLAG_OUT_OF_CALIBRATION, FLAG_TRANSIENT | FLAG_AMBIGUOUS):
        assert math.isnan(effort.effort(0.1, flags))
    assert math.isnan(effort.effort(0.5, 0))  # implausible: beyond max_load
    assert math.isnan(effort.effort(math.nan, 0))
    assert effort.effort(-0.2, 0) == 0.2  # the next trusted sample at once
    assert (effort.carried, effort.withheld) == (3, 6)


def test_a_thresholding_consumer_sees_no_load_that_was_not_trusted() -> None:
    """A collision detector fires when |effort| exceeds its limit. Fed a stream whose untrusted samples are
    spikes (a reversal read as a 6 N m load), it fires on the true load step only."""
    limit = 0.25  # [N m]
    effort = StandardEffort(max_load=0.4)
    stream = [(0.1, 0)] * 10 + [(6.0, FLAG_TRANSIENT), (-14.0, FLAG_TRANSIENT | FLAG_OUT_OF_CALIBRATION)] * 3 \
        + [(0.1, 0)] * 10 + [(0.3, 0)] * 5  # a real 0.3 N m load at the end
    fired = [k for k, (tau, flags) in enumerate(stream) if abs(effort.effort(tau, flags)) > limit]
    assert fired == list(range(26, 31))
