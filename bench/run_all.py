"""All benchmarks: `make bench` (= tools/run.sh python bench/run_all.py).

Prints one `<metric>: <value> <unit>` line per figure on stdout, progress on
stderr. The live-graph benchmark runs first, in a subprocess with its own
ROS_DOMAIN_ID (discovery kept on this host), so no other run on the machine
crosses it; the core benchmarks run after it, so they do not share the CPU
with the graph. Never asserts; exits 1 if a part failed (its figures are nan).
"""
from __future__ import annotations

import os
import random
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
GRAPH_METRICS = tuple(f"graph_{name}{suffix}: nan {unit}".rstrip() for suffix in ("", "_under_load", "_separate")
                      for name, unit in (("cpu_cores", "cores"), ("latency_p50", "ms"), ("latency_p99", "ms"),
                                         ("lost_samples", ""), ("sim_skipped_samples", "")))
JOINT_STATE_METRICS = ("joint_state_estimator_cpu_cores: nan cores", "joint_state_estimator_lost_messages: nan",
                       "joint_state_estimator_max_abs_diff: nan N m", "joint_state_publisher_cpu_cores: nan cores")
SERIAL_METRICS = ("decoder_throughput: nan frames/s", "driver_cpu_at_1khz: nan %", "driver_reconnect_time: nan s")
RECORDER_METRICS = ("recorder_published: nan count", "recorder_recorded: nan count",
                    "recorder_lost_messages: nan count")
MOMENTUM_METRICS = tuple(f"momentum_{name}: nan {unit}" for name, unit in (
    ("update_cpu", "us"), ("step90", "ms"), ("overshoot", "%"), ("ramp_err", "%"), ("reversal_err", "%"),
    ("step90_no_encoder", "ms"), ("noise", "N m"), ("noise_predicted", "N m"), ("linear_floor", "N m"),
    ("held_out_mean", "%"), ("held_out_max", "%")))
DISCOVERY_METRICS = tuple(f"dds_{name}{suffix}: nan s" for suffix in ("_subnet", "_localhost")
                          for name in ("discovery_p50", "discovery_max", "first_sample_p50", "first_sample_max",
                                       "probe_start_p50"))
CONTROLLER_METRICS = tuple(f"loadstep_{name}_{ff}{timing}: nan {unit}" for timing in ("_rig", "", "_graph")
                           for ff in ("ff_off", "ff_on", "ideal")
                           for name, unit in (("peak_dip", "rad/s"), ("settling_time", "s"), ("iae", "rad")))


def run(script: str, env: dict[str, str], fallback: tuple[str, ...], timeout: float,
        args: tuple[str, ...] = ()) -> bool:
    """Run one benchmark script; pass its metric lines through (or the fallback's on failure)."""
    try:
        done = subprocess.run([sys.executable, str(HERE / script), *args], env=env, stdout=subprocess.PIPE,
                              text=True, timeout=timeout)
        lines = [line for line in done.stdout.splitlines() if ": " in line]
        ok = done.returncode == 0
    except subprocess.TimeoutExpired:
        print(f"[run_all] {script} timed out after {timeout:g} s", file=sys.stderr)
        lines, ok = [], False
    if not ok:
        print(f"[run_all] {script} failed", file=sys.stderr)
    for line in lines or fallback:
        print(line, flush=True)
    return ok


def main() -> int:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(random.randint(100, 230))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    print(f"[run_all] graph benchmark on ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}", file=sys.stderr, flush=True)
    ok = run("graph_bench.py", env, GRAPH_METRICS, timeout=600)
    ok &= run("joint_state_bench.py", env, JOINT_STATE_METRICS, timeout=300)
    ok &= run("core_bench.py", dict(os.environ), ("calibration_grid_time: nan s",), timeout=600)
    ok &= run("identify_bench.py", dict(os.environ), ("calibration_rig_time: nan s", "identification_rig_time: nan s",
                                                      "identification_fit_time: nan s"), timeout=300)
    # DDS's own wait before a process started beside the graph hears it (the floor under a respawn)
    ok &= run("discovery_bench.py", env, DISCOVERY_METRICS, timeout=300)
    ok &= run("serial_bench.py", dict(os.environ), SERIAL_METRICS, timeout=300)
    # The 5 minutes at 1 kHz is `python bench/recorder_bench.py`; make bench records 60 s.
    ok &= run("recorder_bench.py", env, RECORDER_METRICS, timeout=240, args=("--duration", "60"))
    ok &= run("controller_bench.py", dict(os.environ), CONTROLLER_METRICS, timeout=900)  # 28 runs of 12 s
    ok &= run("observer_bench.py", dict(os.environ), ("observer_update_cpu: nan us",), timeout=120,
              args=("--cpu-only",))
    ok &= run("momentum_bench.py", dict(os.environ), MOMENTUM_METRICS, timeout=300, args=("--metrics-only",))
    # model_node's callback in-process (rclpy node, so the graph benchmark's own ROS_DOMAIN_ID)
    ok &= run("model_node_bench.py", env, ("model_node_latency_p99: nan us",), timeout=120)
    ok &= run("health_bench.py", env, ("health_monitor_cpu_cores: nan cores",), timeout=300)  # the live health monitor
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
