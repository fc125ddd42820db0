"""Soak of the live node graph: the shipped graph and the recorder for an hour under a changing command profile.

    python bench/soak_bench.py [--minutes 60] [--window 600] [--seed 1] [--chaos] [--work DIR]
    python bench/soak_bench.py --analyse DIR     (the figures of a finished run again, from its files)
    make soak MINUTES=60 SOAK_ARGS="--chaos"

The graph of sim_graph.yaml (the rig's load observer, with the calibration written first, feeds forward and
is the graph's torque_estimate) runs as a rig computer runs it (graph.runner.rig_computer: sim_node in a
process of its own, model_node and controller_node together in another, both at SCHED_FIFO 40), and the
recorder beside it as a user starts it on a rig computer (`chrt -f 30 ros2 run worm_rig_driver recorder
--ros-args -p output:=BAG`: below the graph's priority, as docs/bags-and-tools.md advises; --recorder-priority 0
starts it without chrt; every topic of the graph, the simulator's truth included, which is what makes sim_node
publish it).
This process drives a seeded command profile through controller_node's set-point and the rig's load
command: every window opens with a reference hold (150 rad/s against +0.15 N m, the graph benchmark's
point), then set-point changes, load steps (resistive: opposing the rotation), reversals and idle spells
(0 rad/s, no load) of 5-30 s each (shorter in windows under 10 minutes). It samples every process's RSS
and CPU time every few seconds, the bag's size at every window's end, and the /diagnostics of every node.
After the run it reads the bag back and prints, per window (`_w<i>`, i from 1) and per process:

  soak_rss_<process>_w<i>: <x> MB              resident set at the window's end (/proc/<pid>/status VmRSS)
  soak_cpu_<process>_w<i>: <x> cores           CPU time over the window / its length
  soak_latency_p50_w<i>, _p99_w<i>: <x> ms     newest rig sample a speed command was computed from -> that
                                               command in force at the rig, read from the recorded
                                               /rig/samples' own clock (as bench/graph_bench.py)
  soak_lost_samples_w<i>: <n>                  seqs missing from the recorded /rig/samples in the window
  soak_sim_skipped_samples_w<i>: <n>           periods sim_node never simulated (it fell behind real time)
  soak_bag_growth_w<i>: <x> MB                 what the recorder's bag grew by in the window
  soak_estimate_error_w<i>: <x> N m            steady error of the graph's torque_estimate against the
                                               simulator's true load (/sim/truth_samples, matched by
                                               sample stamp) in the window's reference hold, past its
                                               first 3 s: mean of estimate - truth
  soak_estimate_spread_w<i>: <x> N m           its standard deviation over the same estimates
  soak_estimate_error_all_w<i>: <x> N m        mean |estimate - truth| over every steady spell of the
                                               window (moving, 3 s past a command change)
  soak_host_cpu_w<i>: <x> cores                the whole machine's busy CPU (this run and everyone else's)
  soak_host_loadavg_w<i>: <x>                  the highest 1-minute load average sampled in the window

then over the run: soak_rss_growth_<process> [MB/h] (least-squares slope of the RSS samples after the first
window), soak_latency_p99_rise [ms] (the largest window p99 less the first's), soak_lost_samples,
soak_estimate_error_change [N m] (last window's less the first's), soak_recorder_lost_messages (what the
recorder's own end-of-run line says it lost), soak_diagnostics_gap_<node> [s] (the longest silence of a
node's /diagnostics, 1 Hz when well); a table of the windows; and one verdict line per target:

  verdict rss_growth: PASS|FAIL ...        every process under 1 MB/h after the first window
  verdict latency_p99: PASS|FAIL ...       no window's p99 above the first's by more than 1 ms
  verdict lost_samples: PASS|FAIL ...      0 samples lost
  verdict estimate_error: PASS|FAIL ...    last window's steady error equal to the first's within its spread

With --chaos the same run has faults injected at seeded random moments (bench/soak_chaos.py says which and
what it counts). Progress on stderr. Never asserts: a run that fails prints `soak_failed: 1 (why)` and exits
1, its files left in the work folder.
"""
from __future__ import annotations

import argparse
import bisect
import json
import math
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from graph_bench import cpu_seconds, percentile  # bench/ is on sys.path: the script's folder
from soak_chaos import KINDS as FAULT_KINDS
from torque_estimator.graph.runner import rig_computer
from worm_rig_driver.drive.realtime import realtime_permitted

REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
REF_SPEED = 150.0  # [rad/s] the reference hold's set-point (bench/graph_bench.py's)
REF_LOAD = 0.15  # [N m] and load, resistive at positive speed
SPEEDS = (50.0, 200.0)  # [rad/s] range of a set-point change's magnitude
LOADS = (0.0, 0.2)  # [N m] range of a load step's magnitude (resistive: the sign of the speed)
HOLD = (5.0, 30.0)  # [s] range of a step's duration in a 10-minute window (scaled down in shorter ones)
KINDS = {"setpoint": 3, "load": 3, "reversal": 1, "idle": 1}  # a step's kind and its weight
STEADY_AFTER = 3.0  # [s] after a command change before an estimate counts as steady
SETTLE = 5.0  # [s] after the first commands, before the first window
START_TIMEOUT = 45.0  # [s]
RESOURCE_PERIOD = 5.0  # [s] between two samples of every process's RSS and CPU time
EDGE = 0.5  # [s] a sample this close to a window's edge was taken for that edge (the loop spins 0.2 s at most)
RSS_TARGET = 1.0  # [MB/h]
P99_TARGET = 1.0  # [ms]
HZ = os.sysconf("SC_CLK_TCK")
MB = 1e6
RECORDER = "recorder"
MEASURED = ("/rig/samples", "/sim/truth_samples", "/torque_estimate")  # the recorder records these before t0


def info(text: str) -> None:
    print(f"[soak] {text}", file=sys.stderr, flush=True)


@dataclass(frozen=True)
class Step:
    """One command of the profile: from ``at`` [s after the first window's start] on, this set-point
    [rad/s] and load [N m, positive opposing positive rotation]."""

    at: float
    kind: str
    speed: float
    load: float


def reference_hold(window: float) -> float:
    """[s] of the reference hold that opens every window: a tenth of it, 8 to 60 s."""
    return min(60.0, max(8.0, 0.1 * window))


def command_profile(seed: int, duration: float, window: float) -> list[Step]:
    """The seeded command profile of a run of ``duration`` [s] in windows of ``window`` [s]: each window a
    reference hold, then random steps (KINDS, HOLD long; a tenth of that in windows of a minute or less) to
    its end. A reversal turns the speed and its resistive load
    round; after an idle spell the next step starts the worm in either direction."""
    rng = random.Random(seed)
    scale = min(1.0, max(0.1, window / 600.0))
    steps: list[Step] = []
    for start in [k * window for k in range(max(1, math.ceil(duration / window - 1e-9)))]:
        end = min(start + window, duration)
        speed, load = REF_SPEED, REF_LOAD
        steps.append(Step(start, "reference", speed, load))
        t = start + reference_hold(window)
        while t < end - HOLD[0] * scale:
            kind = rng.choices(list(KINDS), weights=list(KINDS.values()))[0]
            if kind == "idle" and not speed:
                continue  # idle already
            direction = math.copysign(1.0, speed) if speed else rng.choice((-1.0, 1.0))
            if kind == "idle":
                speed, load = 0.0, 0.0
            elif kind == "reversal" and speed:
                speed, load = -speed, -load
            elif kind == "load" and speed:
                load = direction * rng.uniform(*LOADS)
            else:  # a set-point change (also a reversal or load step asked of a worm standing idle)
                kind = "setpoint"
                speed = direction * rng.uniform(*SPEEDS)
                load = direction * abs(load) + 0.0  # + 0.0: no -0.0
            steps.append(Step(round(t, 3), kind, round(speed, 3), round(load, 4)))
            t += rng.uniform(*HOLD) * scale
    return steps


def rss_bytes(pid: int) -> float:
    """Resident set [bytes] of a process (VmRSS).

    Raises:
        ValueError: the process has none (it was killed and is not reaped yet).
    """
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return float(line.split()[1]) * 1024
    raise ValueError(f"process {pid} has no resident set")


def host_busy_seconds() -> float:
    """CPU time [s] every core of the machine spent busy so far (/proc/stat: all but idle and iowait)."""
    fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    return (sum(fields[:8]) - fields[3] - fields[4]) / HZ


def tree_size(path: Path) -> int:
    """[bytes] of every file under ``path`` (0 if it is not there yet)."""
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.exists() else 0


def bag_bytes(work: Path, record: dict) -> int:
    """[bytes] of every bag of the run so far."""
    return sum(tree_size(work / name) for name in record["bags"])


def metric_name(process: str) -> str:
    """A process key as a metric's part: "model_node+controller_node" -> "model_node__controller_node"."""
    return process.strip("/").replace("/", "__").replace("+", "__")


def slope_per_hour(points: list[tuple[float, float]]) -> float:
    """Least-squares slope of (t [s], value) points, per hour (nan under 2 points or no spread in t)."""
    if len(points) < 2:
        return float("nan")
    ts, vs = zip(*points)
    mt, mv = statistics.fmean(ts), statistics.fmean(vs)
    sxx = sum((t - mt) ** 2 for t in ts)
    return float("nan") if sxx == 0 else 3600.0 * sum((t - mt) * (v - mv) for t, v in zip(ts, vs)) / sxx


# --- the run --------------------------------------------------------------------------------------------------

class Processes:
    """Every process of the run by its key (the graph's, and the recorder): pids as they are now (a restarted
    process has a new one), and what they said about their resources."""

    def __init__(self) -> None:
        self.samples: list[dict] = []  # {"t": s, "rss": {key: bytes}, "cpu": {key: s}, "pid": {key: pid}}

    def sample(self, t: float, pids: dict[str, int]) -> dict:
        row = {"t": t, "rss": {}, "cpu": {}, "pid": dict(pids), "host": host_busy_seconds(),
               "load": float(Path("/proc/loadavg").read_text().split()[0])}
        for key, pid in pids.items():
            try:
                row["rss"][key], row["cpu"][key] = rss_bytes(pid), cpu_seconds(pid)
            except (FileNotFoundError, ProcessLookupError, IndexError, ValueError):
                pass  # exited between the listing and the reading
        self.samples.append(row)
        return row


#: SCHED_FIFO priority of the recorder (``chrt -f``), below the graph's 40, as docs/bags-and-tools.md advises on a
#: rig computer; 0 (or a machine that does not permit it): normal scheduling. --recorder-priority changes it.
RECORDER_PRIORITY = 30


def start_recorder(bag: Path, log: Path, priority: int = RECORDER_PRIORITY) -> subprocess.Popen:
    """The recorder as a user starts it on a rig computer: every topic of the graph into ``bag``, at SCHED_FIFO
    ``priority`` (0: normal scheduling)."""
    from worm_model.ros.ament import find_executable

    prefix = ["chrt", "-f", str(priority)] if priority else []
    return subprocess.Popen([*prefix, str(find_executable("recorder")), "--ros-args", "-p", f"output:={bag}"],
                            stdout=open(log, "ab"), stderr=subprocess.STDOUT)


def stop_recorder(recorder: subprocess.Popen) -> int:
    recorder.send_signal(signal.SIGINT)
    try:
        return recorder.wait(60)
    except subprocess.TimeoutExpired:
        recorder.kill()
        return recorder.wait()


def run(args: argparse.Namespace, work: Path) -> dict:
    """Start the graph and the recorder, drive the profile for args.minutes, stop; returns the run's record
    (also written to work/soak.json) for :func:`analyse`."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.experimental import EventsExecutor
    from std_msgs.msg import Float64
    from worm_msgs.msg import LoadCommand, RigSamples

    from torque_estimator.graph.runner import Graph, parse_overrides
    from worm_model.ros.qos import COMMAND, STREAM
    from worm_model.ros.testing import probe_node, spin_until

    duration = 60.0 * args.minutes
    steps = command_profile(args.seed, duration, args.window)
    calibration = work / "calibration.json"
    subprocess.run([sys.executable, "-m", "torque_estimator.calibration.calibrate", "--out", str(calibration),
                    "--quiet"], check=True, stdout=sys.stderr)
    overrides = parse_overrides([f"sim_node.feedforward_calibration={calibration}"])
    chaos = None
    if args.chaos:  # first: it may move this process into a network namespace before any thread starts
        from soak_chaos import Chaos

        def recorder_at_priority(bag: Path, log: Path) -> subprocess.Popen:
            return start_recorder(bag, log, args.recorder_priority)

        chaos = Chaos(args.seed, duration, work, recorder_at_priority, args.faults)
    try:
        graph = Graph(GRAPH_FILE, overrides, work / "logs", **rig_computer(GRAPH_FILE),
                      **(chaos.graph_options(GRAPH_FILE) if chaos else {}))
        record = {"minutes": args.minutes, "window": args.window, "seed": args.seed, "chaos": bool(chaos),
                  "recorder_priority": args.recorder_priority,
                  "steps": [asdict(s) for s in steps], "events": [], "bags": [], "bag_sizes": [], "diagnostics": {}}
        procs = Processes()
        recorder = None
        heard: dict[str, list[float]] = {}  # node name -> receive times [s after t0] of its /diagnostics

        with probe_node("soak_probe", EventsExecutor) as (node, executor):
            t_zero = [time.monotonic()]

            def on_diagnostics(msg) -> None:
                for status in msg.status:
                    heard.setdefault(status.name, []).append(time.monotonic() - t_zero[0])

            node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
            setpoint = node.create_publisher(Float64, "/controller/speed_setpoint", COMMAND)
            load = node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)
            try:
                graph.start()
                bag = work / "bag"
                recorder = start_recorder(bag, work / "recorder.log", args.recorder_priority)
                record["bags"].append(bag.name)
                if chaos is not None:
                    chaos.start_station()
                seen: list[int] = []
                sub = node.create_subscription(RigSamples, "/rig/samples", lambda m: seen.append(m.first_seq), STREAM)
                if not spin_until(executor, lambda: bool(seen) or bool(graph.failed()), START_TIMEOUT) or not seen:
                    raise RuntimeError(f"/rig/samples did not flow within {START_TIMEOUT:g} s "
                                       f"(exited: {graph.failed()}); logs in {work}")
                node.destroy_subscription(sub)  # the probe does not listen to the stream during the run
                log = work / "recorder.log"
                if not spin_until(executor, lambda: all(f"Recording {t} " in log.read_text(errors="replace")
                                                        for t in MEASURED), START_TIMEOUT):
                    raise RuntimeError(f"the recorder did not subscribe to {', '.join(MEASURED)} within "
                                       f"{START_TIMEOUT:g} s; its log: {log}")
                setpoint.publish(Float64(data=steps[0].speed))
                load.publish(LoadCommand(torque=steps[0].load))
                info(f"graph up; {len(steps)} commands over {args.minutes:g} min in windows of {args.window:g} s; "
                     f"settling {SETTLE:g} s")
                spin_until(executor, lambda: False, SETTLE)
                t0_wall, t_zero[0] = time.time_ns(), time.monotonic()
                record["t0_ns"] = t0_wall
                heard.clear()

                def pids() -> dict[str, int]:
                    alive = {key: proc.pid for key, proc in graph.processes.items() if proc.poll() is None}
                    if recorder is not None and recorder.poll() is None:
                        alive[RECORDER] = recorder.pid
                    return alive

                procs.sample(0.0, pids())
                record["bag_sizes"].append((0.0, bag_bytes(work, record)))
                next_step, next_resource, window_end = 1, RESOURCE_PERIOD, args.window
                while (now := time.monotonic() - t_zero[0]) < duration:
                    while next_step < len(steps) and steps[next_step].at <= now:
                        step = steps[next_step]
                        setpoint.publish(Float64(data=step.speed))
                        load.publish(LoadCommand(torque=step.load))
                        next_step += 1
                    if chaos is not None:
                        recorder = chaos.tick(now, graph, recorder, record)
                    if graph.failed() and chaos is None:
                        raise RuntimeError(f"nodes exited during the run: {graph.failed()}; logs in {work}")
                    if now >= next_resource or now >= window_end:
                        row = procs.sample(now, pids())
                        next_resource = now + RESOURCE_PERIOD
                        if now >= window_end:
                            record["bag_sizes"].append((now, bag_bytes(work, record)))
                            rss = ", ".join(f"{k} {v / MB:.1f} MB" for k, v in row["rss"].items())
                            info(f"window {round(window_end / args.window)} done ({now / 60:.1f} of "
                                 f"{args.minutes:g} min): RSS {rss}")
                            window_end += args.window
                    due = min(steps[next_step].at if next_step < len(steps) else duration, next_resource, window_end,
                              duration, *(chaos.due() if chaos else ()))
                    executor.spin_once(timeout_sec=max(0.0, min(0.2, due - (time.monotonic() - t_zero[0]))))
                now = time.monotonic() - t_zero[0]
                procs.sample(now, pids())
                record["bag_sizes"].append((now, bag_bytes(work, record)))
                record["t1_ns"] = time.time_ns()
                if chaos is not None:
                    chaos.finish(now, graph, recorder, record)
            finally:
                if recorder is not None:
                    code = stop_recorder(recorder)
                    record["recorder_exit"] = code
                codes = graph.stop()
                record["exit_codes"] = codes
    finally:
        if chaos is not None:
            chaos.close()  # the hogs, the workstation's recorder, the namespaces
    record["resources"] = procs.samples
    record["diagnostics"] = heard
    record["recorder_log"] = (work / "recorder.log").read_text(errors="replace")[-20000:]
    (work / "soak.json").write_text(json.dumps(record), encoding="utf-8")
    return record


# --- the figures ----------------------------------------------------------------------------------------------

@dataclass
class Window:
    """What the bag says about one window."""

    in_force: int | None = None  # command_seq of the window's first sample
    last_command: int | None = None
    first_seen: dict | None = None  # command source seq -> seq of the first sample it drove
    last_seq: int | None = None
    lost: int = 0
    restarts: int = 0  # the rig's seq went back (it restarted)
    samples: int = 0
    skipped: tuple = (math.nan, math.nan)  # sim_node's skipped_samples at the window's first and last report
    reference_errors: list | None = None
    steady_errors: list | None = None
    estimates: int = 0
    matched: int = 0

    def __post_init__(self) -> None:
        self.first_seen, self.reference_errors, self.steady_errors = {}, [], []


def stamp_ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def stamp_key(ns: float) -> int:
    """A sample's stamp as a key both streams compute alike (0.1 ms: samples are 1 ms apart)."""
    return int(round(ns / 100_000))


def read_bags(bags: list[Path], t0_ns: int, window_ns: int, n_windows: int, steps: list[Step]) -> list[Window]:
    """Per window: latencies, losses, skipped periods and the estimate's errors, from the recorded bags."""
    from worm_model.bags.reader import BagReader

    windows = [Window() for _ in range(n_windows)]
    starts = [s.at for s in steps]
    truths: dict[int, float] = {}  # stamp key of each batch's newest sample -> true load [N m]
    estimates: list[tuple[int, int, float]] = []  # (window, stamp ns, torque)
    topics = ("/rig/samples", "/sim/truth_samples", "/torque_estimate", "/diagnostics")
    for bag in bags:
        for w in windows:  # a new recorder: the time between two bags is not the stream's loss
            w.last_seq = w.last_command = None
        with BagReader(bag, allow_truncated=True) as reader:
            for message in reader.messages([t for t in topics if t in reader.topics]):
                m = message.decoded
                ns = stamp_ns(m.header.stamp)
                k = (ns - t0_ns) // window_ns
                if message.topic == "/diagnostics":
                    for status in m.status:
                        if status.name == "sim_node" and 0 <= k < n_windows:
                            value = float({kv.key: kv.value for kv in status.values}.get("skipped_samples", "nan"))
                            w = windows[k]
                            w.skipped = (value if math.isnan(w.skipped[0]) else w.skipped[0], value)
                    continue
                if not 0 <= k < n_windows:
                    continue
                w = windows[k]
                if message.topic == "/rig/samples":
                    _add_batch(w, m)
                elif message.topic == "/sim/truth_samples":
                    n = len(m.tau_load)
                    truths[stamp_key(ns + (n - 1) * m.sample_period * 1e9)] = float(m.tau_load[-1])
                else:
                    estimates.append((k, ns, float(m.torque)))
    for k, ns, torque in estimates:
        w = windows[k]
        w.estimates += 1
        truth = truths.get(stamp_key(ns))
        if truth is None or not math.isfinite(torque):
            continue
        w.matched += 1
        since = (ns - t0_ns) / 1e9
        i = bisect.bisect_right(starts, since) - 1
        if i < 0 or since - starts[i] < STEADY_AFTER or steps[i].speed == 0.0:
            continue
        error = torque - truth
        w.steady_errors.append(abs(error))
        if steps[i].kind == "reference":
            w.reference_errors.append(error)
    return windows


def _add_batch(w: Window, m) -> None:
    """Account for one RigSamples batch of a window: seq gaps and the commands' first periods."""
    first, n = int(m.first_seq), len(m.command_seq)
    if w.last_seq is not None:
        if first <= w.last_seq:
            w.restarts += 1  # a new rig: its seqs start again (a gap across the restart is no loss)
            w.last_command = None
        elif first > w.last_seq + 1:
            w.lost += first - w.last_seq - 1
    w.last_seq = first + n - 1
    w.samples += n
    for j, source in enumerate(m.command_seq):
        source = int(source)
        if source == w.last_command:
            continue
        w.last_command = source
        if w.in_force is None:
            w.in_force = source  # in force at the window's first sample: it may have driven periods before it
            continue
        if source and source != w.in_force and source not in w.first_seen:
            w.first_seen[source] = first + j


def latencies_ms(w: Window) -> list[float]:
    """[ms] per command of the window: from its sample's stamp to the start of the first period it drove
    (the rig's period is 1 ms; worm_model.rig_data.samples.command_latencies counts alike)."""
    return [float(k - 1 - s) for s, k in w.first_seen.items() if k > s]


def recorder_lost(log: str) -> float:
    """What the recorder's end-of-run lines say it lost (nan if it said nothing: killed, or still running)."""
    said = re.findall(r"recorder: (lost nothing|LOST (\d+) messages)", log)
    return float("nan") if not said else float(sum(int(n or 0) for _, n in said))


def analyse(record: dict, work: Path) -> tuple[dict[str, float], list[str], list[str]]:
    """The run's figures {metric: value}, its window table (markdown lines) and its verdict lines."""
    window = float(record["window"])
    duration = 60.0 * float(record["minutes"])
    n = max(1, math.ceil(duration / window - 1e-9))
    steps = [Step(**s) for s in record["steps"]]
    bags = [work / name for name in record["bags"] if (work / name).exists()]
    info(f"reading {len(bags)} bag(s), {bag_bytes(work, record) / MB:.0f} MB")
    windows = read_bags(bags, record["t0_ns"], int(window * 1e9), n, steps)
    figures: dict[str, float] = {}
    units: dict[str, str] = {}

    def put(name: str, value: float, unit: str = "") -> None:
        figures[name], units[name] = value, unit

    resources = record["resources"]
    keys = sorted({key for row in resources for key in row["rss"]})
    edges = [k * window for k in range(n + 1)]
    edges[-1] = min(edges[-1], resources[-1]["t"]) if resources else edges[-1]
    sizes = record["bag_sizes"]
    for i in range(n):
        lo, hi = edges[i], edges[i + 1]
        # the samples taken at the window's start and end (each within a spin of its edge) and between
        inside = [r for r in resources if lo - EDGE <= r["t"] <= hi + EDGE]
        for key in keys:
            end = [r for r in inside if key in r["rss"]]
            put(f"soak_rss_{metric_name(key)}_w{i + 1}", end[-1]["rss"][key] / MB if end else math.nan, "MB")
            same = [r for r in end if r["pid"].get(key) == (end[-1]["pid"].get(key) if end else None)]
            used = (same[-1]["cpu"][key] - same[0]["cpu"][key]) / (same[-1]["t"] - same[0]["t"]) \
                if len(same) > 1 and same[-1]["t"] > same[0]["t"] else math.nan
            put(f"soak_cpu_{metric_name(key)}_w{i + 1}", used, "cores")
        if len(inside) > 1:  # the whole machine: this run's processes and everyone else's
            busy = (inside[-1]["host"] - inside[0]["host"]) / (inside[-1]["t"] - inside[0]["t"])
            put(f"soak_host_cpu_w{i + 1}", busy, "cores")
            put(f"soak_host_loadavg_w{i + 1}", max(r["load"] for r in inside))
        w = windows[i]
        lat = latencies_ms(w)
        put(f"soak_latency_p50_w{i + 1}", percentile(lat, 50), "ms")
        put(f"soak_latency_p99_w{i + 1}", percentile(lat, 99), "ms")
        put(f"soak_lost_samples_w{i + 1}", float(w.lost) if w.samples else math.nan)
        put(f"soak_sim_skipped_samples_w{i + 1}", w.skipped[1] - w.skipped[0])
        grown = [s for t, s in sizes if lo - EDGE <= t <= hi + EDGE]
        before = [s for t, s in sizes if t <= lo + EDGE]
        put(f"soak_bag_growth_w{i + 1}", (grown[-1] - before[-1]) / MB if grown and before else math.nan, "MB")
        ref = w.reference_errors
        put(f"soak_estimate_error_w{i + 1}", statistics.fmean(ref) if ref else math.nan, "N m")
        put(f"soak_estimate_spread_w{i + 1}", statistics.pstdev(ref) if len(ref) > 1 else math.nan, "N m")
        put(f"soak_estimate_error_all_w{i + 1}",
            statistics.fmean(w.steady_errors) if w.steady_errors else math.nan, "N m")
        info(f"window {i + 1}: {w.samples} samples, {len(lat)} commands, {w.matched} of {w.estimates} estimates "
             f"matched to the truth, {len(ref)} in the reference hold, {w.restarts} rig restarts")

    for key in keys:  # the process running at the end (a respawned one from its start)
        pid = next((r["pid"][key] for r in reversed(resources) if key in r["rss"]), None)
        points = [(r["t"], r["rss"][key] / MB) for r in resources
                  if r["pid"].get(key) == pid and key in r["rss"] and r["t"] >= window - 1e-6]
        put(f"soak_rss_growth_{metric_name(key)}", slope_per_hour(points), "MB/h")
    p99 = [figures[f"soak_latency_p99_w{i + 1}"] for i in range(n)]
    put("soak_latency_p99_rise", max(p99) - p99[0] if p99 else math.nan, "ms")
    put("soak_lost_samples", float(sum(w.lost for w in windows)))
    first, last = figures["soak_estimate_error_w1"], figures[f"soak_estimate_error_w{n}"]
    put("soak_estimate_error_change", last - first, "N m")
    put("soak_recorder_lost_messages", recorder_lost(record.get("recorder_log", "")))
    end = min(duration, resources[-1]["t"]) if resources else duration
    for name, times in sorted(record["diagnostics"].items()):
        marks = [0.0, *sorted(times), end]
        put(f"soak_diagnostics_gap_{metric_name(name)}", max(b - a for a, b in zip(marks, marks[1:])), "s")

    verdicts = []
    growth = {key: figures[f"soak_rss_growth_{metric_name(key)}"] for key in keys}
    worst = max(growth, key=lambda k: growth[k] if math.isfinite(growth[k]) else math.inf) if growth else "-"
    ok = bool(growth) and all(math.isfinite(g) and g < RSS_TARGET for g in growth.values())
    verdicts.append(f"verdict rss_growth: {'PASS' if ok else 'FAIL'} (every process under {RSS_TARGET:g} MB/h "
                    f"after the first window; largest {worst} {growth.get(worst, math.nan):.2f} MB/h)")
    rise = figures["soak_latency_p99_rise"]
    ok = math.isfinite(rise) and all(math.isfinite(p) for p in p99) and rise <= P99_TARGET
    verdicts.append(f"verdict latency_p99: {'PASS' if ok else 'FAIL'} (no window's p99 above the first's "
                    f"{p99[0]:.0f} ms by more than {P99_TARGET:g} ms; largest rise {rise:.0f} ms)")
    lost = figures["soak_lost_samples"]
    ok = all(w.samples for w in windows) and lost == 0
    verdicts.append(f"verdict lost_samples: {'PASS' if ok else 'FAIL'} ({lost:g} samples lost, "
                    f"{sum(w.samples for w in windows)} recorded)")
    spread = figures["soak_estimate_spread_w1"]
    change = figures["soak_estimate_error_change"]
    ok = math.isfinite(change) and math.isfinite(spread) and abs(change) <= spread
    verdicts.append(f"verdict estimate_error: {'PASS' if ok else 'FAIL'} (last window's steady error "
                    f"{last:+.4f} N m against the first's {first:+.4f} +- {spread:.4f} N m)")

    table = window_table(figures, keys, n, window)
    out = {k: (v, units[k]) for k, v in figures.items()}
    if record["chaos"]:
        from soak_chaos import chaos_figures

        more, chaos_verdicts = chaos_figures(record, work, figures["soak_recorder_lost_messages"])
        out.update(more)
        verdicts += chaos_verdicts
    return out, table, verdicts


def window_table(figures: dict[str, float], keys: list[str], n: int, window: float) -> list[str]:
    """A markdown table: one row per window."""
    head = ["window"] + [f"RSS {k} [MB]" for k in keys] + [f"CPU {k} [cores]" for k in keys] + [
        "latency p50 / p99 [ms]", "lost", "skipped", "bag growth [MB]", "steady error ± spread [N m]",
        "mean abs error, all steady [N m]", "machine busy [cores] (load average)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for i in range(1, n + 1):
        def f(name: str, fmt: str, i: int = i) -> str:
            value = figures.get(f"{name}_w{i}", math.nan)
            return format(value, fmt) if math.isfinite(value) else "nan"

        row = [f"{clock((i - 1) * window)}-{clock(i * window)}"]
        row += [f(f"soak_rss_{metric_name(k)}", ".1f") for k in keys]
        row += [f(f"soak_cpu_{metric_name(k)}", ".3f") for k in keys]
        row += [f"{f('soak_latency_p50', '.0f')} / {f('soak_latency_p99', '.0f')}", f("soak_lost_samples", "g"),
                f("soak_sim_skipped_samples", "g"), f("soak_bag_growth", ".1f"),
                f"{f('soak_estimate_error', '+.4f')} ± {f('soak_estimate_spread', '.4f')}",
                f("soak_estimate_error_all", ".4f"),
                f"{f('soak_host_cpu', '.2f')} ({f('soak_host_loadavg', '.2f')})"]
        lines.append("| " + " | ".join(row) + " |")
    return lines


def clock(seconds: float) -> str:
    """[s] as m:ss."""
    return f"{int(seconds // 60)}:{int(round(seconds % 60)):02d}"


def print_report(figures: dict[str, tuple[float, str]], table: list[str], verdicts: list[str]) -> None:
    for name, (value, unit) in figures.items():
        text = f"{value:.3f}" if unit == "cores" else f"{value:.4f}" if unit == "N m" else \
            f"{value:.2f}" if unit in ("ms", "MB", "MB/h", "s") else f"{value:g}"
        print(f"{name}: {text} {unit}".rstrip(), flush=True)
    print()
    print("\n".join(table))
    print()
    print("\n".join(verdicts), flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="length of the run [min] (default 60)")
    parser.add_argument("--window", type=float, default=600.0,
                        help="length of a window [s] the figures are given for (default 600 = 10 minutes)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the command profile (and of the faults)")
    parser.add_argument("--chaos", action="store_true",
                        help="inject faults at seeded random moments (bench/soak_chaos.py): kill -9 of each "
                             "process of the graph and of the recorder, a CPU hog burst, a DDS cut where allowed")
    parser.add_argument("--faults", default=",".join(FAULT_KINDS), metavar="KIND[,KIND]",
                        help=f"with --chaos, the kinds of fault injected (default all: {','.join(FAULT_KINDS)})")
    parser.add_argument("--recorder-priority", type=int, default=RECORDER_PRIORITY, metavar="PRIORITY",
                        help=f"SCHED_FIFO priority of the recorder, 1-99 below the graph's 40 (`chrt -f`; default "
                             f"{RECORDER_PRIORITY}, as on a rig computer); 0: normal scheduling, as a user who "
                             "starts it without chrt")
    parser.add_argument("--work", type=Path, default=None,
                        help="folder for the run's calibration, logs, bags and soak.json (must not exist; "
                             "default: a new temporary folder, kept)")
    parser.add_argument("--analyse", type=Path, default=None, metavar="DIR",
                        help="run nothing: print the figures of the finished run in DIR (its soak.json and bags)")
    args = parser.parse_args(argv)
    if args.analyse is not None:
        try:
            record = json.loads((args.analyse / "soak.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as err:
            print(f"soak_bench: --analyse {args.analyse}: no readable soak.json ({err})", file=sys.stderr)
            return 2
        print_report(*analyse(record, args.analyse))
        return 0
    if not (args.minutes > 0 and math.isfinite(args.minutes)):
        parser.error(f"--minutes {args.minutes:g}: must be a positive number of minutes")
    if not (args.window >= 10 and math.isfinite(args.window)):
        parser.error(f"--window {args.window:g}: must be at least 10 s")
    if not 0 <= args.recorder_priority <= 99:
        parser.error(f"--recorder-priority {args.recorder_priority}: must be 0 (normal scheduling) to 99")
    args.faults = tuple(k for k in args.faults.split(",") if k)
    if unknown := [k for k in args.faults if k not in FAULT_KINDS] or not args.faults:
        parser.error(f"--faults {','.join(args.faults)}: not kinds of fault {unknown or ''} (the kinds: "
                     f"{', '.join(FAULT_KINDS)})")
    if args.work is not None and args.work.exists():
        parser.error(f"--work {args.work}: exists already; name a new folder")
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(100, 230)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if args.recorder_priority and not realtime_permitted(args.recorder_priority):
        info(f"SCHED_FIFO {args.recorder_priority} is not permitted here: the recorder runs at normal priority")
        args.recorder_priority = 0
    work = args.work or Path(tempfile.mkdtemp(prefix="soak_bench_"))
    work.mkdir(parents=True, exist_ok=True)
    info(f"domain {os.environ['ROS_DOMAIN_ID']}, work dir {work}, recorder "
         f"{f'SCHED_FIFO {args.recorder_priority}' if args.recorder_priority else 'at normal priority'}")
    try:
        record = run(args, work)
        figures, table, verdicts = analyse(record, work)
    except Exception as err:  # noqa: BLE001 - a benchmark reports, it does not assert
        info(f"failed: {err!r}; files in {work}")
        print(f"soak_failed: 1 ({err})")
        return 1
    print_report(figures, table, verdicts)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
