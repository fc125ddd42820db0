"""Benchmark of estimator_node on a robot's /joint_states: one estimator for 6 joints from a 1 kHz JointState.

    python bench/joint_state_bench.py [--window 20] [--joints 6] [--method extended_model]
                                      (run_all.py runs it with its own ROS_DOMAIN_ID)

Six simulated drives (the bundled NMRV030 rig, each its own seed, speed and load steps) are run
offline first; a publisher process then plays them as ros2_control's joint_state_broadcaster
publishes a robot (every joint in one sensor_msgs/JointState per 1 ms tick, the names in another
order than joint_names, output-shaft position and velocity, effort the drive current; reliable,
depth 10), paced on absolute 1 ms deadlines, with a seventh joint the estimator is not asked about.
estimator_node (``input: joint_state``, the method's defaults, publishing every 5th tick) estimates
the six joints; both processes run as on a rig computer (SCHED_FIFO, graph.runner's priority) when
permitted. Prints to stdout:

  joint_state_estimator_cpu_cores: <x> cores     estimator_node's process CPU over the window / window
  joint_state_estimator_lost_messages: <n>       JointStates the estimator never got (its per-joint
                                                 seq gaps from the stamps, /diagnostics), the worst joint
  joint_state_estimator_max_abs_diff: <x> N m    largest |published estimate - the same joint's samples
                                                 through a single-drive LiveEstimator that filters every
                                                 sample and maps those published| (the method's own
                                                 figures hold for every joint when this is round-off)
  joint_state_publisher_cpu_cores: <x> cores     the publisher's (the stand-in for joint_state_broadcaster)

Progress on stderr. Never asserts: a failure prints nan figures and exits 1.
"""
from __future__ import annotations

import argparse
import math
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from graph_bench import cpu_seconds  # noqa: E402  (the same CPU accounting as the graph benchmark)

START_TIMEOUT = 60.0  # [s]
PUBLISH_EVERY = 5



def info(text: str) -> None:
    print(f"[joint_state_bench] {text}", file=sys.stderr, flush=True)


def simulate(joints: int, samples: int) -> dict[str, np.ndarray]:
    """``joints`` drives of the bundled rig held at their speeds, a load step each: every sample's values."""
    from worm_model.physics.parameters import load_rig
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController
    from worm_rig_driver.sim.simulated_rig import SimulatedRig

    rig = load_rig(None)
    sim = SimulatedRig(rig, n=joints, seed=11)
    controller = SpeedController(rig, DEFAULT_GAINS, n=joints)
    speeds = np.linspace(-150.0, 150.0, joints) + 20.0  # no drive at standstill
    steps = np.linspace(0.2, 0.8, joints) * samples
    omega, current, theta = (np.empty((samples, joints)) for _ in range(3))
    for k in range(samples):
        sim.command(load_torque=np.where(k >= steps, 0.12, 0.02))
        m = sim.sample()
        omega[k], current[k], theta[k] = m.omega_worm, m.current_drive, m.theta_worm
        sim.command(voltage_drive=controller.update(sim.sample_period, speeds, m.omega_worm).voltage)
    ratio = rig.gearbox.ratio
    return {"omega": omega, "current": current, "theta": theta, "ratio": np.array(ratio)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--window", type=float, default=20.0, help="seconds of 1 kHz joint states measured")
    parser.add_argument("--joints", type=int, default=6, help="joints estimated")
    parser.add_argument("--method", default="", help="estimator method (default: estimator_node's on a JointState)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 230)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    figures = {"cpu_cores": math.nan, "lost_messages": math.nan, "max_abs_diff": math.nan,
               "publisher_cpu_cores": math.nan}
    try:
        figures.update(run(args))
        code = 0
    except Exception as err:  # noqa: BLE001 - a benchmark reports, it does not assert
        info(f"failed: {err!r}")
        code = 1
    print(f"joint_state_estimator_cpu_cores: {figures['cpu_cores']:.3f} cores", flush=True)
    print(f"joint_state_estimator_lost_messages: {figures['lost_messages']:g}", flush=True)
    print(f"joint_state_estimator_max_abs_diff: {figures['max_abs_diff']:.3g} N m", flush=True)
    print(f"joint_state_publisher_cpu_cores: {figures['publisher_cpu_cores']:.3f} cores", flush=True)
    return code


def run(args: argparse.Namespace) -> dict[str, float]:
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from worm_msgs.msg import TorqueEstimate

    from torque_estimator.estimation.live import estimate_filtered
    from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
    from torque_estimator.graph.runner import RIG_COMPUTER_PRIORITY, Graph
    from torque_estimator.joints.settings import JOINT_STATE_METHOD
    from worm_model.ros.testing import probe_node
    from worm_rig_driver.drive.realtime import realtime_permitted

    method = args.method or JOINT_STATE_METHOD
    work = Path(tempfile.mkdtemp(prefix="joint_state_bench_"))
    samples = int(round(args.window * 1000))
    info(f"domain {os.environ['ROS_DOMAIN_ID']}, work dir {work}; simulating {args.joints} drives, {samples} samples")
    sim = simulate(args.joints, samples)
    names = [f"joint_{k + 1}" for k in range(args.joints)]
    ratio = float(sim["ratio"])
    base = (time.time_ns() // 5_000_000) * 5_000_000
    extra = np.zeros((samples, 1))
    data = work / "joints.npz"
    # the robot's order: reversed, an extra joint first
    np.savez(data, names=np.array([*names, "wrist"])[::-1], base_ns=base,
             position=np.hstack([sim["theta"] * ratio, extra])[:, ::-1],
             velocity=np.hstack([sim["omega"] * ratio, extra])[:, ::-1],
             effort=np.hstack([sim["current"], extra])[:, ::-1])
    graph_file = work / "graph.yaml"
    graph_file.write_text(
        "estimator_node:\n  ros__parameters:\n    input: joint_state\n"
        f"    joint_names: [{', '.join(names)}]\n    joint_side: output\n    effort_is: current\n"
        f"    method: {method}\n    publish_every: {PUBLISH_EVERY}\n", encoding="utf-8")
    priority = RIG_COMPUTER_PRIORITY if realtime_permitted(RIG_COMPUTER_PRIORITY) else 0
    graph = Graph(graph_file, {}, work / "logs", priority=priority)
    got: dict[str, list] = {n: [] for n in names}
    health: dict[str, str] = {}
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000, reliability=ReliabilityPolicy.BEST_EFFORT)
    figures: dict[str, float] = {}
    try:
        graph.start()
        with probe_node("joint_state_bench_probe") as (node, executor):
            for name in names:
                node.create_subscription(TorqueEstimate, f"/torque_estimate/{name}", got[name].append, qos)
            node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: health.update(
                {kv.key: kv.value for s in m.status if s.hardware_id == "/estimator_node" for kv in s.values}), 100)
            deadline = time.monotonic() + START_TIMEOUT
            while not node.count_publishers(f"/torque_estimate/{names[-1]}") and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.1)
            # /diagnostics reports at 1 Hz: the publisher stays 2.5 s after its last message
            command = [sys.executable, "-m", "worm_model.ros.joint_state_player", str(data), "--tail", "2.5"]
            if priority:
                command = ["chrt", "-f", str(priority), *command]
            publisher = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=open(work / "publisher.log", "wb"),
                                         text=True)
            estimator_pid = next(iter(graph.processes.values())).pid
            while not (work / "publisher.log").read_text(errors="replace").startswith("publishing") \
                    and publisher.poll() is None and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.05)
            before = (cpu_seconds(estimator_pid), cpu_seconds(publisher.pid), time.monotonic())
            info(f"publishing {args.window:g} s of /joint_states at 1 kHz for {args.joints} joints ({method})")
            done_at = None
            while publisher.poll() is None:
                executor.spin_once(timeout_sec=0.05)
                if done_at is None and _line_ready(publisher):
                    done_at = (cpu_seconds(estimator_pid), cpu_seconds(publisher.pid), time.monotonic())
            after = done_at or (cpu_seconds(estimator_pid), math.nan, time.monotonic())
            for _ in range(20):
                executor.spin_once(timeout_sec=0.05)
        elapsed = after[2] - before[2]
        figures["cpu_cores"] = (after[0] - before[0]) / elapsed
        figures["publisher_cpu_cores"] = (after[1] - before[1]) / elapsed
        figures["lost_messages"] = max(int(health.get(f"{n}.samples_lost", "nan") or 0) + sum(
            int(health.get(f"{n}.{r}", 0)) for r in ("absent", "missing_field", "not_finite", "repeated",
                                                     "out_of_order", "early")) for n in names)
        info(f"estimator diagnostics: messages {health.get('messages')}, "
             + ", ".join(f"{n}: samples {health.get(f'{n}.samples')} lost {health.get(f'{n}.samples_lost')}"
                         for n in names))
    finally:
        graph.stop()
    # each joint's published estimates against its samples through one single-drive LiveEstimator that filters
    # every sample and maps the published ones (estimator_node's way on a JointState: joints.estimators)
    built = build_estimator(EstimatorSettings(method))
    worst = 0.0
    index = {base + k * 1_000_000: k for k in range(samples)}
    for j, name in enumerate(names):
        received = {index.get(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec): m.torque
                    for m in got[name]}
        live = built.live(1e-3)
        for k in range(samples):
            filtered = live.filter(float(sim["omega"][k, j]), float(sim["current"][k, j]),
                                   float(sim["theta"][k, j]), k)
            if k in received:
                direct = live.judge(estimate_filtered(built.estimator, [filtered])[0]).torque
                worst = max(worst, abs(received[k] - direct))
        info(f"{name}: {len(got[name])} estimates received")
    figures["max_abs_diff"] = worst
    return figures


def _line_ready(process: subprocess.Popen) -> bool:
    """Whether the publisher printed its 'done' line (non-blocking)."""
    import select
    ready, _, _ = select.select([process.stdout], [], [], 0)
    return bool(ready) and "done" in process.stdout.readline()


if __name__ == "__main__":
    raise SystemExit(main())
