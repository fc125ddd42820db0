"""`identify` over real DDS: sim_node and controller_node as processes, identify as a third.

The installed executable drives the graph through a 20 s excitation, is interrupted with Ctrl-C
part-way (the rig must be left at rest: controller_node holds 0 rad/s), and `--resume` records the
missing segments and fits: the extended rig file loads, the record holds the whole excitation in
two runs (the resumed part after a gap).  ROS_DOMAIN_ID: the ros_env fixture (tests/conftest.py).
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

from torque_estimator.graph.runner import Graph
from torque_estimator.session.recording import journal_paths
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.reader import read_rig_data
from worm_model.ros.ament import find_executable
from rig_sessions import last_speed_command, session_graph

GRAPH = session_graph(seed=3)


@pytest.fixture(scope="module")
def rig_graph(start_graph: Callable[[str, str], Graph]) -> Graph:
    return start_graph(GRAPH, "identify_graph")


def _segments(state: Path) -> int:
    try:
        return int(json.loads(state.read_text())["segments_done"])
    except (OSError, ValueError, KeyError):
        return 0


def test_live_identification_interrupted_and_resumed(rig_graph: Graph, ros_env: dict[str, str],
                                                     tmp_path: Path) -> None:
    out = tmp_path / "identified.yaml"
    state, _csv = journal_paths(out)
    command = [str(find_executable("identify")), "--out", str(out), "--duration", "20", "--quiet"]
    proc = subprocess.Popen(command, env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 90.0
    while _segments(state) < 10:
        assert proc.poll() is None, f"identify exited early ({proc.returncode}):\n{proc.communicate()[1]}"
        assert time.monotonic() < deadline, f"no 10 segments in 90 s; logs in {rig_graph.log_dir}"
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert "--resume" in err and not out.exists()
    last = last_speed_command("identify_test_probe")
    assert last is not None and last.speed_setpoint == 0.0, last  # the rig was left stopped
    assert not rig_graph.failed(), rig_graph.failed()

    done = subprocess.run(command + ["--resume"], env=ros_env, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1].startswith("identify: rig_time_s=")
    assert not state.exists()
    assert load_rig(out).name == load_rig().name
    record = read_rig_data(tmp_path / "identified_record.csv")
    assert len(np.unique(record.run)) == 2 and len(record) == pytest.approx(20000, abs=40)
    assert np.abs(record.omega_worm).max() > 300  # the rig followed the excitation
    last = last_speed_command("identify_test_probe")
    assert last is not None and last.speed_setpoint == 0.0, last
