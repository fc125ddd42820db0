"""`calibrate --live` over real DDS: sim_node and controller_node as processes, calibrate as a third.

The graph is sim_node (the rig; driver_node takes its place on the real rig)
and controller_node (feedforward off: there is no calibration yet). The
installed `calibrate` executable drives it through a small grid with short
windows, is interrupted with Ctrl-C (SIGINT) part-way, and `--resume`
finishes it. The database must hold every grid point, steady, with its
spread, the points taken before the interruption unchanged, and the same
map as the in-process batch calibration of the same grid (within noise).

ROS_DOMAIN_ID: the environment's if set, else a random one in 100..230;
discovery stays on this host (the ros_env fixture of tests/conftest.py).
"""
from __future__ import annotations

import json
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.database import load_database
from torque_estimator.calibration.journal import CalibrationJournal, default_journal_path
from torque_estimator.graph.runner import Graph
from worm_model.ros.ament import find_executable
from rig_sessions import last_speed_command, session_graph
from torque_estimator.calibration.operating_points import SteadyStateCriterion
from worm_model.physics.parameters import load_rig

GRAPH = session_graph(seed=3)
RIG = load_rig()
CRITERION = SteadyStateCriterion(window=0.2, settle_time=0.3, timeout=4.0)
GRID = CalibrationGrid.paper(RIG, n_speeds=2, n_torques=2, speed_min=100.0, speed_max=200.0)  # 4 speeds x 2
N_POINTS = 8
CLI_GRID = ["--speeds", "2", "--torques", "2", "--speed-min", "100", "--speed-max", "200", "--window", "0.2",
            "--settle-time", "0.3", "--timeout", "4"]


@pytest.fixture(scope="module")
def rig_graph(start_graph: Callable[[str, str], Graph]) -> Graph:
    """sim_node + controller_node (ros_env and start_graph: tests/conftest.py)."""
    return start_graph(GRAPH, "live_graph")


def _points(journal: Path) -> int:
    try:
        return len(json.loads(journal.read_text())["points"]["plan_index"])
    except (OSError, ValueError, KeyError):
        return 0


def test_live_calibration_interrupted_and_resumed(rig_graph: Graph, ros_env: dict[str, str],
                                                  tmp_path: Path) -> None:
    out = tmp_path / "live.json"
    journal = default_journal_path(out)
    command = [str(find_executable("calibrate")), "--live", "--out", str(out), "--quiet", *CLI_GRID]

    proc = subprocess.Popen(command, env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 90.0
    while _points(journal) < 3:
        assert proc.poll() is None, f"calibrate exited early ({proc.returncode}):\n{proc.communicate()[1]}"
        assert time.monotonic() < deadline, f"no 3 points in 90 s; logs in {rig_graph.log_dir}"
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "--resume" in err and not out.exists()
    before = CalibrationJournal.load(journal, N_POINTS).points
    assert 3 <= len(before) < N_POINTS, f"{len(before)} points before the interruption"
    # calibrate left the rig at rest: controller_node now holds 0 rad/s
    last = last_speed_command("calibrate_test_probe")
    assert last is not None and last.speed_setpoint == 0.0, last
    assert not rig_graph.failed(), rig_graph.failed()

    done = subprocess.run(command + ["--resume"], env=ros_env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert not journal.exists()
    db = load_database(out)
    print(done.stdout)

    speeds, torques, index = GRID.points()
    assert len(db) == N_POINTS and not db.steady_state["unsettled_points"]
    np.testing.assert_array_equal(db.setpoint_index, index)
    assert "live rig" in db.notes and "resumed 1 time(s)" in db.notes
    assert db.rig["name"] == RIG.name and db.steady_state["window"] == CRITERION.window
    # each point held at its set-points, with its spread kept
    allowed = CRITERION.speed_tolerance * np.abs(speeds) + CRITERION.speed_floor
    assert np.all(np.abs(db.omega_worm - speeds) <= allowed), db.omega_worm
    np.testing.assert_allclose(db.tau_load, torques, atol=0.01)
    for name in ("omega_std", "current_std", "tau_std"):
        assert np.all(getattr(db, name) > 0), name
    np.testing.assert_array_equal(db.samples, round(CRITERION.window * RIG.sensors.sample_rate_hz))
    # the points taken before Ctrl-C were kept, not measured again
    for i, point in before.items():
        assert db.current_drive[i] == point["current_drive"] and db.omega_worm[i] == point["omega_worm"]
    # the same map as the in-process batch calibration (same physics, other noise)
    batch = calibrate_simulated(RIG, GRID, seed=0, criterion=CRITERION)
    standard_error = np.hypot(db.current_std, batch.current_std) / np.sqrt(db.samples)
    deviation = np.abs(db.current_drive - batch.current_drive) / standard_error
    assert np.all(deviation < 6), f"live vs batch current, in standard errors: {deviation}"


def test_live_calibration_without_a_rig_fails_naming_the_topic(ros_env: dict[str, str], tmp_path: Path) -> None:
    env = dict(ros_env)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "OFF"  # sees no other process: certainly no rig
    done = subprocess.run([str(find_executable("calibrate")), "--live", "--out", str(tmp_path / "x.json"),
                           "--quiet", "--start-timeout", "2", *CLI_GRID], env=env, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "rig/samples" in done.stderr and not (tmp_path / "x.json").exists()
