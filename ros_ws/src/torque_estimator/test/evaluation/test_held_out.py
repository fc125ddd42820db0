"""Held-out evaluation (the paper's Table 3): set-points off the grid, error figures, sweeps, the CLI."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.database import save_database
from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.evaluation.held_out import (Evaluation, format_table, held_out_setpoints, measure_held_out, score,
                                         sweep_k, with_noise)
from worm_model.ros.ament import find_executable
from torque_estimator.estimation.knn import KnnEstimator

RIG = load_rig()
GRID = CalibrationGrid.paper(RIG)
LAST_LINE = re.compile(r"^knn: mae_pct=(\d+\.\d\d) max_pct=(\d+\.\d\d) points=(\d+)$")


def test_held_out_set_points_are_inside_the_span_off_the_nodes_in_every_quadrant() -> None:
    speeds, torques = held_out_setpoints(GRID, 200, seed=3)
    magnitudes = np.unique(np.abs(GRID.speeds))
    speed_step, torque_step = np.diff(magnitudes).min(), np.diff(GRID.torques).min()
    near_speed = np.min(np.abs(np.abs(speeds)[:, None] - magnitudes), axis=1) < 0.2 * speed_step
    near_torque = np.min(np.abs(torques[:, None] - GRID.torques), axis=1) < 0.2 * torque_step
    assert not np.any(near_speed & near_torque)  # no held-out point is (close to) a grid point
    assert np.all((np.abs(speeds) >= magnitudes[0]) & (np.abs(speeds) <= magnitudes[-1]))
    assert np.all((torques >= GRID.torques[0]) & (torques <= GRID.torques[-1]))
    # 17 points (the paper's count) cover both directions and both torque signs in each direction
    speeds, torques = held_out_setpoints(GRID, 17, seed=1)
    for direction in (1, -1):
        for sign in (1, -1):
            assert np.any((np.sign(speeds) == direction) & (np.sign(torques) == sign))
    again = held_out_setpoints(GRID, 17, seed=1)
    np.testing.assert_array_equal(again[0], speeds)
    assert not np.array_equal(held_out_setpoints(GRID, 17, seed=2)[0], speeds)


def test_error_figures_are_percent_of_the_torque_range() -> None:
    ev = Evaluation(omega_worm=np.array([100.0, -50.0, 20.0]), current_drive=np.array([0.1, -0.2, 0.3]),
                    tau_true=np.array([0.10, -0.20, 0.05]), tau_estimated=np.array([0.11, -0.18, 0.05]),
                    flags=np.array([0, int(EstimateFlags.AMBIGUOUS), 0]), torque_range=0.5)
    np.testing.assert_allclose(ev.error_pct, [2.0, 4.0, 0.0])
    assert ev.mae_pct == pytest.approx(2.0) and ev.max_pct == pytest.approx(4.0)
    rows = format_table(ev)
    assert len(rows) == 4 and "AMBIGUOUS" in rows[2] and rows[1].split()[:2] == ["1", "100.0"]


def test_score_compares_the_estimate_of_each_measured_point_with_its_applied_load() -> None:
    grid = CalibrationGrid.paper(RIG, n_speeds=5, n_torques=6)
    db = calibrate_simulated(RIG, grid, seed=0)
    measured = measure_held_out(RIG, grid, n=12, seed=4)
    estimator = KnnEstimator(db, k=3)
    ev = score(estimator, measured, db.torque_range)
    expected = estimator.estimate(measured.omega_worm, measured.current_drive).torque
    np.testing.assert_array_equal(ev.tau_estimated, expected)
    np.testing.assert_array_equal(ev.tau_true, measured.tau_true)
    assert ev.torque_range == db.torque_range and ev.mae_pct < 10.0  # a coarse map still estimates
    # k = 1 is the nearest point whatever the weighting; the sweep reports it identically
    sweep = sweep_k(db, measured, [1, 3])
    assert sweep.mae_pct["inverse_distance"][0] == sweep.mae_pct["uniform"][0]
    assert sweep.mae_pct["inverse_distance"][1] == pytest.approx(ev.mae_pct)


def test_with_noise_scales_only_the_noise() -> None:
    noisy = with_noise(RIG, 2.0)
    assert noisy.sensors.current_noise_std == 2 * RIG.sensors.current_noise_std
    assert noisy.sensors.tacho_noise_std == 2 * RIG.sensors.tacho_noise_std
    assert noisy.sensors.current_lsb == RIG.sensors.current_lsb and noisy.gearbox == RIG.gearbox


def _table_rows(stdout: str) -> list[list[str]]:
    return [line.split() for line in stdout.splitlines() if re.match(r"^\s+\d+\s+-?\d+\.\d\s", line)]


def test_cli_prints_table_3_and_its_summary_last(tmp_path: Path) -> None:
    grid = CalibrationGrid.paper(RIG, n_speeds=4, n_torques=5)
    db = calibrate_simulated(RIG, grid, seed=0)
    calibration = tmp_path / "cal.json"
    save_database(db, calibration)
    exe = find_executable("evaluate")  # the installed console script, as `ros2 run` finds it
    done = subprocess.run([str(exe), "--calibration", str(calibration), "--points", "6", "--no-sweeps",
                           "--no-transient", "--no-residuals", "--no-real", "--no-health", "--no-foreign", "--out",
                           str(tmp_path / "out"), "--quiet"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    last = done.stdout.rstrip("\n").splitlines()[-1]
    match = LAST_LINE.match(last)
    assert match, f"last line: {last!r}"
    assert match.group(3) == "6"
    rows = _table_rows(done.stdout)
    assert len(rows) == 6
    # the summary is the table's errors: |est - true| / range, from the printed (rounded) columns
    true = np.array([float(r[3]) for r in rows])
    est = np.array([float(r[4]) for r in rows])
    errors = 100 * np.abs(est - true) / db.torque_range
    np.testing.assert_allclose([float(r[5]) for r in rows], errors, atol=0.02 + 2e-4 / db.torque_range * 100)
    assert float(match.group(1)) == pytest.approx(errors.mean(), abs=0.03)
    assert float(match.group(2)) == pytest.approx(errors.max(), abs=0.03)
    assert (tmp_path / "out" / "held_out_deviation.png").stat().st_size > 0


def test_cli_sweeps_write_their_plot(tmp_path: Path) -> None:
    done = subprocess.run([str(find_executable("evaluate")), "--speeds", "3", "--torques", "4", "--points", "4",
                           "--sweep-points", "8", "--ks", "1,2", "--grid-sizes", "2x2,3x4", "--noise", "0,1",
                           "--no-transient", "--no-residuals", "--no-real", "--no-health", "--no-foreign", "--out",
                           str(tmp_path / "out"), "--quiet"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert LAST_LINE.match(done.stdout.splitlines()[-1]).group(3) == "4"
    assert (tmp_path / "out" / "error_sweeps.png").stat().st_size > 0
    assert "neighbours k [uniform]  1: " in done.stdout


def test_cli_bad_input_exits_2_naming_it(tmp_path: Path) -> None:
    missing = tmp_path / "nope.json"
    done = subprocess.run([str(find_executable("evaluate")), "--calibration", str(missing), "--quiet"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and str(missing) in done.stderr
    done = subprocess.run([str(find_executable("evaluate")), "--grid-sizes", "3by4"], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2 and "SPEEDSxTORQUES" in done.stderr
