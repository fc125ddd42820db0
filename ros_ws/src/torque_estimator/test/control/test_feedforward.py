"""Which estimate controller_node may feed forward (FeedforwardGate)."""
from __future__ import annotations

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
