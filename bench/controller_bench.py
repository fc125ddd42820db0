"""Load-step rejection of the speed controller, feedforward off and on (no ROS, deterministic).

    python bench/controller_bench.py [--seed N]

Runs the demo's scenario (torque_estimator.scenario.DEMO_SCENARIO: load steps
into all three modes at +-150 rad/s) on the live graph's control loop in one
process (torque_estimator.closed_loop: SimulatedRig + LiveEstimator +
FeedforwardGate + SpeedController, the cores sim_node, estimator_node and
controller_node run), with the PI gains, estimator options and timeouts of
the installed sim_graph.yaml, on a calibration of the paper's grid. The
controller gets each estimate one sample late (on the graph: >= 1).
Three rigs side by side: feedforward off, on (the k-NN estimate), and ideal
(the applied load itself, one sample late: the bound any estimator could reach).

Per pure load step (same speed, new load), from the rig's true worm speed
(tacho noise is not a dip):
  peak dip       largest |omega - set-point| until the next segment [rad/s]
  settling time  until |omega - set-point| stays within +-1 % of the set-point
                 (at least 0.5 rad/s) to the segment's end [s]; nan: never
  IAE            integral of |omega - set-point| from the step to the segment's end [rad]

Prints the table on stderr and, on stdout, over all load steps: the worst
peak dip, the worst settling time and the summed IAE:
  loadstep_peak_dip_ff_off: <x> rad/s          loadstep_peak_dip_ff_on: <x> rad/s
  loadstep_settling_time_ff_off: <x> s         loadstep_settling_time_ff_on: <x> s
  loadstep_iae_ff_off: <x> rad                 loadstep_iae_ff_on: <x> rad
Never asserts.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import yaml

from torque_estimator.calibration import CalibrationGrid, calibrate_simulated
from torque_estimator.closed_loop import run_scenario
from torque_estimator.graph import default_graph_file
from torque_estimator.estimator import make_estimator
from torque_estimator.run_analysis import load_step_responses
from torque_estimator.scenario import DEMO_SCENARIO
from torque_estimator.speed_controller import PiGains
from worm_model.parameters import load_rig

MODES = {"off": "ff_off", "estimate": "ff_on", "truth": "ff_ideal"}
LABELS = {"off": "off", "estimate": "on (k-NN)", "truth": "ideal (true load)"}


def info(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def metric(name: str, value: float, unit: str) -> None:
    print(f"{name}: {value:.4g} {unit}", flush=True)


def graph_parameters() -> dict:
    """estimator_node and controller_node parameters of the installed sim_graph.yaml."""
    path = default_graph_file()
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    info(f"[controller_bench] parameters from {path}")
    return {node: doc[node]["ros__parameters"] for node in ("estimator_node", "controller_node")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of calibration and run noise (default 0)")
    args = parser.parse_args(argv)
    rig = load_rig(None)
    params = graph_parameters()
    est_p, ctl_p = params["estimator_node"], params["controller_node"]

    start = time.perf_counter()
    db = calibrate_simulated(rig, CalibrationGrid.paper(rig), seed=args.seed)
    estimator = make_estimator(est_p.get("method", "knn"), db, k=int(est_p.get("k", 4)),
                               weighting=est_p.get("weighting", "inverse_distance"))
    info(f"[controller_bench] calibration: {len(db)} points in {time.perf_counter() - start:.1f} s")

    start = time.perf_counter()
    runs = run_scenario(rig, DEMO_SCENARIO, tuple(MODES), estimator=estimator, seed=args.seed + 1,
                        gains=PiGains(float(ctl_p["kp"]), float(ctl_p["ki"])),
                        estimate_timeout=float(ctl_p.get("estimate_timeout", 0.05)),
                        input_filter=float(est_p.get("input_filter", 0.05)))
    duration = sum(s.duration for s in DEMO_SCENARIO)
    info(f"[controller_bench] {duration:.0f} s scenario x {len(MODES)} rigs simulated in "
         f"{time.perf_counter() - start:.1f} s")

    responses = {mode: load_step_responses(DEMO_SCENARIO, r.t, r.omega_true, r.setpoint)
                 for mode, r in runs.items()}
    band = responses["off"][0].band
    info("")
    info(f"Load-step rejection (true worm speed; settled: within +-{band:g} rad/s to the segment's end)")
    info(f"  {'load step':54s} {'feedforward':18s} {'peak dip':>12s} {'settling':>9s} {'IAE':>10s}")
    for i, step in enumerate(responses["off"]):
        name = (f"{step.load_before:+.3f} -> {step.load_after:+.3f} N m at {step.speed:+.0f} rad/s, "
                f"{DEMO_SCENARIO[step.segment].label}")
        for mode in MODES:
            r = responses[mode][i]
            info(f"  {name:54s} {LABELS[mode]:18s} {r.peak_dip:6.2f} rad/s {r.settling_time:7.3f} s "
                 f"{r.iae:6.3f} rad")
            name = ""
    summary = {}
    for mode in MODES:
        steps = responses[mode]
        settling = [s.settling_time for s in steps]
        summary[mode] = (max(s.peak_dip for s in steps),
                         float("nan") if np.isnan(settling).any() else max(settling),
                         sum(s.iae for s in steps))
        dip, settle, iae = summary[mode]
        name = "all steps: worst dip and settling, IAE summed" if mode == "off" else ""
        info(f"  {name:54s} {LABELS[mode]:18s} {dip:6.2f} rad/s {settle:7.3f} s {iae:6.3f} rad")
    info("")
    for mode in ("off", "estimate"):
        dip, settle, iae = summary[mode]
        metric(f"loadstep_peak_dip_{MODES[mode]}", dip, "rad/s")
        metric(f"loadstep_settling_time_{MODES[mode]}", settle, "s")
        metric(f"loadstep_iae_{MODES[mode]}", iae, "rad")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
