"""The demo's figures show what they claim: the estimate on the loads' scale with flagged estimates marked
(never drawn as estimates), the speed error on the load steps' scale, a panel per load step with both runs.

The runs are synthetic (the demo scenario's loads and set-points, a dip after each load step, a 6 N m
flagged spike at the speed reversal like the live estimate's), so each assertion knows the answer.
"""
from __future__ import annotations

from itertools import pairwise
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.patches import Polygon, Rectangle
from torque_estimator.demo.plots import (
    ESTIMATE_LABEL,
    EstimateTrace,
    SpeedTrace,
    draw_estimate_vs_truth,
    draw_load_steps,
    draw_tracking,
    estimate_vs_truth,
    flagged_spans,
    group_steps,
    load_limits,
    load_steps,
    setpoint_changes,
    torque_text,
    tracking,
)
from torque_estimator.demo.run_analysis import recorded_load_steps, steady_spans
from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.evaluation.scenario import DEMO_SCENARIO, segment_starts

RANGE = 0.495  # [N m] the demo's calibrated range
SPIKE = 6.0  # [N m] the flagged estimate at the reversal (the live feedforward-off run's)
DIPS = {"feedforward off": (5.0, 0.10), "feedforward on": (2.5, 0.02)}  # peak [rad/s], decay [s]


def _scenario_at(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The demo scenario's load [N m] and set-point [rad/s] at times t [s]."""
    k = np.clip(np.searchsorted(segment_starts(DEMO_SCENARIO), t, side="right") - 1, 0, len(DEMO_SCENARIO) - 1)
    return np.array([s.load for s in DEMO_SCENARIO])[k], np.array([s.speed for s in DEMO_SCENARIO])[k]


def _speed_run(peak: float, decay: float, shift: float) -> SpeedTrace:
    """1 kHz true speed: the set-point plus a dip of ``peak`` [rad/s] after each load step, the start-up and
    the reversal lagging; the run's clock ``shift`` [s] off the schedule."""
    t = np.arange(0.0, 12.0, 0.001)
    load, setpoint = _scenario_at(t - shift)
    setpoint[t < shift] = 0.0  # the drive at rest until the scenario starts
    omega = setpoint.copy()
    for k, start in enumerate(segment_starts(DEMO_SCENARIO)):
        dt = t - start - shift
        after = dt >= 0
        if k == 0 or DEMO_SCENARIO[k].speed != DEMO_SCENARIO[k - 1].speed:
            before = DEMO_SCENARIO[k - 1].speed if k else 0.0
            omega[after] += (before - DEMO_SCENARIO[k].speed) * np.exp(-dt[after] / 0.05)
        else:
            sign = -np.sign(DEMO_SCENARIO[k].speed) * np.sign(DEMO_SCENARIO[k].load - DEMO_SCENARIO[k - 1].load)
            shape = np.exp(-dt[after] / decay) * (1 - np.exp(-dt[after] / 0.002))
            omega[after] += sign * peak * shape / shape.max()
    return SpeedTrace(t, omega, setpoint), load


@pytest.fixture(scope="module")
def speed_runs():
    runs, loads = {}, {}
    for shift, (name, (peak, decay)) in zip((0.003, 0.011), DIPS.items()):
        runs[name], loads[name] = _speed_run(peak, decay, shift)
    steps = {name: recorded_load_steps(r.t, loads[name], r.t, r.omega, r.setpoint) for name, r in runs.items()}
    return runs, steps


@pytest.fixture(scope="module")
def estimate_runs():
    """200 Hz estimates on the truth, with flagged samples: one per load step (transient), the reversal's
    spike (out of calibration, +6 and -1 N m) and one invalid input (NaN)."""
    rng = np.random.default_rng(0)
    t_truth = np.arange(0.0, 12.0, 0.001)
    truth = _scenario_at(t_truth)[0]
    runs = {}
    for name in DIPS:
        t = np.arange(0.0, 12.0, 0.005)
        estimate = np.interp(t, t_truth, truth) + rng.normal(0.0, 0.002, t.size)
        flags = np.zeros(t.size, int)
        for start in segment_starts(DEMO_SCENARIO)[1:]:
            k = np.searchsorted(t, start)
            flags[k] |= EstimateFlags.TRANSIENT
            estimate[k] = 0.1
        k = np.searchsorted(t, 8.0)
        flags[k:k + 2] |= EstimateFlags.OUT_OF_CALIBRATION | EstimateFlags.TRANSIENT
        estimate[k:k + 2] = (SPIKE, -1.0)
        flags[500] |= EstimateFlags.INVALID_INPUT
        estimate[500] = np.nan
        flags[100:110] |= EstimateFlags.AMBIGUOUS
        runs[name] = EstimateTrace(t, estimate, flags, t_truth, truth)
    return runs


def _xspan(patch) -> tuple[float, float]:
    """The time span [s] an axvspan patch covers (a Rectangle, or a Polygon on older matplotlib)."""
    if isinstance(patch, Rectangle):
        return float(patch.get_x()), float(patch.get_x() + patch.get_width())
    xs = np.asarray(patch.get_xy())[:, 0]
    return float(xs.min()), float(xs.max())


def _torque_axes(fig) -> list:
    return [ax for ax in fig.axes if ax.get_ylabel().startswith("τ_d")]


def _estimate_line(ax):
    (line,) = [ln for ln in ax.get_lines() if ln.get_label().startswith(ESTIMATE_LABEL)]
    return line


def test_flagged_estimates_are_marked_and_never_drawn_as_estimates(estimate_runs) -> None:
    fig = draw_estimate_vs_truth(estimate_runs, RANGE, steady_spans(DEMO_SCENARIO))
    try:
        axes = _torque_axes(fig)
        assert len(axes) == len(estimate_runs)
        for ax, run in zip(axes, estimate_runs.values()):
            x, y = (np.asarray(a, float) for a in _estimate_line(ax).get_data())
            flagged = run.flags != 0
            np.testing.assert_array_equal(x, run.t_est)
            assert np.all(np.isnan(y[flagged]))  # the line breaks at every flagged estimate
            np.testing.assert_array_equal(y[~flagged], run.estimate[~flagged])  # and draws every other one
            # each flagged estimate lies under a shaded span
            spans = [_xspan(p) for p in ax.patches if isinstance(p, (Polygon, Rectangle))]
            covered = [any(a <= t <= b for a, b in spans) for t in run.t_est[flagged]]
            assert all(covered)
            # and has a marker: at its value on the scale, at the axis' edge (its value printed) off it
            markers = np.concatenate([ln.get_xdata() for ln in ax.get_lines() if ln.get_marker() in ("o", "^", "v")])
            finite = flagged & np.isfinite(run.estimate)
            assert set(np.round(run.t_est[finite], 6)) <= set(np.round(markers.astype(float), 6))
            assert any(f"+{SPIKE:.1f} N·m" in text.get_text() for text in ax.texts)
            assert {f"flagged: {kind}" for kind in ("out of calibration", "transient", "ambiguous")} <= set(
                ax.get_legend_handles_labels()[1] + fig.axes[0].get_legend_handles_labels()[1])
    finally:
        plt.close(fig)


def test_estimate_axis_is_scaled_to_the_loads_not_to_the_spike(estimate_runs) -> None:
    fig = draw_estimate_vs_truth(estimate_runs, RANGE)  # no judged spans: nothing shaded on the error panels
    try:
        assert not any(ax.patches for ax in fig.axes if "% of range" in ax.get_ylabel())
        loads = load_limits(np.concatenate([r.truth for r in estimate_runs.values()]))
        for ax in _torque_axes(fig):
            lo, hi = ax.get_ylim()
            assert (lo, hi) == pytest.approx(loads)
            assert lo < -0.2 and hi > 0.2  # the loads (+/-0.2 N m) on the axis
            assert hi - lo < 3 * 0.4  # and the 6 N m spike not: the 0.4 N m span of the loads fills it
            for line in ax.get_lines():  # nothing drawn outside it (off-scale markers sit at its edge)
                y = np.asarray(line.get_ydata(), float)
                assert np.all((y[np.isfinite(y)] >= lo) & (y[np.isfinite(y)] <= hi)), line.get_label()
    finally:
        plt.close(fig)


def test_error_panels_are_in_percent_of_range_and_shade_what_the_table_leaves_out(estimate_runs) -> None:
    judged = steady_spans(DEMO_SCENARIO)
    fig = draw_estimate_vs_truth(estimate_runs, RANGE, judged)
    try:
        errors = [ax for ax in fig.axes if "% of range" in ax.get_ylabel()]
        assert len(errors) == len(estimate_runs)
        for ax, run in zip(errors, estimate_runs.values()):
            y = np.asarray(ax.get_lines()[0].get_ydata(), float)
            expected = 100 * (run.estimate - np.interp(run.t_est, run.t_truth, run.truth)) / RANGE
            ok = run.flags == 0
            np.testing.assert_allclose(y[ok], expected[ok])
            assert np.all(np.isnan(y[~ok]))
            assert ax.get_ylim()[1] < 10  # the steady error (~0.5 %) is visible, not a sliver
            shaded = sorted(_xspan(p) for p in ax.patches)
            # the settling after each change: the gaps between the table's steady spans
            gaps = [(0.0, judged[0][0])] + [(a[1], b[0]) for a, b in pairwise(judged)]
            np.testing.assert_allclose(shaded, gaps)
    finally:
        plt.close(fig)


def test_load_steps_figure_has_a_panel_per_step_with_both_runs_and_their_dips(speed_runs) -> None:
    runs, steps = speed_runs
    assert all(len(s) == 4 for s in steps.values())  # the scenario's four load steps, found in the record
    fig = draw_load_steps(runs, steps)
    try:
        panels = [ax for ax in fig.axes if ax.get_visible()]
        assert len(panels) == 4
        for k, ax in enumerate(panels):
            labels = [ln.get_label() for ln in ax.get_lines() if not ln.get_label().startswith("_")]
            assert len(labels) == 2 and all(label.startswith(name) for label, name in zip(labels, runs))
            lo, hi = ax.get_ylim()
            assert max(abs(lo), hi) < 3 * DIPS["feedforward off"][0]  # the dips' scale, not +/-150 rad/s
            for name in runs:
                step = steps[name][k]
                assert f"dip {step.peak_dip:.2f} rad/s, IAE {step.iae:.2f} rad" in " ".join(labels)
                (line,) = [ln for ln in ax.get_lines() if ln.get_label().startswith(name)]
                x, y = (np.asarray(a, float) for a in line.get_data())
                assert x.min() < 0 < x.max()  # from before the step to after it [ms], on the run's own clock
                assert np.max(np.abs(y)) == pytest.approx(step.peak_dip, rel=0.02)
                assert lo < -step.peak_dip or hi > step.peak_dip
        assert "+0.2" in panels[0].get_title() and "+150 rad/s" in panels[0].get_title()
        assert "-150 rad/s" in panels[3].get_title()
    finally:
        plt.close(fig)


def test_tracking_error_panel_is_on_the_dips_scale_and_names_the_set_point_changes(speed_runs) -> None:
    runs, steps = speed_runs
    fig = draw_tracking(runs, steps)
    try:
        top, bottom = fig.axes
        assert top.get_ylim()[1] > 150  # the speed at full scale above
        lo, hi = bottom.get_ylim()
        assert 5.0 < hi < 10.0 and lo == -hi  # the 5 rad/s dip fits; the 300 rad/s reversal does not
        texts = " ".join(t.get_text() for t in bottom.texts)
        assert "set-point +150 → -150 rad/s" in texts and "set-point 0 → +150 rad/s" in texts
        assert texts.count("N·m") == 4  # each load step named
        assert len([ln for ln in bottom.get_lines() if len(ln.get_xdata()) == len(runs["feedforward on"].t)]) == 2
    finally:
        plt.close(fig)


def test_the_figures_are_written_as_png(tmp_path: Path, estimate_runs, speed_runs) -> None:
    runs, steps = speed_runs
    for path in (estimate_vs_truth(tmp_path / "e.png", estimate_runs, RANGE, steady_spans(DEMO_SCENARIO)),
                 tracking(tmp_path / "t.png", runs, steps), load_steps(tmp_path / "l.png", runs, steps)):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_load_limits_hold_the_loads_with_half_their_span_to_spare() -> None:
    assert load_limits([0.0, 0.2, -0.004, -0.2]) == pytest.approx((-0.4, 0.4))
    assert load_limits([0.0, 0.1]) == pytest.approx((-0.05, 0.15))
    lo, hi = load_limits([0.3, 0.3, np.nan])  # a constant load still gets an axis around it
    assert lo < 0.3 < hi


def test_flagged_spans_are_runs_of_flagged_samples_half_a_period_wider() -> None:
    t = np.arange(10) * 0.01
    flagged = np.array([1, 1, 0, 0, 1, 0, 0, 0, 1, 1], bool)
    np.testing.assert_allclose(flagged_spans(t, flagged), [(-0.005, 0.015), (0.035, 0.045), (0.075, 0.095)])
    assert flagged_spans(t, np.zeros(10, bool)) == []


def test_group_steps_pairs_the_same_step_of_every_run() -> None:
    groups = group_steps({"off": [1.99, 3.99, 10.0], "on": [2.001, 6.0, 10.01]})
    assert groups == [{"off": 0, "on": 0}, {"off": 1}, {"on": 1}, {"off": 2, "on": 2}]
    assert group_steps({"off": [1.0, 1.2]}) == [{"off": 0}, {"off": 1}]  # one run's two steps stay two


def test_labels_say_the_loads_and_set_points_as_the_scenario_has_them() -> None:
    assert [torque_text(x) for x in (0.0, 0.2, -0.004, -0.2, 1e-12)] == ["0", "+0.2", "-0.004", "-0.2", "0"]
    assert setpoint_changes([0, 1, 2, 3], [0, 150, 150, -150]) == [(1.0, 0.0, 150.0), (3.0, 150.0, -150.0)]


def test_steady_spans_are_each_segment_after_its_settling() -> None:
    spans = steady_spans(DEMO_SCENARIO, settle=0.8)
    np.testing.assert_allclose(spans, [(s + 0.8, s + 2.0) for s in segment_starts(DEMO_SCENARIO)])
