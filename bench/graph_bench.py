"""Benchmark of the live node graph over DDS: CPU, command latency, lost samples; idle and under load.

    python bench/graph_bench.py [--window 60] [--skip-load] [--separate-window 20]
                                 (run_all.py runs it with its own ROS_DOMAIN_ID)

The graph of sim_graph.yaml (the rig's load observer, with the calibration written
first, feeds forward and is the graph's torque_estimate) runs as a rig computer runs it:
sim_node in a process of its own, model_node and controller_node together in another,
both at SCHED_FIFO 40 (`run_graph sim_graph.yaml --together model_node,controller_node
--priority 40`; graph.runner.rig_computer), the recorder (`ros2 run worm_rig_driver
recorder`, the graph's streams /rig/samples, /torque_estimate, /gearbox/forces,
/rig/speed_command) beside it at normal priority. Twice (the second time while a CPU
hog started here holds one core busy at normal priority): commands 150 rad/s and a
resistive load of +0.15 N m, lets it settle, then measures for --window seconds and
prints to stdout:

  graph_cpu_cores: <x> cores          CPU of every process of the graph (sim_node, model_node, controller_node)
  graph_cpu_<process>: <x> cores      each process of the graph (process CPU time over the window / window)
  graph_latency_p50: <x> ms           newest rig sample a speed command was computed from (its stamp)
  graph_latency_p99: <x> ms           -> that command in force at the rig, per command, read from the
                                      recorded /rig/samples' own clock (seq, command_seq): the time from
                                      that sample's stamp to the start of the first period the command
                                      drove, in whole periods (1 ms): a command that missed only the
                                      tick right after its sample counts 1 ms
  graph_lost_samples: <n>             seqs missing from the recorded /rig/samples over the window
  graph_sim_skipped_samples: <n>      sample periods sim_node never simulated (it fell behind real time)

and the same with an ``_under_load`` suffix for the loaded run; then, for comparison,
the graph as `run_graph sim_graph.yaml` starts it by default (one process per node,
normal priority), idle, for --separate-window seconds: the same lines with a
``_separate`` suffix. Progress on stderr.
Never asserts: a failure prints nan figures and exits 1.
"""
from __future__ import annotations

import argparse
import math
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from torque_estimator.graph.runner import rig_computer

SETTLE = 5.0  # [s] after the commands, before the window
SPEED_SETPOINT = 150.0  # [rad/s]
LOAD = 0.15  # [N m], resistive at positive speed
START_TIMEOUT = 45.0  # [s]
REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
RECORDED = ("/rig/samples", "/torque_estimate", "/gearbox/forces", "/rig/speed_command", "/diagnostics")
HZ = os.sysconf("SC_CLK_TCK")


def info(text: str) -> None:
    print(f"[graph_bench] {text}", file=sys.stderr, flush=True)


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, math.ceil(q / 100 * len(ordered)) - 1))]


def cpu_seconds(pid: int) -> float:
    """User + system CPU time [s] of a process and its threads."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / HZ


def start_hog() -> subprocess.Popen:
    """One process spinning one core at 100 % (stopped by the caller)."""
    return subprocess.Popen([sys.executable, "-c", "while True: pass"], env={**os.environ,
                            "_ROS_WHEELS_BOOTSTRAP_COMPLETE": "1"})


def _cpu_over(pids: dict[str, int], wait) -> dict[str, float]:
    """Each process's CPU [cores] while ``wait()`` runs: ``cpu_<name>`` (a group "a+b" as ``a__b``) and their sum."""
    before = {name: cpu_seconds(pid) for name, pid in pids.items()}
    t0 = time.monotonic()
    wait()
    elapsed = time.monotonic() - t0
    after = {name: cpu_seconds(pid) for name, pid in pids.items()}
    cores = {f"cpu_{name.replace('+', '__')}": (after[name] - before[name]) / elapsed for name in pids}
    return {**cores, "cpu_cores": sum(cores.values())}


def run_phase(calibration: Path, work: Path, window: float, hog: bool, together: list[list[str]],
              priority: int = 0) -> dict[str, float]:
    """One measurement; returns the figures by name (without suffix)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    from rclpy.task import Future
    from std_msgs.msg import Float64
    from worm_msgs.msg import LoadCommand

    from torque_estimator.graph.runner import Graph, parse_overrides
    from worm_model.ros.ament import find_executable
    from worm_model.ros.qos import COMMAND

    tag = ("under_load" if hog else "idle") + ("" if together else "_separate")
    bag = work / f"bag_{tag}"
    figures = {name: float("nan") for name in ("cpu_cores", "latency_p50", "latency_p99", "lost_samples",
                                               "sim_skipped_samples")}
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("graph_bench_probe", context=context)
    executor = EventsExecutor(context=context)
    executor.add_node(node)

    def spin_for(seconds: float) -> None:
        executor.spin_until_future_complete(Future(executor=executor), timeout_sec=seconds)

    overrides = parse_overrides([f"sim_node.feedforward_calibration={calibration}",
                                 f"controller_node.speed_setpoint={SPEED_SETPOINT}"])
    graph = Graph(GRAPH_FILE, overrides, work / f"logs_{tag}", together=together, priority=priority)
    recorder = hog_proc = None
    try:
        hog_proc = start_hog() if hog else None
        graph.start()
        recorder = subprocess.Popen([str(find_executable("recorder")), "--ros-args", "-p", f"output:={bag}",
                                     "-p", f"topics:=[{','.join(RECORDED)}]"],
                                    stdout=open(work / f"recorder_{tag}.log", "wb"), stderr=subprocess.STDOUT)
        seen = []
        from worm_msgs.msg import RigSamples
        from worm_model.ros.qos import STREAM
        sub = node.create_subscription(RigSamples, "/rig/samples", lambda m: seen.append(m.first_seq), STREAM)
        deadline = time.monotonic() + START_TIMEOUT
        while not seen and not graph.failed() and time.monotonic() < deadline:
            spin_for(0.1)
        node.destroy_subscription(sub)  # the probe does not listen during the window
        if not seen:
            raise RuntimeError(f"/rig/samples did not flow within {START_TIMEOUT:g} s (exited: {graph.failed()})")
        node.create_publisher(Float64, "/controller/speed_setpoint", COMMAND).publish(Float64(data=SPEED_SETPOINT))
        node.create_publisher(LoadCommand, "/rig/load_command", COMMAND).publish(LoadCommand(torque=LOAD))
        info(f"{tag}: graph up; {SPEED_SETPOINT:g} rad/s, load {LOAD:+g} N m; settling {SETTLE:g} s")
        spin_for(SETTLE)
        pids = {name: proc.pid for name, proc in graph.processes.items()}
        wall0 = time.time_ns()
        figures.update(_cpu_over(pids, lambda: spin_for(window)))
        wall1 = time.time_ns()
        if graph.failed():
            raise RuntimeError(f"nodes exited during the run: {graph.failed()}")
    finally:
        if recorder is not None:
            recorder.send_signal(signal.SIGINT)
            try:
                recorder.wait(30)
            except subprocess.TimeoutExpired:
                recorder.kill()
        codes = graph.stop()
        if hog_proc is not None:
            hog_proc.kill()
            hog_proc.wait()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        if any(codes.values()):
            info(f"{tag}: node exit codes {codes}; logs in {work}")
    figures.update(_figures_from_bag(bag, wall0, wall1, tag, window))
    return figures


def _figures_from_bag(bag: Path, wall0: int, wall1: int, tag: str, window: float) -> dict[str, float]:
    """Latency, losses and sim_node's skipped periods of the samples the recorder kept within [wall0, wall1] [ns]."""
    from worm_model.bags.reader import BagReader
    from worm_model.rig_data.samples import command_latencies, missing_seqs, unbatch

    samples, skipped = [], {"before": 0.0, "end": math.nan}
    with BagReader(bag) as reader:
        for message in reader.messages(["/rig/samples"]):
            stamp = message.decoded.header.stamp
            if wall0 <= stamp.sec * 1_000_000_000 + stamp.nanosec <= wall1:
                samples += unbatch(message.decoded)
        # sim_node's count of periods it never simulated, at the window's start and end (it is cumulative)
        for message in reader.messages(["/diagnostics"]) if "/diagnostics" in reader.topics else ():
            stamp = message.decoded.header.stamp
            ns = stamp.sec * 1_000_000_000 + stamp.nanosec
            for status in message.decoded.status:
                if status.name == "sim_node":
                    values = {kv.key: kv.value for kv in status.values}
                    if ns <= wall0:
                        skipped["before"] = float(values.get("skipped_samples", 0.0))
                    elif ns <= wall1 + 1_000_000_000:  # the report published within 1 s after the window
                        skipped["end"] = float(values.get("skipped_samples", math.nan))
    period_ms = 1.0  # the rig's sample period [ms]
    # from sample s's stamp (the end of its period) to the start of the first period the command drives
    latencies = [k * period_ms for k in command_latencies(samples)]
    info(f"{tag}: {len(samples)} samples recorded in the {window:g} s window, {len(latencies)} commands; "
         f"latency max {max(latencies, default=math.nan):.0f} ms")
    return {"latency_p50": percentile(latencies, 50), "latency_p99": percentile(latencies, 99),
            "lost_samples": missing_seqs(s.seq for s in samples),
            "sim_skipped_samples": skipped["end"] - skipped["before"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--window", type=float, default=60.0, help="measuring window [s] of each run")
    parser.add_argument("--skip-load", action="store_true", help="only the run without the CPU hog")
    parser.add_argument("--separate-window", type=float, default=20.0,
                        help="window [s] of the comparison run with one process per node (0: skip it)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 230)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    work = Path(tempfile.mkdtemp(prefix="graph_bench_"))
    info(f"domain {os.environ['ROS_DOMAIN_ID']}, work dir {work}")
    calibration = work / "calibration.json"
    subprocess.run([sys.executable, "-m", "torque_estimator.calibration.calibrate", "--out", str(calibration),
                    "--quiet"], check=True, stdout=sys.stderr)
    code = 0
    units = {"cpu": "cores", "latency": "ms"}
    rig = rig_computer(GRAPH_FILE)
    runs = [("", False, rig, args.window)] + ([] if args.skip_load else [("_under_load", True, rig, args.window)])
    if args.separate_window > 0:
        runs.append(("_separate", False, {"together": [], "priority": 0}, args.separate_window))
    for suffix, hog, options, window in runs:
        try:
            figures = run_phase(calibration, work, window, hog, options["together"], options["priority"])
        except Exception as err:  # noqa: BLE001 - a benchmark reports, it does not assert
            info(f"failed: {err!r}")
            figures = {}
            code = 1
        names = ("cpu_cores", *sorted(n for n in figures if n.startswith("cpu_") and n != "cpu_cores"),
                 "latency_p50", "latency_p99", "lost_samples", "sim_skipped_samples")
        for name in names:
            value = figures.get(name, float("nan"))
            unit = units.get(name.split("_")[0], "")
            text = f"{value:.3f}" if unit == "cores" else f"{value:.2f}" if unit == "ms" else f"{value:g}"
            print(f"graph_{name}{suffix}: {text} {unit}".rstrip(), flush=True)
    return code


if __name__ == "__main__":
    raise SystemExit(main())
