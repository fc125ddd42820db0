"""docs/new-drive.md, run as an engineer runs it: every command of its five steps, as written on the page, in one
working folder, on a drive the project did not make (torque_estimator.evaluation.foreign: a plant of its own
equations, friction and sensors, whose numbers no tool reads).

1. ``rig_from_datasheet`` writes my_drive.yaml from the page's catalogue and motor numbers (the foreign 30:1
   drive's): it loads, and its geometry is the catalogue's (ratio, worm diameter, lead angle).
2. ``worm_calc --rig my_drive.yaml`` checks it: the page's self-locking figures.
3. ``identify --from my_run.csv`` fits it to a recorded run (the drive's 120 s excitation): the page's
   rms_before / rms_after and mu.
4. ``estimate my_check.csv`` on a second recording with the identified file: the page's figures, for the
   extended model and (the page's prose) the momentum observer and the observer.
5. ``estimator_node`` on the robot's /joint_states (a stand-in robot: that drive as joint "elbow" among others,
   published as joint_state_broadcaster publishes, output side, effort the drive current), without and with the
   page's load prior: torque_estimate/elbow follows the load the drive carries, and
   torque_estimate/joint_states names the joint.
"""
from __future__ import annotations

import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from worm_msgs.msg import TorqueEstimate

from worm_model.physics.parameters import load_rig
from worm_model.ros.ament import find_executable
from worm_model.ros.testing import probe_node, stop_process

from torque_estimator.evaluation.foreign.drives import DRIVES
from torque_estimator.evaluation.foreign.recordings import excitation, steady, validation, write_csv

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "new-drive.md"
STEPS = ("## 1.", "## 2.", "## 3.", "## 4.", "## 5.", "## On a test bench")
DRIVE = DRIVES["foreign30"]
SECONDS = 120.0  # [s] of each recording (the page's)
LOAD = 0.5  # [N m] the stand-in robot's load on the elbow
SPEED = 120.0  # [rad/s] worm


def page_commands() -> list[str]:
    """The `ros2 run` lines of the code blocks of the page's four steps, in order."""
    text = PAGE.read_text(encoding="utf-8")
    section = text[text.index(STEPS[0]):text.index(STEPS[-1])]
    return [line.strip() for block in re.findall(r"```\n(.*?)```", section, flags=re.S)
            for line in block.splitlines() if line.strip().startswith("ros2 run ")]


def argv(line: str) -> list[str]:
    """A `ros2 run <pkg> <exe> args` line as the process `ros2 run` starts."""
    words = shlex.split(line)
    assert words[:2] == ["ros2", "run"], line
    return [str(find_executable(words[3])), *words[4:]]


def robot_states(samples: int) -> dict[str, np.ndarray]:
    """The elbow at SPEED under LOAD, held by the drive's own speed loop: every sample's output-side values."""
    rec = steady(DRIVE, SPEED, LOAD, samples / DRIVE.sample_rate, seed=4)
    ratio = 1.0 / DRIVE.ratio if DRIVE.ratio > 1.0 else DRIVE.ratio
    return {"position": rec.theta_worm[:samples] * ratio, "velocity": rec.omega_worm[:samples] * ratio,
            "effort": rec.current_drive[:samples]}


def page_figure(text: str, pattern: str) -> str:
    found = re.search(pattern, text)
    assert found, pattern
    return found.group(1)


def run_node(command: str, folder: Path, env: dict[str, str]) -> tuple[list, list]:
    """The page's estimator_node command, fed the stand-in robot's joint states: (estimates, joint states out)."""
    estimates: list = []
    joints: list = []
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=2000, reliability=ReliabilityPolicy.BEST_EFFORT)
    node_process = subprocess.Popen(argv(command), cwd=folder, env=env, stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True)
    robot = None
    try:
        with probe_node("new_drive_probe") as (node, executor):
            node.create_subscription(TorqueEstimate, "/torque_estimate/elbow", estimates.append, qos)
            node.create_subscription(JointState, "/torque_estimate/joint_states", joints.append, qos)
            deadline = time.monotonic() + 60.0
            while not node.count_publishers("/torque_estimate/elbow") and time.monotonic() < deadline:
                assert node_process.poll() is None, node_process.stdout.read()
                executor.spin_once(timeout_sec=0.1)
            robot = subprocess.Popen([sys.executable, "-m", "worm_model.ros.joint_state_player",
                                      str(folder / "robot.npz"), "--period", "0.002", "--wait", "1.0"], env=env)
            while robot.poll() is None and time.monotonic() < deadline + 60.0:
                executor.spin_once(timeout_sec=0.05)
            end = time.monotonic() + 1.0
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
        assert robot.returncode == 0
    finally:
        if robot is not None:
            stop_process(robot)
        assert stop_process(node_process) == 0, node_process.stdout.read()
    return estimates, joints


def test_every_step_of_the_page(ros_env: dict[str, str], tmp_path: Path) -> None:
    page = PAGE.read_text(encoding="utf-8")
    commands = page_commands()
    assert [shlex.split(c)[3] for c in commands] == ["rig_from_datasheet", "worm_calc", "identify", "estimate",
                                                      "estimator_node", "estimator_node"]
    make_rig, check, identify, estimate, estimator, with_prior = commands

    # 1. the rig file from the datasheet: the foreign drive's catalogue, as the page types it
    done = subprocess.run(argv(make_rig), cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    rig = load_rig(tmp_path / "my_drive.yaml")
    words = shlex.split(make_rig)
    given = {w: float(words[words.index(w) + 1]) for w in ("--ratio", "--worm-diameter-mm", "--lead-angle-deg")}
    for option, key in (("--ratio", "ratio"), ("--worm-diameter-mm", "worm_diameter_mm"),
                        ("--lead-angle-deg", "lead_angle_deg"), ("--torque-constant", "torque_constant")):
        assert float(words[words.index(option) + 1]) == pytest.approx(DRIVE.catalogue[key]), option
    gb = rig.gearbox
    assert 1 / gb.ratio == pytest.approx(given["--ratio"])
    assert 2e3 * gb.worm_pitch_radius == pytest.approx(given["--worm-diameter-mm"])
    assert np.degrees(gb.lead_angle) == pytest.approx(given["--lead-angle-deg"])
    assert gb.geometric_ratio == pytest.approx(gb.ratio, rel=1e-5)
    document = yaml.safe_load((tmp_path / "my_drive.yaml").read_text(encoding="utf-8"))
    assert "source" in document["drive_motor"]["torque_constant"] and "assumption" in document["friction"]["scale"]

    # 2. its check: the page's self-locking figures
    done = subprocess.run(argv(check), cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert re.search(r"self-locking\s+no$", done.stdout, re.M), done.stdout
    limit = page_figure(page, r"`self-locking above mu = ([\d.]+)`")
    assert re.search(rf"self-locking above mu =\s+{re.escape(limit)}$", done.stdout, re.M), done.stdout

    # 3. identify from a recorded run of the drive
    write_csv(tmp_path / "my_run.csv", excitation(DRIVE, SECONDS, 1))
    done = subprocess.run(argv(identify), cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    last = done.stdout.strip().splitlines()[-1]
    print(last)
    before, after = re.search(r"rms_before=([\d.e-]+) rms_after=([\d.e-]+)", last).groups()
    assert before == page_figure(page, r"`rms_before=([\d.]+)") and after == page_figure(page, r"rms_after=([\d.]+) A`")
    identified = load_rig(tmp_path / "my_drive_identified.yaml")
    assert identified.name == rig.name
    mu = page_figure(page, r"with μ identified at ([\d.]+)")
    assert f"{identified.friction.mu_constant:.4f}" == mu and abs(float(mu) - DRIVE.mu_k) < 1e-3  # the truth's

    # 4. the fit checked on a second run
    write_csv(tmp_path / "my_check.csv", validation(DRIVE, SECONDS, 2))
    done = subprocess.run(argv(estimate), cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    last = done.stdout.strip().splitlines()[-1]
    print(last)
    shown = page_figure(page, r"`(estimate: method=extended_model [^`]*)`").split()
    assert last.split() == shown, (last, shown)
    for method, figures in (("momentum", r"score ([\d.]+) / ([\d.]+) %"),
                            ("observer", r"and ([\d.]+) / ([\d.]+) %\.")):
        done = subprocess.run(argv(estimate.replace("extended_model", method).replace(".csv --quiet",
                                                                                      f"_{method}.csv --quiet")),
                              cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stderr[-3000:]
        line = done.stdout.strip().splitlines()[-1]
        mae, worst = re.search(figures, page).groups()
        assert f"mae_pct={mae} max_pct={worst} " in line, (method, line)

    # 5. the estimator on the robot's /joint_states, without and with the page's load prior
    data = robot_states(3000)
    # the robot's joints: a shoulder (at rest) and the elbow, our drive
    np.savez(tmp_path / "robot.npz", names=np.array(["shoulder", "elbow"]),
             **{k: np.column_stack([np.zeros_like(v), v]) for k, v in data.items()})
    assert "-p load_min:=0.0 -p load_max:=1.96" in with_prior and with_prior.startswith(estimator)
    for command in (estimator, with_prior):
        estimates, joints = run_node(command, tmp_path, ros_env)
        settled = [e.torque for e in estimates[len(estimates) // 2:]]  # the second half of the 6 s run
        assert len(settled) > 100, len(estimates)
        print(f"elbow: {np.mean(settled):.4f} N m estimated, {LOAD} N m applied, {len(estimates)} estimates")
        assert np.mean(settled) == pytest.approx(LOAD, abs=0.01)
        assert all(j.name == ["elbow"] for j in joints) and joints
