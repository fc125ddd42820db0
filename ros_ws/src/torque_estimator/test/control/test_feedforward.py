"""Which estimate controller_node may feed forward (FeedforwardGate)."""
from __future__ import annotations

import pytest

from torque_estimator.control.feedforward import FeedforwardGate
from torque_estimator.estimation.base import EstimateFlags


def test_feedforward_gate_uses_only_fresh_usable_estimates() -> None:
    gate = FeedforwardGate(timeout=0.05)
    assert gate.load(10.0) is None  # nothing offered yet
    gate.offer(0.12, 0, stamp=10.0)
    assert gate.load(10.001) == 0.12
    assert gate.load(10.049) == 0.12 and gate.load(10.051) is None  # stale beyond the timeout
    for flag in (EstimateFlags.AMBIGUOUS, EstimateFlags.TRANSIENT):
        gate.offer(0.1, int(flag), stamp=11.0)
        assert gate.load(11.0) == 0.1, flag.name  # still the best guess
    for flag in (EstimateFlags.INVALID_INPUT, EstimateFlags.OUT_OF_CALIBRATION):
        gate.offer(0.1, int(flag | EstimateFlags.AMBIGUOUS), stamp=12.0)
        assert gate.load(12.0) is None, flag.name
    gate.offer(float("nan"), 0, stamp=13.0)
    assert gate.load(13.0) is None
    gate.offer(-0.2, 0, stamp=14.0)
    gate.enabled = False
    assert gate.load(14.0) is None
    gate.enabled = True
    assert gate.load(14.0) == -0.2


def test_feedforward_gate_refuses_implausible_loads() -> None:
    gate = FeedforwardGate(timeout=0.05, max_load=0.4)
    gate.offer(0.39, 0, stamp=1.0)
    assert gate.load(1.0) == 0.39
    gate.offer(-0.41, int(EstimateFlags.TRANSIENT), stamp=2.0)
    assert gate.load(2.0) is None


def test_feedforward_gate_ages_a_late_estimate_by_its_lateness() -> None:
    """The rig's clock 60 ms behind the controller's (a simulated rig behind real time): estimates that
    arrive with the stream's usual lag are fresh; one 80 ms later than usual is stale at once; with
    none coming the held one ages on the controller's clock; one held 3 s in a queue (a link down) is
    stale; a rig that catches up resets the lag at once, one that falls behind is followed at 50 ms/s."""
    gate = FeedforwardGate(timeout=0.05)
    for k in range(100):  # every 5 ms, lag 60 ms (+ 1 ms of transit every other one)
        stamp = 10.0 + 0.005 * k
        gate.offer(0.2, 0, stamp, arrival=stamp + 0.060 + 0.001 * (k % 2))
        assert gate.load(stamp + 0.061) == 0.2
    assert gate.clock_lag == pytest.approx(0.060, abs=5e-4)  # + up to 50 ms/s x 5 ms of creep
    gate.offer(0.3, 0, 10.5, arrival=10.640)  # 80 ms later than the stream's best
    assert gate.age(10.640) > 0.075 and gate.load(10.640) is None
    gate.offer(0.3, 0, 10.6, arrival=10.661)
    assert gate.load(10.661 + 0.049) == 0.3 and gate.load(10.661 + 0.052) is None  # the estimator went quiet
    gate.offer(0.3, 0, 10.62, arrival=13.661)  # held in a queue for 3 s
    assert gate.load(13.661) is None
    gate.offer(0.3, 0, 13.7, arrival=13.701)  # the rig caught up: the lag is 1 ms at once
    assert gate.clock_lag == pytest.approx(0.001) and gate.load(13.701 + 0.049) == 0.3
    for k in range(1, 500):  # the rig falls 100 ms behind at once: stale until the lag has followed
        stamp = 13.7 + 0.005 * k
        gate.offer(0.3, 0, stamp, arrival=stamp + 0.1)
        if k == 100:
            assert gate.load(stamp + 0.1) is None
            assert gate.clock_lag == pytest.approx(0.001 + 0.05 * (stamp + 0.1 - 13.701), abs=1e-3)
    assert gate.clock_lag == pytest.approx(0.1) and gate.load(stamp + 0.1) == 0.3


def test_feedforward_gate_without_arrivals_judges_on_one_clock() -> None:
    gate = FeedforwardGate(timeout=0.05)
    gate.offer(0.2, 0, 1.0)
    assert gate.clock_lag == 0.0 and gate.load(1.0499) == 0.2 and gate.load(1.0501) is None
