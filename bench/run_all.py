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
GRAPH_METRICS = ("graph_rate: nan Hz", "graph_latency_p99: nan ms", "graph_lost_samples: nan")


def run(script: str, env: dict[str, str], fallback: tuple[str, ...], timeout: float) -> bool:
    """Run one benchmark script; pass its metric lines through (or the fallback's on failure)."""
    try:
        done = subprocess.run([sys.executable, str(HERE / script)], env=env, stdout=subprocess.PIPE,
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
    ok = run("graph_bench.py", env, GRAPH_METRICS, timeout=180)
    ok &= run("core_bench.py", dict(os.environ), ("calibration_grid_time: nan s",), timeout=600)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
