"""docs/new-drive.md, run as an engineer runs it: every command of its four steps, as written on the page, in one
working folder, on a simulated drive standing in for theirs.

1. ``rig_from_datasheet`` writes my_drive.yaml from the page's catalogue and motor numbers: it loads, and its
   geometry is the catalogue's (ratio, centre distance, lead angle).
2. ``worm_calc --rig my_drive.yaml`` checks it (efficiencies, self-locking).
3. ``identify --from my_run.csv`` fits it to a recorded run. The run stands in for the engineer's drive: the
   excitation ``identify`` plays, on the simulator with a drive whose friction and drags the datasheet did not
   know (mu x 1.3, drags x 2: the rig file's assumptions are off as a datasheet's stand-ins are). The fit
   must bring the model's current closer to the run's (its rms_after below rms_before).
4. ``estimator_node`` on the robot's /joint_states (a stand-in robot: that drive as joint "elbow" among
   others, published as joint_state_broadcaster publishes, output side, effort the drive current) with the
   identified file: torque_estimate/elbow follows the load the drive carries, and torque_estimate/joint_states
   names the joint.
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
from worm_model.rig_data.schema import write_rig_csv
from worm_model.ros.ament import find_executable
from worm_model.ros.testing import probe_node, stop_process

REPO = Path(__file__).resolve().parents[1]
PAGE = REPO / "docs" / "new-drive.md"
STEPS = ("## 1.", "## 2.", "## 3.", "## 4.", "## On a test bench")
LOAD = 0.1  # [N m] the stand-in robot's load on the elbow
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


def true_drive(rig_file: Path, folder: Path) -> Path:
    """The engineer's drive as it is: the rig file with friction and drags the datasheet did not know."""
    doc = yaml.safe_load(rig_file.read_text(encoding="utf-8"))
    doc["friction"]["scale"]["value"] *= 1.3
    for motor in ("drive_motor", "load_motor"):
        for drag in ("viscous_drag", "coulomb_drag"):
            doc[motor][drag]["value"] *= 2.0
    path = folder / "true_drive.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def record_run(true_file: Path, out: Path) -> None:
    """The run of step 3: identify's excitation on the simulated true drive, in the rig-data CSV schema."""
    from torque_estimator.identification.excitation import default_excitation
    from torque_estimator.identification.simulated import record_on_simulator

    rig = load_rig(true_file)
    write_rig_csv(out, record_on_simulator(rig, default_excitation(rig), seed=3))


def robot_states(true_file: Path, samples: int) -> dict[str, np.ndarray]:
    """The elbow at SPEED under LOAD, held by the drive's PI: every sample's output-side values."""
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController
    from worm_rig_driver.sim.simulated_rig import SimulatedRig

    rig = load_rig(true_file)
    sim = SimulatedRig(rig, n=1, seed=4)
    controller = SpeedController(rig, DEFAULT_GAINS, n=1)
    rows = []
    for _ in range(samples):
        sim.command(load_torque=LOAD)
        m = sim.sample()
        rows.append((float(m.theta_worm[0]), float(m.omega_worm[0]), float(m.current_drive[0])))
        sim.command(voltage_drive=controller.update(sim.sample_period, np.array([SPEED]), m.omega_worm).voltage)
    theta, omega, current = (np.array(c) for c in zip(*rows))
    return {"position": theta * rig.gearbox.ratio, "velocity": omega * rig.gearbox.ratio, "effort": current}




def test_every_step_of_the_page(ros_env: dict[str, str], tmp_path: Path) -> None:
    commands = page_commands()
    assert [shlex.split(c)[3] for c in commands] == ["rig_from_datasheet", "worm_calc", "identify", "estimator_node"]
    make_rig, check, identify, estimator = commands

    # 1. the rig file from the datasheet
    done = subprocess.run(argv(make_rig), cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    rig = load_rig(tmp_path / "my_drive.yaml")
    words = shlex.split(make_rig)
    given = {w: float(words[words.index(w) + 1]) for w in ("--ratio", "--centre-distance-mm", "--lead-angle-deg")}
    gb = rig.gearbox
    assert 1 / gb.ratio == pytest.approx(given["--ratio"])
    assert (gb.worm_pitch_radius + gb.gear_pitch_radius) * 1e3 == pytest.approx(given["--centre-distance-mm"])
    assert np.degrees(gb.lead_angle) == pytest.approx(given["--lead-angle-deg"])
    assert gb.geometric_ratio == pytest.approx(gb.ratio, rel=1e-5)
    document = yaml.safe_load((tmp_path / "my_drive.yaml").read_text(encoding="utf-8"))
    assert "source" in document["drive_motor"]["torque_constant"] and "assumption" in document["friction"]["scale"]

    # 2. its check
    done = subprocess.run(argv(check), cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "self-locking" in done.stdout, done.stdout + done.stderr

    # 3. identify from a recorded run of "their" drive
    true_file = true_drive(tmp_path / "my_drive.yaml", tmp_path)
    record_run(true_file, tmp_path / "my_run.csv")
    done = subprocess.run(argv(identify), cwd=tmp_path, env=ros_env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    last = done.stdout.strip().splitlines()[-1]
    before, after = (float(x) for x in re.search(r"rms_before=([\d.e-]+) rms_after=([\d.e-]+)", last).groups())
    print(last)
    assert after < 0.8 * before, last
    assert load_rig(tmp_path / "my_drive_identified.yaml").name == rig.name

    # 4. the estimator on the robot's /joint_states
    data = robot_states(true_file, 3000)
    # the robot's joints: a shoulder (at rest) and the elbow, our drive
    np.savez(tmp_path / "robot.npz", names=np.array(["shoulder", "elbow"]),
             **{k: np.column_stack([np.zeros_like(v), v]) for k, v in data.items()})
    estimates: list = []
    joints: list = []
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=2000, reliability=ReliabilityPolicy.BEST_EFFORT)
    node_process = subprocess.Popen(argv(estimator), cwd=tmp_path, env=ros_env, stdout=subprocess.PIPE,
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
                                      str(tmp_path / "robot.npz"), "--period", "0.002", "--wait", "1.0"], env=ros_env)
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
    settled = [e.torque for e in estimates[len(estimates) // 2:]]  # the second half of the 3 s run
    assert len(settled) > 100, len(estimates)
    print(f"elbow: {np.mean(settled):.4f} N m estimated, {LOAD} N m applied, {len(estimates)} estimates")
    assert np.mean(settled) == pytest.approx(LOAD, abs=0.02)
    assert all(j.name == ["elbow"] for j in joints) and joints
