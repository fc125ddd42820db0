"""Benchmark of DDS discovery: how long a process started beside a running graph waits before it hears it.

    python bench/discovery_bench.py [--starts 14] [--ranges SUBNET,LOCALHOST] [--transports UDPv4]
                                    (run_all.py runs it with its own ROS_DOMAIN_ID)

Every node that is started again (a respawn, a recorder restarted beside its graph) waits for DDS to
discover the graph before it can take a message: a floor under the chaos run's "outputs back within 2 s"
that no code of this project sets. This measures it without any of that code in the way: for each
ROS_AUTOMATIC_DISCOVERY_RANGE of --ranges, the graph of sim_graph.yaml runs (`run_graph`, one process per
node) and --starts times a bare rclpy process (this script with --probe: rclpy.init, one node, nothing
else) starts beside it, polls the graph every 10 ms for /rig/samples, subscribes to it with the streams'
QoS once it is known, and reports, suffixed with the range (_subnet, _localhost):

  dds_discovery_p50: <x> s        from its rclpy.init to /rig/samples' publisher known to it
  dds_discovery_max: <x> s        (the graph's topic list, what a recorder polls)
  dds_first_sample_p50: <x> s     from its rclpy.init to the first /rig/samples message it took
  dds_first_sample_max: <x> s
  dds_probe_start_p50: <x> s      from the probe's process start to its rclpy.init (Python and rclpy
                                  imports: what every node pays before discovery begins)

A probe that heard nothing within 15 s counts as infinitely late (inf).

--transports sets FASTDDS_BUILTIN_TRANSPORTS for the probes only (e.g. UDPv4: no shared memory), to
compare Fast DDS's transports. Progress on stderr. Never asserts: a failure prints nan figures and
exits 1.
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

HERE = Path(__file__).resolve().parent
GRAPH_FILE = HERE.parent / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
TOPIC = "/rig/samples"
POLL_S = 0.010  # [s] the probe's graph polling period
PROBE_LIMIT_S = 15.0  # [s] a probe that hears nothing for this long reports nan (counted inf: late)
SETTLE_S = 8.0  # [s] the graph runs this long before the first probe
GAP_S = 0.5  # [s] between probes
METRICS = ("discovery", "first_sample", "probe_start")
RANGES = ("SUBNET", "LOCALHOST", "OFF", "SYSTEM_DEFAULT")  # ROS_AUTOMATIC_DISCOVERY_RANGE's values


def info(text: str) -> None:
    print(f"[discovery_bench] {text}", file=sys.stderr, flush=True)


def probe(started: float) -> int:
    """One bare rclpy process: prints '<start> <discovery> <first sample>' [s] on stdout."""
    import rclpy
    from rclpy.node import Node
    from worm_msgs.msg import RigSamples
    from worm_model.ros.qos import STREAM

    init = time.time()
    rclpy.init()
    node = Node("discovery_probe")
    known = first = math.nan
    taken: list[float] = []
    try:
        while time.time() - init < PROBE_LIMIT_S:
            if math.isnan(known) and TOPIC in (name for name, _types in node.get_topic_names_and_types()):
                known = time.time() - init
                node.create_subscription(RigSamples, TOPIC, lambda _m: taken.append(time.time()), STREAM)
            rclpy.spin_once(node, timeout_sec=POLL_S)
            if taken:
                first = taken[0] - init
                break
    finally:
        node.destroy_node()
        rclpy.shutdown()
    print(f"{init - started:.4f} {known:.4f} {first:.4f}", flush=True)
    return 0


def late(values: list[float]) -> list[float]:
    """The probes' times with one that heard nothing counted as infinitely late."""
    return [v if math.isfinite(v) else math.inf for v in values]


def measure(starts: int, discovery_range: str, transports: str | None) -> dict[str, list[float]]:
    """Per figure, each probe's time [s] (module docstring), the graph and the probes on ``discovery_range``."""
    from torque_estimator.graph.runner import Graph

    work = Path(tempfile.mkdtemp(prefix="discovery_bench_"))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = discovery_range  # the graph's (Graph takes this environment)
    env = dict(os.environ)
    if transports:
        env["FASTDDS_BUILTIN_TRANSPORTS"] = transports
    times: dict[str, list[float]] = {name: [] for name in METRICS}
    with Graph(GRAPH_FILE, {}, work / "logs") as graph:
        info(f"{discovery_range}: graph of {GRAPH_FILE.name} starting; {starts} probes after {SETTLE_S:g} s")
        time.sleep(SETTLE_S)
        if graph.failed():
            raise RuntimeError(f"the graph's processes ended: {graph.failed()} (logs: {work / 'logs'})")
        for k in range(starts):
            done = subprocess.run([sys.executable, str(Path(__file__).resolve()), "--probe", f"{time.time():.6f}"],
                                  env=env, capture_output=True, text=True, timeout=PROBE_LIMIT_S + 30)
            fields = (done.stdout.split() + ["nan"] * 3)[:3] if done.returncode == 0 else ["nan"] * 3
            start, known, first = (float(x) for x in fields)
            for name, value in zip(("probe_start", "discovery", "first_sample"), (start, known, first)):
                times[name].append(value)
            info(f"probe {k + 1}/{starts}: start {start:.2f} s, {TOPIC} known {known:.2f} s, "
                 f"first message {first:.2f} s after rclpy.init")
            time.sleep(GAP_S)
    return times


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--starts", type=int, default=14, help="probe processes started one after another")
    parser.add_argument("--ranges", default="SUBNET,LOCALHOST",
                        help="comma-separated ROS_AUTOMATIC_DISCOVERY_RANGE values measured, each with a graph of its "
                             "own (default SUBNET,LOCALHOST)")
    parser.add_argument("--transports", default=None,
                        help="FASTDDS_BUILTIN_TRANSPORTS of the probes (e.g. UDPv4; default: Fast DDS's own)")
    parser.add_argument("--probe", type=float, default=None, metavar="START",
                        help="run as one probe, START the wall time [s] its parent started it at (used by the "
                             "benchmark itself)")
    args = parser.parse_args(argv)
    if args.probe is not None:
        return probe(args.probe)
    if args.starts < 1:
        parser.error(f"--starts must be >= 1, got {args.starts}")
    ranges = [r.strip().upper() for r in args.ranges.split(",") if r.strip()]
    if not ranges or set(ranges) - set(RANGES):
        parser.error(f"--ranges: each of {', '.join(RANGES)}, got {args.ranges!r}")
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 230)))
    # graph_bench's nearest rank, imported here (bench/ is on sys.path: the scripts run from it), not where a probe
    # would pay for its imports before rclpy.init
    from graph_bench import percentile

    code = 0
    for discovery_range in ranges:
        try:
            times = measure(args.starts, discovery_range, args.transports)
        except Exception as err:  # noqa: BLE001 - a benchmark reports, it does not assert
            info(f"failed: {err!r}")
            times, code = {name: [math.nan] for name in METRICS}, 1
        suffix = f"_{discovery_range.lower()}"
        for name in ("discovery", "first_sample"):
            print(f"dds_{name}_p50{suffix}: {percentile(late(times[name]), 50):.2f} s", flush=True)
            print(f"dds_{name}_max{suffix}: {percentile(late(times[name]), 100):.2f} s", flush=True)
        print(f"dds_probe_start_p50{suffix}: {percentile(late(times['probe_start']), 50):.2f} s", flush=True)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
