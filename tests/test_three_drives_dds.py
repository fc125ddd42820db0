"""System test: three simulated drives side by side in namespaces, one estimator fed by their joint states
(ros_ws/src/torque_estimator/config/three_drives.yaml, as shipped), and no cross-talk.

Each drive (/arm/joint1: the NMRV030 i=30, /arm/joint2: the T-RO 60:1 worm drive, /arm/joint3: the
NMRV030 i=15) runs its sim_node and controller_node in its namespace; joint_state_merger publishes
them as one /joint_states at 1 kHz; estimator_node estimates every joint from it. The graph runs as a
rig computer runs it (run_graph's rig_computer: real-time priority, each rig alone, the rest of each
namespace in one process), and so does the recorder that keeps what is judged (the estimates, joint1's
truth): the judging reads its bag, so a starved test process loses nothing.

A load step on joint1 alone (on /arm/joint1/rig/load_command, as `ros2 topic pub` would send it)
moves joint1's estimate by the step and leaves the other two within their noise: their mean over a
window after the step differs from the one before by less than NOISE_SIGMAS standard deviations of
their own estimates before it (the estimates are smoothed, so neighbours are not independent: their
standard deviation, not its error of the mean, is the noise), and by less than 5 % of joint1's step.
Windows are of the drives' own time (the streams' stamps), never the test's wall clock.

A second recorder, started in the graph's root with its default topic list, records every drive's
streams under their namespaces and leaves out each drive's per-sample copy (rig/sample, a relative
exclude: in any namespace).
"""
from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import numpy as np
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from worm_msgs.msg import LoadCommand, SimTruths

from torque_estimator.graph.runner import RIG_COMPUTER_PRIORITY, Graph, rig_computer
from worm_model.bags.reader import BagReader
from worm_model.bags.writer import read_messages
from worm_model.rig_data.samples import batch_stamps_ns
from worm_model.ros.ament import find_executable
from worm_model.ros.qos import COMMAND
from worm_model.ros.testing import probe_node, stop_process
from worm_rig_driver.drive.realtime import realtime_permitted

REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "three_drives.yaml"
JOINTS = ("joint1", "joint2", "joint3")
STEP = 0.15  # [N m] on joint1
WARM_UP = 2.0  # [s] of drive time after the recording starts (the estimators' filters settle)
WINDOW = 2.0  # [s] of drive time before the step, and after it has settled
SETTLE = 0.5  # [s] after the step
NOISE_SIGMAS = 2.0
#: estimates needed in a window (of 400 published): on a loaded machine the estimator may fall behind and
#: lose JointStates (best effort: its /diagnostics count them); the test judges what arrives
ENOUGH = 100
START_TIMEOUT = 90.0  # [s] eight Python processes on a loaded 2-core machine
JUDGED = [f"/torque_estimate/{j}" for j in JOINTS] + ["/arm/joint1/sim/truth_samples", "/diagnostics"]
PROBE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=2000, reliability=ReliabilityPolicy.BEST_EFFORT)


def recorder(bag: Path, env: dict[str, str], log: Path, topics: list[str] | None = None,
             priority: int = 0) -> subprocess.Popen:
    command = [str(find_executable("recorder")), "--ros-args", "-p", f"output:={bag}", "-p", "discovery_period:=0.2"]
    if topics:
        command += ["-p", f"topics:=[{','.join(topics)}]"]
    if priority:
        command = ["chrt", "-f", str(priority), *command]
    return subprocess.Popen(command, env=env, stdout=open(log, "wb"), stderr=subprocess.STDOUT)


def stamp_s(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def test_a_load_step_on_one_drive_moves_only_its_estimate(ros_env: dict[str, str], tmp_path: Path) -> None:
    graph = Graph(GRAPH_FILE, {}, tmp_path / "logs", **rig_computer(GRAPH_FILE))
    priority = RIG_COMPUTER_PRIORITY - 10 if realtime_permitted(RIG_COMPUTER_PRIORITY - 10) else 0
    judged, everything = tmp_path / "judged", tmp_path / "everything"
    truth: list = []
    processes: list[subprocess.Popen] = []
    try:
        graph.start()
        processes.append(recorder(judged, ros_env, tmp_path / "judged.log", JUDGED, priority))
        processes.append(recorder(everything, ros_env, tmp_path / "everything.log"))
        logs = lambda name: (tmp_path / f"{name}.log").read_text(errors="replace")  # noqa: E731
        with probe_node("three_drives_probe") as (node, executor):
            node.create_subscription(SimTruths, "/arm/joint1/sim/truth_samples", truth.append, PROBE_QOS)
            load = node.create_publisher(LoadCommand, "/arm/joint1/rig/load_command", COMMAND)

            def spin_until(done, timeout: float) -> bool:
                deadline = time.monotonic() + timeout
                while not done() and time.monotonic() < deadline and not graph.failed():
                    executor.spin_once(timeout_sec=0.05)
                return done()

            def drive_time() -> float:
                return stamp_s(truth[-1].header) if truth else 0.0

            assert spin_until(lambda: truth and load.get_subscription_count() and "Recording /torque_estimate/joint3"
                              in logs("judged") and "Recording /arm/joint3/rig/samples" in logs("everything"),
                              START_TIMEOUT), f"the graph did not start (exited {graph.failed()}); logs in {tmp_path}"
            start = drive_time()
            assert spin_until(lambda: drive_time() > start + WARM_UP + WINDOW, START_TIMEOUT), "the drives stopped"
            processes[-1].send_signal(signal.SIGINT)  # the default topic list: seen enough of it (load off the step)
            load.publish(LoadCommand(torque=STEP))
            assert spin_until(lambda: any(max(b.tau_load) > 0.5 * STEP for b in truth[-20:]), START_TIMEOUT), \
                "joint1's load never stepped"
            stepped = min(stamp_s(b.header) for b in truth if max(b.tau_load) > 0.5 * STEP)
            assert spin_until(lambda: drive_time() > stepped + SETTLE + WINDOW + 0.5, START_TIMEOUT), \
                "the drives stopped"
            load.publish(LoadCommand(torque=0.0))
            executor.spin_once(timeout_sec=0.1)
    finally:
        for process in processes:
            process.send_signal(signal.SIGINT)
            stop_process(process, grace=30.0)
        codes = graph.stop()
    assert all(code == 0 for code in codes.values()), f"unclean exits {codes}; logs in {graph.log_dir}"

    # the step on joint1's own clock, from the recorded truth (every sample's)
    stepped = min(t * 1e-9 for _, m in read_messages(judged, "/arm/joint1/sim/truth_samples")
                  for t, tau in zip(batch_stamps_ns(m, len(m.tau_load)), m.tau_load) if tau > 0.5 * STEP)
    health = {s.hardware_id: {kv.key: kv.value for kv in s.values} for _, m in read_messages(judged, "/diagnostics")
              for s in m.status}
    moved = {}
    for joint in JOINTS:
        torque = [(stamp_s(m.header), m.torque) for _, m in read_messages(judged, f"/torque_estimate/{joint}")]
        before = np.array([tau for t, tau in torque if stepped - WINDOW <= t < stepped])
        after = np.array([tau for t, tau in torque if stepped + SETTLE <= t < stepped + SETTLE + WINDOW])
        assert len(before) > ENOUGH and len(after) > ENOUGH, (joint, len(before), len(after),
                                                             health.get("/estimator_node"))
        moved[joint] = (float(np.mean(after) - np.mean(before)), float(np.std(before)))
    print(moved, health.get("/estimator_node"))
    change, _noise = moved["joint1"]
    assert abs(change - STEP) < 0.1 * STEP, f"joint1's estimate moved {change:+.4f} N m for a {STEP} N m step"
    for joint in ("joint2", "joint3"):
        change, noise = moved[joint]
        assert abs(change) < NOISE_SIGMAS * noise and abs(change) < 0.05 * STEP, (
            f"{joint}'s estimate moved {change:+.5f} N m when joint1's load stepped (noise {noise:.5f})")

    with BagReader(everything) as reader:
        topics = set(reader.topics)
    for joint in JOINTS:
        assert f"/arm/{joint}/rig/samples" in topics and f"/torque_estimate/{joint}" in topics, sorted(topics)
        assert f"/arm/{joint}/rig/sample" not in topics, f"/arm/{joint}/rig/sample recorded despite the exclude"
    assert "/joint_states" in topics
