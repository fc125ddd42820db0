"""The README's deterministic figures, recomputed: feedforward (controller_bench), the estimators' transients
(make evaluate), the observer's noise against its bound and the step-size bound.

Every run here is seeded, so the figures are exact up to round-off: the tolerances are the README's
printed precision. (The live figures, the demo's, are pinned by tests/test_demo.py; the benchmark's
CPU and latency are measurements, printed by `make bench`, not asserted.)
"""
from __future__ import annotations

import numpy as np
import pytest

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.control.rig_feedforward import feedforward_estimator
from torque_estimator.estimation.observer import jump_bound, steady_state_bound
from torque_estimator.estimation.registry import make_estimator
from torque_estimator.evaluation.closed_loop import run_scenario
from torque_estimator.demo.run_analysis import load_step_responses
from torque_estimator.evaluation.scenario import DEMO_SCENARIO
from torque_estimator.evaluation.transient import STEP_SPEED, transient_figures
from worm_model.physics.parameters import load_rig

RIG = load_rig()


@pytest.fixture(scope="module")
def database():
    """The paper's grid calibrated as make evaluate and controller_bench do (seed 0)."""
    return calibrate_simulated(RIG, CalibrationGrid.paper(RIG), seed=0)


def worst(runs) -> dict[str, tuple[float, float]]:
    """mode -> (worst dip [rad/s], summed IAE [rad]) over the demo's load steps."""
    out = {}
    for mode, run in runs.items():
        steps = load_step_responses(DEMO_SCENARIO, run.t, run.omega_true, run.setpoint)
        out[mode] = (max(s.peak_dip for s in steps), sum(s.iae for s in steps))
    return out


SEEDS = (1, 2, 3, 4)  # controller_bench's default runs (--seed 0 --seeds 4)
TIMINGS = {"firmware": {}, "graph": {"ff_batch": 5, "ff_latency": 1}}  # graph: each seed at the 5 batch positions


@pytest.fixture(scope="module")
def feedforward(database) -> dict:
    """(estimator, timing) -> mode -> per seed (worst dip, summed IAE), as controller_bench runs them."""
    out = {}
    for name, estimator in (("observer", make_estimator("observer", database)), ("knn", make_estimator("knn", database))):
        for timing, options in TIMINGS.items():
            phases = range(options.get("ff_batch", 1))
            per_seed = [worst(run_scenario(RIG, DEMO_SCENARIO, ("off", "estimate", "truth"), estimator=estimator,
                                           seed=seed, ff_phase=phase, **options)) for seed in SEEDS for phase in phases]
            out[name, timing] = {mode: np.array([s[mode] for s in per_seed]) for mode in per_seed[0]}
    return out


@pytest.mark.parametrize("timing, expected", [
    ("firmware", {"off": (4.93, 2.31), "estimate": (3.32, 0.76), "truth": (1.61, 0.68)}),
    ("graph", {"off": (4.93, 2.31), "estimate": (3.91, 0.805), "truth": (2.64, 0.715)}),
])
def test_feedforward_table(feedforward, timing: str, expected: dict) -> None:
    """README, Feedforward: off -> observer -> ideal, means of controller_bench's 4 runs (graph: 4 x 5 batch
    positions); the graph's within 1.5 x the ideal (issue 14)."""
    got = feedforward["observer", timing]
    for mode, (dip, iae) in expected.items():
        assert got[mode][:, 0].mean() == pytest.approx(dip, abs=0.005), (timing, mode, got[mode])
        assert got[mode][:, 1].mean() == pytest.approx(iae, abs=0.005), (timing, mode, got[mode])
    if timing == "firmware":  # README: the observer's runs 3.06-3.63 rad/s; its IAE 1.12 x the ideal
        assert got["estimate"][:, 0].min() == pytest.approx(3.06, abs=0.005)
        assert got["estimate"][:, 0].max() == pytest.approx(3.63, abs=0.005)
        assert got["estimate"][:, 1].mean() <= 1.3 * got["truth"][:, 1].mean()  # issue 14's 1.3 x: met
    else:  # README: runs 3.11-4.59; issue 14's 1.5 x at the graph's timing, dip (1.48 x) and IAE
        assert got["estimate"][:, 0].min() == pytest.approx(3.11, abs=0.005)
        assert got["estimate"][:, 0].max() == pytest.approx(4.59, abs=0.005)
        assert got["estimate"][:, 0].mean() <= 1.5 * got["truth"][:, 0].mean()
        assert got["estimate"][:, 1].mean() <= 1.5 * got["truth"][:, 1].mean()


def test_the_feedforward_at_the_rig(database) -> None:
    """README, Feedforward: the shipped graph's timing (the observer beside the rig's PI, its step detector at
    1e-3: control.rig_feedforward), controller_bench's rig table: off -> on -> ideal, and issue 14's 40 %: the
    feedforward takes >= 40 % off the worst dip and the IAE."""
    estimator = feedforward_estimator("observer", database, RIG)
    per_seed = [worst(run_scenario(RIG, DEMO_SCENARIO, ("off", "estimate", "truth"), estimator=estimator, seed=seed,
                                   ff_batch=1, ff_latency=0)) for seed in SEEDS]
    got = {mode: np.array([s[mode] for s in per_seed]) for mode in per_seed[0]}
    for mode, (dip, iae) in {"off": (4.93, 2.314), "estimate": (2.83, 0.741), "truth": (0.92, 0.669)}.items():
        assert got[mode][:, 0].mean() == pytest.approx(dip, abs=0.005), (mode, got[mode])
        assert got[mode][:, 1].mean() == pytest.approx(iae, abs=0.0005), (mode, got[mode])
    assert got["estimate"][:, 0].min() == pytest.approx(2.51, abs=0.005)
    assert got["estimate"][:, 0].max() == pytest.approx(3.13, abs=0.005)
    assert got["estimate"][:, 0].mean() <= 0.6 * got["off"][:, 0].mean()  # -42.6 %
    assert got["estimate"][:, 1].mean() <= 0.6 * got["off"][:, 1].mean()  # -68 %


@pytest.mark.xfail(strict=True, reason="the dip needs the load known within ~1 ms of the step; the step-size "
                                       "bound gives 1 sigma = 32 % of a 0.2 N m step after 2 samples")
def test_the_dip_within_1_3_times_the_ideal(feedforward) -> None:
    """Issue 14's dip target with the firmware's timing (the README says why it is out of reach)."""
    got = feedforward["observer", "firmware"]
    assert got["estimate"][:, 0].mean() <= 1.3 * got["truth"][:, 0].mean()


@pytest.mark.parametrize("timing, dip, iae", [("firmware", 4.02, 0.92), ("graph", 4.46, 0.96)])
def test_the_knn_feedforward(feedforward, timing: str, dip: float, iae: float) -> None:
    """README, Feedforward: the k-NN's figures in both timings (controller_bench --method knn)."""
    got = feedforward["knn", timing]["estimate"]
    assert got[:, 0].mean() == pytest.approx(dip, abs=0.005) and got[:, 1].mean() == pytest.approx(iae, abs=0.005)


def test_the_true_load_fed_forward_late() -> None:
    """README: the true load fed forward 2 or 3 samples late gives a dip of 2.21 or 2.78 rad/s."""
    for latency, dip in ((2, 2.21), (3, 2.78)):
        runs = run_scenario(RIG, DEMO_SCENARIO, ("truth",), seed=1, ff_latency=latency)
        assert worst(runs)["truth"][0] == pytest.approx(dip, abs=0.005), latency


def test_the_step_size_bound() -> None:
    """README: 1 sigma of a 0.2 N m step is 78, 32, 18 % of it after 1, 2, 3 samples."""
    bound = 100 * jump_bound(RIG, 150.0, 0.1, 3) / 0.2
    np.testing.assert_allclose(np.round(bound), [78, 32, 18])


def test_transient_table_and_noise(database) -> None:
    """README, the transient table (make evaluate's `transient:` lines) and the observer's noise ratio."""
    expected = {"knn": (16, 12.9, 1.08, 3.91), "extended_model": (16, 7.0, 1.43, 7.67),
                "observer": (3, 19.1, 0.18, 8.38)}
    for method, (step90, overshoot, ramp, reversal) in expected.items():
        estimator = make_estimator(method, database, **({"k": 4} if method == "knn" else {}))
        f = transient_figures(RIG, method, estimator, database.torque_range, seeds=12, seed=0)
        assert f.step90_ms == step90, (method, f)
        assert f.overshoot_pct == pytest.approx(overshoot, abs=0.05), (method, f)
        assert f.ramp_err_pct == pytest.approx(ramp, abs=0.005), (method, f)
        assert f.reversal_err_pct == pytest.approx(reversal, abs=0.005), (method, f)
        if method == "observer":
            assert f.steady_std == pytest.approx(5.2e-4, abs=0.05e-4)
            assert f.steady_std / steady_state_bound(RIG, STEP_SPEED, 0.0) == pytest.approx(1.03, abs=0.005)
