"""System test: `make demo`'s job, end to end (calibration, held-out evaluation, two live runs
of the whole graph over DDS with a recorder, plots), as the user runs it.

It runs the demo module the Makefile runs and checks what it promises: a summary with every
figure, the modes the scenario must visit, and every output file, including two bags that
hold the live runs' estimates.
"""
from __future__ import annotations

import os
import random
import re
import subprocess
import sys
from pathlib import Path

from worm_model.bags.writer import read_bag_counts


def test_demo_runs_end_to_end(tmp_path: Path) -> None:
    env = dict(os.environ, ROS_DOMAIN_ID=str(random.randint(100, 230)), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    out = tmp_path / "demo"
    done = subprocess.run([sys.executable, "-m", "torque_estimator.experiment.demo", "--out", str(out)],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"demo failed:\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}"
    summary = done.stdout[done.stdout.index("Summary"):]

    held_out = re.search(r"held-out estimation error \(17 points\): mean ([\d.]+) %, max ([\d.]+) %", summary)
    assert held_out, summary
    assert float(held_out[1]) < 2.0, f"held-out mean error {held_out[1]} %"
    assert re.search(r"live estimation error \(steady parts\):\s+mean [\d.]+ %", summary), summary
    assert "modes visited: resistive, pseudo-resistive, assistive" in summary
    assert re.search(r"feedforward off\s+[\d.]+ rad/s\s+[\d.]+ rad/s\s+[\d.]+ rad", summary), summary
    assert re.search(r"feedforward on\s+[\d.]+ rad/s\s+[\d.]+ rad/s\s+[\d.]+ rad", summary), summary

    for name in ("calibration.json", "held_out_deviation.png", "estimate_vs_truth.png", "tracking.png"):
        assert (out / name).stat().st_size > 0, name
    for bag in ("bag_ff_off", "bag_ff_on"):
        counts = read_bag_counts(out / bag)
        # 12 s of scenario at 1 kHz: most estimates must be in the bag
        assert counts.get("/torque_estimate", 0) > 6000, f"{bag}: {counts}"
        assert counts.get("/rig/sample", 0) > 6000, f"{bag}: {counts}"
