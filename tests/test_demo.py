"""System test: `make demo`'s job, end to end (calibration, held-out evaluation, two live runs
of the whole graph over DDS with a recorder, plots), as the user runs it.

It runs the demo module the Makefile runs and checks what it promises: a summary with every
figure, the modes the scenario must visit, and every output file, including two bags that
hold the live runs' estimates.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from worm_model.bags.writer import read_bag_counts
from worm_model.ros.testing import local_domain

from torque_estimator.graph.runner import batch_rate, default_graph_file

BATCH_RATE = batch_rate(default_graph_file())  # [Hz] the shipped graph's /rig/samples messages and estimates


def test_demo_runs_end_to_end(tmp_path: Path) -> None:
    env = dict(os.environ, **local_domain({}))  # a domain of its own (this xdist worker's share)
    out = tmp_path / "demo"
    done = subprocess.run([sys.executable, "-m", "torque_estimator.demo.demo", "--out", str(out)],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"demo failed:\n{done.stdout[-4000:]}\n{done.stderr[-4000:]}"
    summary = done.stdout[done.stdout.index("Summary"):]
    print(summary)  # shown with -s or -rP: the live figures of this run

    held_out = re.search(r"held-out estimation error \(17 points\): mean ([\d.]+) %, max ([\d.]+) %", summary)
    assert held_out, summary
    # deterministic (seeded calibration and held-out draws): the README's figures exactly
    assert (held_out[1], held_out[2]) == ("0.72", "2.13"), held_out[0]
    live = re.search(r"live estimation error \(steady parts\):\s+mean ([\d.]+) %, worst segment ([\d.]+) %", summary)
    assert live, summary
    # live (timing-dependent): the observer's steady error, mean / worst segment. The worst is the assistive
    # segment, whose mean error (+0.56 to +0.93 % in the runs below, sd 0.12 between runs) moves from run to
    # run by about its estimates' spread within one (sd 0.12-0.21 % over 120 estimates, which follow one
    # another closely: a slow wander, so 1.2 s of them average little of it out).
    # Runs seen with one core held by a CPU hog: 0.19-0.32 / 0.36-0.77 %; with three hogs on the two cores
    # 0.27-0.29 / 0.67-0.93 %; in CI 0.25 / 0.73 % and 0.31 / 0.93 %: the bound is their mean + 3 sd.
    # Offline, the same scenario gives 0.43 % at worst (the assistive segment).
    assert float(live[1]) < 0.4 and float(live[2]) < 1.1, live[0]
    # those figures leave out the estimates flagged untrusted (what the standard outputs do not carry): in the
    # steady parts, the observer's step detector at the rig's false-alarm rate (1e-3 a sample) flags a few
    # (0-9 of 720-1440 in the feedforward-on runs seen, one of them a -1.36 N m spike at a constant 0.2 N m load)
    flagged = re.search(r"flagged in the steady parts \(not above\): (\d+) of (\d+) estimates", summary)
    assert flagged and int(flagged[2]) > 600 and int(flagged[1]) < 0.02 * int(flagged[2]), summary
    assert "modes visited: resistive, pseudo-resistive, assistive" in summary
    steps = {m[1]: (float(m[2]), float(m[3])) for m in re.finditer(
        r"feedforward (off|on)\s+4\s+([\d.]+) rad/s\s+([\d.]+) rad", summary)}
    assert set(steps) == {"off", "on"}, summary
    (dip_off, iae_off), (dip_on, iae_on) = steps["off"], steps["on"]
    # what the README says of the load steps (about two thirds off the IAE, close to half off the worst dip),
    # with the feedforward at the rig and the rig in its own process (graph.runner.rig_computer), read on the
    # true speed at every sample (/sim/truth_samples): over seven runs, three with a CPU hog on one core, the
    # IAE fell to 0.32-0.35 of it; the off dip 4.82-5.10 rad/s, its IAE 2.31-2.36 rad. A step's window ends
    # where the rig took the next set-point (the samples' command_seq), not at that command's stamp, and a gap
    # in the record adds nothing (run_analysis.recorded_load_steps); once in CI before both, the on run's
    # steps summed 13.46 rad with a 2.73 rad/s dip (its bag not kept).
    assert 4.0 < dip_off < 5.5 and 2.0 < iae_off < 2.8, steps
    assert iae_on < 0.4 * iae_off, steps
    # The worst dip (the reversed 0.4 N m step) is where the step detector fires, a matter of the noise at
    # the step: each sample it fires later adds ~0.5 rad/s. The same scenario at rig timing offline
    # (controller_bench's rig timing, run seeds 1-16): 0.51-0.70 of the off dip, mean 0.57; live runs
    # 0.52-0.67. Without the feedforward it would be ~1.
    assert dip_on < 0.75 * dip_off, steps

    for name in ("calibration.json", "held_out_deviation.png", "estimate_vs_truth.png", "tracking.png",
                 "load_steps.png"):
        assert (out / name).stat().st_size > 0, name
    for bag in ("bag_ff_off", "bag_ff_on"):
        counts = read_bag_counts(out / bag)
        # 12 s of scenario: the rig's batches (1 kHz / batch_size) and an estimate per batch must be in the bag
        assert counts.get("/rig/samples", 0) > 0.9 * 12 * BATCH_RATE, f"{bag}: {counts}"
        assert counts.get("/torque_estimate", 0) > 0.9 * 12 * BATCH_RATE, f"{bag}: {counts}"
