"""Benchmark of the live node graph over DDS: rate, command latency and lost samples.

    python bench/graph_bench.py          (run_all.py runs it with its own ROS_DOMAIN_ID)

Starts the graph of sim_graph.yaml (calibration written first, speed set-point
150 rad/s, a resistive load of +0.15 N m), lets it settle, then a probe in this
process listens for WINDOW seconds and prints to stdout:

  graph_rate: <x> Hz            /rig/sample messages received per second
  graph_latency_p99: <x> ms     p99 of DriveCommand.header.stamp - feedforward_stamp
                                (commands with feedforward): rig sample stamped -> command out
  graph_lost_samples: <n>       seqs missing between consecutive /rig/sample messages

Progress goes to stderr. Never asserts: a failure prints nan figures and exits 1.
"""
from __future__ import annotations

import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

WINDOW = 10.0  # [s]
SETTLE = 3.0  # [s] after the load command, before the window
SPEED_SETPOINT = 150.0  # [rad/s]
LOAD = 0.15  # [N m], resistive at positive speed
START_TIMEOUT = 45.0  # [s]
REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"


def info(text: str) -> None:
    print(f"[graph_bench] {text}", file=sys.stderr, flush=True)


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))]


def main() -> int:
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 230)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    import rclpy
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.task import Future
    from worm_msgs.msg import DriveCommand, LoadCommand, RigSample

    from torque_estimator.graph.runner import Graph, parse_overrides
    from worm_model.ros.qos import COMMAND

    probe_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500, reliability=ReliabilityPolicy.BEST_EFFORT)
    work = Path(tempfile.mkdtemp(prefix="graph_bench_"))
    calibration = work / "calibration.json"
    info(f"domain {os.environ['ROS_DOMAIN_ID']}, work dir {work}")
    subprocess.run([sys.executable, "-m", "torque_estimator.calibration.calibrate", "--out", str(calibration), "--quiet"],
                   check=True, stdout=sys.stderr)

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("graph_bench_probe", context=context)
    executor = EventsExecutor(context=context)
    executor.add_node(node)

    def spin_for(seconds: float) -> None:
        executor.spin_until_future_complete(Future(executor=executor), timeout_sec=seconds)

    samples: list[tuple[float, int]] = []  # (receive time, seq)
    latencies: list[float] = []  # [s]
    sample_latencies: list[float] = []  # [s] command stamp - stamp of the sample it responds to (stderr only)
    window = [False]

    def on_sample(msg: RigSample) -> None:
        if window[0]:
            samples.append((time.monotonic(), msg.seq))
        elif not samples:
            samples.append((time.monotonic(), msg.seq))  # the first one only says "flowing"

    def on_command(msg: DriveCommand) -> None:
        ff, sent = msg.feedforward_stamp, msg.header.stamp
        if window[0]:
            sample_latencies.append((sent.sec - msg.sample_stamp.sec) + (sent.nanosec - msg.sample_stamp.nanosec) * 1e-9)
        if window[0] and (ff.sec or ff.nanosec):
            latencies.append((sent.sec - ff.sec) + (sent.nanosec - ff.nanosec) * 1e-9)

    overrides = parse_overrides([f"estimator_node.calibration_file={calibration}",
                                 f"controller_node.speed_setpoint={SPEED_SETPOINT}"])
    graph = Graph(GRAPH_FILE, overrides, work / "logs")
    code = 0
    rate = p99 = float("nan")
    lost: float | int = float("nan")
    try:
        graph.start()
        node.create_subscription(RigSample, "/rig/sample", on_sample, probe_qos)
        node.create_subscription(DriveCommand, "/rig/drive_command", on_command, probe_qos)
        load_pub = node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)
        deadline = time.monotonic() + START_TIMEOUT
        while not samples and not graph.failed() and time.monotonic() < deadline:
            spin_for(0.1)
        if not samples:
            raise RuntimeError(f"/rig/sample did not flow within {START_TIMEOUT:g} s (exited: {graph.failed()}); "
                               f"logs in {work / 'logs'}")
        load_pub.publish(LoadCommand(torque=LOAD))
        info(f"graph up; load {LOAD:+g} N m, speed {SPEED_SETPOINT:g} rad/s; settling {SETTLE:g} s")
        spin_for(SETTLE)
        samples.clear()
        window[0] = True
        t0 = time.monotonic()
        spin_for(WINDOW)
        t1 = time.monotonic()
        window[0] = False
        info(f"window {t1 - t0:.2f} s: {len(samples)} samples, {len(latencies)} commands with feedforward")
        in_window = [seq for t, seq in samples if t <= t1]
        rate = len(in_window) / (t1 - t0)
        seqs = [seq for _, seq in samples]
        lost = sum(b - a - 1 for a, b in zip(seqs, seqs[1:]) if b > a + 1)
        reordered = sum(1 for a, b in zip(seqs, seqs[1:]) if b <= a)
        if reordered:
            info(f"{reordered} samples out of order or duplicated")
        p99 = percentile(latencies, 99) * 1e3
        info(f"sample -> feedforward command: p50 {percentile(latencies, 50) * 1e3:.2f} ms, "
             f"max {max(latencies, default=float('nan')) * 1e3:.2f} ms; sample -> its command: "
             f"p50 {percentile(sample_latencies, 50) * 1e3:.2f} ms, p99 {percentile(sample_latencies, 99) * 1e3:.2f} ms")
        if graph.failed():
            info(f"nodes exited during the run: {graph.failed()}")
            code = 1
    except Exception as err:  # a benchmark reports, it does not assert
        info(f"failed: {err!r}")
        code = 1
    finally:
        codes = graph.stop()
        if any(codes.values()):
            info(f"node exit codes {codes}; logs in {work / 'logs'}")
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    print(f"graph_rate: {rate:.1f} Hz")
    print(f"graph_latency_p99: {p99:.2f} ms")
    print(f"graph_lost_samples: {lost}")
    return code


if __name__ == "__main__":
    raise SystemExit(main())
