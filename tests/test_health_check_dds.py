"""`health_check` over real DDS: sim_node and controller_node as processes, the installed health_check a third.

It drives the graph through the reference run (28.5 s of rig time) with the machinery of `identify`,
writes the record and the trend, and finds the plant the rig file describes (sim_node without effects):
mu's scale 1 and the drive drags of the rig file, within the check's intervals.
ROS_DOMAIN_ID: the ros_env fixture (tests/conftest.py).
"""
from __future__ import annotations

import math
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from torque_estimator.graph.runner import Graph
from worm_model.health.record import read_trend
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.reader import read_rig_data
from worm_model.ros.ament import find_executable
from rig_sessions import session_graph

CHECK_GRAPH = session_graph(seed=4)

@pytest.fixture(scope="module")
def check_graph(start_graph: Callable[[str, str], Graph]) -> Graph:
    return start_graph(CHECK_GRAPH, "health_check_graph")


def test_health_check_drives_the_live_graph_and_finds_the_plant(check_graph: Graph, ros_env: dict[str, str],
                                                                 tmp_path: Path) -> None:
    trend, record = tmp_path / "gearbox.jsonl", tmp_path / "run.csv"
    done = subprocess.run([str(find_executable("health_check")), "--trend", str(trend), "--record", str(record),
                           "--hours", "12", "--quiet"], env=ros_env, capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stderr
    last = done.stdout.strip().splitlines()[-1]
    assert last.startswith("health_check: level=OK mu_change=n/a (baseline)") and str(trend) in last, last
    data = read_rig_data(record)
    assert len(data) == pytest.approx(28500, abs=60) and abs(data.omega_worm).max() > 280
    checks = read_trend(trend).records
    assert len(checks) == 1 and checks[0].hours == 12.0 and checks[0].points >= 28
    check = checks[0]
    rig = load_rig()
    # the plant is the rig file's model: mu as the file's (scale 1) and its drags, within the intervals
    # (sigma x the root of the fit's reduced chi-square, 3 of them)
    widen = 3.0 * math.sqrt(max(1.0, check.chi2_red))
    assert abs(check.parameters.mu_scale - 1.0) < widen * check.sigma["mu_scale"] + 0.01, check.parameters
    assert abs(check.parameters.drive_coulomb - rig.drive_motor.coulomb_drag) \
        < widen * check.sigma["drive_coulomb"] + 2e-4, check.parameters
    assert not check_graph.failed(), check_graph.failed()
