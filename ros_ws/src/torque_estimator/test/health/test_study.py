"""How well the health monitor does, on simulated gearboxes whose truth is known (health.study).

The fast tests run a few lives (the machinery: the batch of checks, the fits, the assessments in order, the
live monitor on a lubricant loss); the slow one runs `make evaluate`'s whole study and pins the figures
docs/health.md states.
"""
from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np
import pytest

from worm_model.health.bound import detection_probability
from worm_model.physics.parameters import load_rig
from torque_estimator.health.study import (LUBRICANT_AT, GEARBOX_EFFECTS, draw_lives, live_lines, live_reference,
                                           live_run, live_scenarios, operation, run_lives, run_study, _with)

RIG = load_rig()


def test_a_few_lives_measured_and_estimated() -> None:
    result = run_study(RIG, gearboxes=2, baseline=5, healthy=3, detect_gearboxes=2, before=1, after={0.15: 1},
                       seed=11)
    assert result.false_alarms == {"measured": (0, 6), "estimated": (0, 6)}
    assert result.detected[(0.15, "measured")] == [1, 1]
    assert 0.01 < result.sigma["measured"] < result.sigma["estimated"] < 0.08
    lines = result.lines()
    assert lines[0].startswith("health: change=mu+15% detected_in_checks=1 ") and lines[0].endswith("measured")
    assert any(line.startswith("health: false_alarms=0 of 6 temperature=estimated") for line in lines)
    # a 15 % rise, the checks in the temperatures seen: any monitor finds it at the first check, almost surely
    assert all(0.01 < s < result.sigma["measured"] * 1.5 for s in result.bound[(0.15, "measured")]), result.bound
    assert any(line.startswith("health: change=mu+15% in_first_check=2 of 2 bound=2.0 worst_bound_sigma_pct=")
               and line.endswith("temperature=measured") for line in lines), lines


def test_each_check_runs_at_its_own_oil_temperature_and_load() -> None:
    lives = draw_lives(1, 4, seed=12)
    run_lives(RIG, lives, seed=12)
    life = lives[0]
    measured = [r.temperature for r in life.records["measured"]]
    # the run's mean oil temperature: where it started, drifting < 1 K over the 28.5 s run, plus the sensor's error
    np.testing.assert_allclose([t.value for t in measured], life.temperature, atol=2.5)
    assert all(t.source == "measured" for t in measured)
    assert all(r.temperature.source == "estimated" for r in life.records["estimated"])
    spans = [r.loads[1] - r.loads[0] for r in life.records["measured"]]
    gain = 1.0 + GEARBOX_EFFECTS["sensor_gain"].get("load_current", 0.02)  # (the load sensors read 2 % high)
    np.testing.assert_allclose(spans, 1.8 * RIG.max_load_torque * life.load_scale * gain, rtol=0.005)


def test_the_live_monitor_warns_of_a_lubricant_loss_within_2_s() -> None:
    reference = live_reference(RIG, 13, __import__("worm_model.health.settings", fromlist=["x"]).HealthSettings())
    effects = _with(GEARBOX_EFFECTS, oil_temperature={"initial": 40.0},
                    lubricant_loss={"rise": 0.3, "at": LUBRICANT_AT})
    traces = live_run(RIG, reference, operation(RIG, LUBRICANT_AT + 10.0), effects=effects, seed=13)
    for mode, trace in traces.items():
        assert math.isnan(trace.first("WARN")) or trace.first("WARN") > LUBRICANT_AT, mode
        assert trace.first("WARN", LUBRICANT_AT) - LUBRICANT_AT <= 2.0, mode


@pytest.mark.slow
def test_the_study_meets_the_figures_docs_health_states() -> None:
    """make evaluate's health lines (seed 0): the tables of docs/health.md (~10 min)."""
    result = run_study(RIG, seed=0)

    def within(found, checks):
        return sum(1 for n in found if n is not None and n <= checks)

    measured, estimated = result.detected[(0.10, "measured")], result.detected[(0.10, "estimated")]
    assert np.median([n or 99 for n in measured]) == 1 and None not in measured and max(measured) <= 3
    assert np.median([n or 99 for n in estimated]) <= 2 and within(estimated, 3) >= 15
    small, small_estimated = result.detected[(0.05, "measured")], result.detected[(0.05, "estimated")]
    assert np.median([n or 99 for n in small]) <= 4 and within(small, 8) >= 19
    assert np.median([n or 99 for n in small_estimated]) <= 6.5 and within(small_estimated, 8) >= 13
    assert result.false_alarms == {"measured": (0, 1000), "estimated": (0, 1000)}
    # one check's bound (worm_model.health.bound): found by the first check after the change, against the most any
    # monitor could expect at the same bar; the worst gearbox's sigma_B puts a 10 % rise below 3.1 sigma
    for mode, first, bound, worst in (("measured", 17, 17.3, 0.0320), ("estimated", 7, 8.9, 0.0605)):
        found, sigmas = result.detected[(0.10, mode)], result.bound[(0.10, mode)]
        assert sum(n == 1 for n in found) == first, (mode, found)
        assert sum(detection_probability(0.10, s, result.limits) for s in sigmas) == pytest.approx(bound, abs=0.05)
        assert max(sigmas) == pytest.approx(worst, abs=0.0005)
        assert 0.10 / max(sigmas) < 3.13, mode
    assert 1000 * (1 - NormalDist().cdf(3.1)) == pytest.approx(0.97, abs=0.005)  # false alarms per 1000 at 3.1 sigma
    # that gearbox (the lives of the 10 % rise: seed 1, the change after 9 healthy checks): 53 degC, 12 K warmer
    # than any check before it (27-41 degC)
    oil = draw_lives(20, 12, 1)[int(np.argmax(result.bound[(0.10, "measured")]))].temperature
    check, earlier = oil[9], oil[:9]
    assert (round(check), round(check - earlier.max()), round(earlier.min()), round(earlier.max())) == (53, 12, 27, 41)
    assert result.sigma["measured"] == pytest.approx(0.0187, abs=0.001)
    assert result.sigma["estimated"] == pytest.approx(0.0260, abs=0.001)
    traces = live_scenarios(RIG, 0)
    lines = live_lines(traces)
    for mode, after in (("measured", 0.90), ("estimated", 1.05)):
        lub = traces["lubricant"][mode]
        assert lub.first("WARN", LUBRICANT_AT) - LUBRICANT_AT == pytest.approx(after, abs=0.06), lines
        assert not lub.first("WARN") < LUBRICANT_AT
        cold = traces["cold"][mode]
        assert all(level == "OK" for level in cold.level), lines
        assert cold.true_temperature[0] == pytest.approx(15.0, abs=0.01)
        assert cold.true_temperature[-1] == pytest.approx(45.0, abs=1.0)
