"""Load-step rejection of the speed controller, feedforward off and on (no ROS, deterministic).

    python bench/controller_bench.py [--seed N] [--method NAME] [--graph-latency N] [--graph FILE]
                                     [--set NODE.PARAM=VALUE ...]

Runs the demo's scenario (torque_estimator.evaluation.scenario.DEMO_SCENARIO:
load steps into all three modes at +-150 rad/s) on the live graph's control
loop in one process (torque_estimator.evaluation.closed_loop: SimulatedRig with
the rig's own speed PI, LiveEstimator, FeedforwardGate, the cores sim_node,
estimator_node and controller_node run), with the PI gains, estimator options
and timeouts of the installed sim_graph.yaml, on a calibration of the paper's
grid. Three rigs side by side: feedforward off, on (the estimator the graph
file selects, or --method), and ideal (the applied load itself, through the
same timing: the bound any estimator could reach).

Three timings, one table each:
  rig       as the shipped graph runs it (sim_graph.yaml: sim_node's
            feedforward_estimator, controller_node's feedforward_at_rig): the
            estimator beside the rig's PI, on every sample; the estimate of one
            sample feeds the very next period (the observer with the step
            detector of a rig feedforward, control.rig_feedforward);
  firmware  the rig's PI on every sample; the estimate of one sample feeds the
            period after next (the estimator beside the rig, one sample late);
  graph     as the node graph runs it: the controller gets the estimator's
            newest estimate once per /rig/samples batch (5 samples: GRAPH_BATCH) and its speed
            command drives the rig --graph-latency sample periods after the next
            one (bench/graph_bench.py measures that latency on the live graph).
            Live, where a load step falls in its batch is chance: each seed runs
            once per position (5 runs), and the figures are their means. (The
            demo's segments last whole batches: with one position only, every
            step would land on a batch's first sample, the observer's best case
            and the true load's worst.)

Per pure load step (same speed, new load), from the rig's true worm speed
(tacho noise is not a dip):
  peak dip       largest |omega - set-point| until the next segment [rad/s]
  settling time  until |omega - set-point| stays within +-1 % of the set-point
                 (at least 0.5 rad/s) to the segment's end [s]; nan: never
  IAE            integral of |omega - set-point| from the step to the segment's end [rad]
and, per run, the live estimate's error in the steady parts (as the demo's
summary: mean |estimate - applied load| from 0.8 s after each change, % of the
calibrated torque range).

Prints the tables on stderr and, on stdout, over all load steps and averaged over
--seeds runs (graph timing: --seeds x 5 batch positions): the worst peak dip, the worst
settling time and the summed IAE, for the firmware timing
  loadstep_peak_dip_ff_off: <x> rad/s   loadstep_peak_dip_ff_on: <x> rad/s   loadstep_peak_dip_ideal: <x> rad/s
  loadstep_settling_time_ff_off: <x> s  loadstep_settling_time_ff_on: <x> s  loadstep_settling_time_ideal: <x> s
  loadstep_iae_ff_off: <x> rad          loadstep_iae_ff_on: <x> rad          loadstep_iae_ideal: <x> rad
and the same with a _rig suffix (loadstep_peak_dip_ff_on_rig, ...) for the rig timing and a _graph
suffix (loadstep_iae_ff_on_graph, ...) for the graph timing.
Never asserts.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.control.rig_feedforward import feedforward_estimator
from torque_estimator.evaluation.closed_loop import run_scenario
from torque_estimator.graph.runner import default_graph_file
from torque_estimator.estimation.registry import ESTIMATORS
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.demo.run_analysis import load_step_responses
from torque_estimator.evaluation.scenario import DEMO_SCENARIO, segment_starts
from worm_rig_driver.drive.speed_loop import PiGains
from worm_model.physics.parameters import load_rig

MODES = {"off": "ff_off", "estimate": "ff_on", "truth": "ideal"}
LABELS = {"off": "off", "estimate": "on", "truth": "ideal (true load)"}


def info(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def metric(name: str, value: float, unit: str) -> None:
    print(f"{name}: {value:.4g} {unit}", flush=True)


def graph_parameters(path: Path | None, overrides: list[str]) -> dict:
    """The estimator's and controller_node's parameters of a graph file (default: the installed
    sim_graph.yaml), with 'node.param=value' overrides (values parsed as YAML). The estimator's are
    estimator_node's where the graph runs one, else the rig's feedforward estimator's (sim_node's
    feedforward_estimator as ``method``, every option at its default): both under "estimator_node"."""
    path = path or default_graph_file()
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    info(f"[controller_bench] parameters from {path}")
    if "estimator_node" in doc:
        estimator = dict(doc["estimator_node"]["ros__parameters"])
    else:
        estimator = {"method": doc["sim_node"]["ros__parameters"].get("feedforward_estimator") or "observer"}
    params = {"estimator_node": estimator, "controller_node": dict(doc["controller_node"]["ros__parameters"])}
    for item in overrides:
        target, sep, value = item.partition("=")
        node, dot, name = target.partition(".")
        if not (sep and dot and node in params and name):
            raise SystemExit(f"controller_bench: --set {item!r}: need estimator_node.<param>=<value> or "
                             f"controller_node.<param>=<value>")
        params[node][name] = yaml.safe_load(value)
    return params


#: The graph's speed-command latency [sample periods] from the sample an estimate came from to the
#: first period its command drives, less the one period that is always there (graph_latency_p50 of
#: bench/graph_bench.py in ms, minus 1): see --graph-latency.
GRAPH_LATENCY = 1
#: samples per /rig/samples batch of the graph timing: 5, a graph that feeds forward through its batches at
#: 200 Hz (the shipped graph feeds forward at the rig and batches 10: through it, later still)
GRAPH_BATCH = 5
SETTLE = 0.8  # [s] after a change before the live estimate counts as steady (run_analysis.analyse_run)


def steady_estimate_error_pct(run, torque_range: float) -> float:
    """Mean |estimate - applied load| in the steady parts of the run, % of the calibrated range."""
    starts = segment_starts(DEMO_SCENARIO)
    ends = starts + np.array([s.duration for s in DEMO_SCENARIO])
    steady = np.any([(run.t >= a + SETTLE) & (run.t < b) for a, b in zip(starts, ends)], axis=0)
    return float(100 * np.mean(np.abs(run.tau_estimated - run.tau_true)[steady]) / torque_range)


def report(timing: str, runs: dict, torque_range: float) -> dict[str, tuple[float, float, float]]:
    """Print one timing's table; returns mode -> (worst dip, worst settling, summed IAE)."""
    responses = {mode: load_step_responses(DEMO_SCENARIO, r.t, r.omega_true, r.setpoint)
                 for mode, r in runs.items()}
    band = responses["off"][0].band
    info("")
    info(f"Load-step rejection, {timing} timing (true worm speed; settled: within +-{band:g} rad/s "
         f"to the segment's end)")
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
    info(f"  live estimate in the steady parts: mean error "
         f"{steady_estimate_error_pct(runs['estimate'], torque_range):.2f} % of the calibrated range")
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of calibration and run noise (default 0)")
    parser.add_argument("--seeds", type=int, default=4,
                        help="runs averaged, seeds seed+1 .. seed+SEEDS of the run noise (default 4): one run's "
                             "worst dip depends on where the step detector happens to fire (3.06-3.63 rad/s "
                             "with the observer over 4 seeds)")
    parser.add_argument("--method", choices=sorted(ESTIMATORS), default=None,
                        help="estimator fed forward (default: estimator_node's method in the graph file)")
    parser.add_argument("--graph-latency", type=int, default=GRAPH_LATENCY,
                        help="graph timing: sample periods from the period after an estimate's sample to the "
                             f"first period its speed command drives (default {GRAPH_LATENCY})")
    parser.add_argument("--graph", type=Path, default=None,
                        help="graph parameter file to take the gains and estimator options from "
                             "(default: the installed sim_graph.yaml)")
    parser.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=VALUE",
                        help="override one parameter of estimator_node or controller_node, e.g. "
                             "--set estimator_node.input_filter=0.005 (repeatable)")
    args = parser.parse_args(argv)
    rig = load_rig(None)
    params = graph_parameters(args.graph, args.set)
    est_p, ctl_p = params["estimator_node"], params["controller_node"]

    start = time.perf_counter()
    db = calibrate_simulated(rig, CalibrationGrid.paper(rig), seed=args.seed)
    method = args.method or est_p.get("method", "knn")
    # estimator_node's method and options as the node reads them, on this bench's rig and calibration
    settings = EstimatorSettings(method, options=EstimatorSettings.from_parameters(est_p, method).options)
    estimator = build_estimator(settings, rig=rig, database=db)
    LABELS["estimate"] = f"on ({method})"
    info(f"[controller_bench] feedforward estimator: {method}")
    info(f"[controller_bench] calibration: {len(db)} points in {time.perf_counter() - start:.1f} s")
    info(f"[controller_bench] estimator options: {settings.options}")

    metrics = []
    # (batch, latency, metric suffix, the estimator fed forward): at the rig, the estimator as a rig runs it
    timings = {"rig": (1, 0, "_rig", feedforward_estimator(method, db, rig)), "firmware": (1, 1, "", estimator),
               "graph": (GRAPH_BATCH, args.graph_latency, "_graph", estimator)}
    for timing, (batch, latency, suffix, fed) in timings.items():
        start = time.perf_counter()
        summaries = []
        for seed in range(args.seed + 1, args.seed + 1 + args.seeds):
            for phase in range(batch):  # every position of the load steps in a batch
                runs = run_scenario(rig, DEMO_SCENARIO, tuple(MODES), estimator=fed, seed=seed,
                                    gains=PiGains(float(ctl_p["kp"]), float(ctl_p["ki"])),
                                    estimate_timeout=float(ctl_p.get("estimate_timeout", 0.05)),
                                    ff_batch=batch, ff_latency=latency, ff_phase=phase)
                where = f", batch position {phase}" if batch > 1 else ""
                summaries.append(report(f"{timing}, run seed {seed}{where}", runs, db.torque_range))
        duration = sum(s.duration for s in DEMO_SCENARIO)
        info(f"[controller_bench] {timing} timing: {len(summaries)} x {duration:.0f} s scenario x {len(MODES)} rigs "
             f"simulated in {time.perf_counter() - start:.1f} s")
        for mode in MODES:
            dip, settle, iae = (float(np.mean([s[mode][i] for s in summaries])) for i in range(3))
            dips = [s[mode][0] for s in summaries]
            info(f"  {timing} {LABELS[mode]:18s} worst dip {dip:.2f} rad/s (runs {min(dips):.2f}-{max(dips):.2f}), "
                 f"IAE {iae:.3f} rad")
            metrics += [(f"loadstep_peak_dip_{MODES[mode]}{suffix}", dip, "rad/s"),
                        (f"loadstep_settling_time_{MODES[mode]}{suffix}", settle, "s"),
                        (f"loadstep_iae_{MODES[mode]}{suffix}", iae, "rad")]
    info("")
    for name, value, unit in metrics:
        metric(name, value, unit)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
