"""Figures of the momentum observer (torque_estimator.estimation.momentum) on the simulated rig; no ROS, never asserts.

    python bench/momentum_bench.py [--metrics-only]

Fed current, speed and encoder angle only (NaN for the voltage), as from a drive that reports no voltage.
Prints, as `<metric>: <value> <unit>` lines (what `make bench` passes on, --metrics-only):

* ``momentum_update_cpu``: the median CPU time (time.process_time) of one update on a steady 8 V, 0.1 N m run
  of the simulated rig (what a node pays per 1 ms sample; observer_bench.update_cpu_us);
* ``momentum_step90`` / ``momentum_overshoot`` / ``momentum_ramp_err`` / ``momentum_reversal_err``: make evaluate's
  transient experiments (evaluation.transient, 12 seeds, no calibration); ``momentum_step90_no_encoder``: the same
  step fed no encoder angle;
* ``momentum_noise``: the estimate's spread across 12 seeds on a constant load at 150 rad/s, beside
  ``momentum_noise_predicted`` (its steady filter's) and ``momentum_linear_floor`` (the least noise of any linear
  estimator with 90 % of a step after 5 samples: why it detects steps);
* ``momentum_held_out_mean`` / ``_max``: the 17 held-out points streamed, % of the range.

Then (not with --metrics-only) the robustness table: the observer's model perturbed (mu ±30 %, K_t ±5 %, J ±20 %),
its step figures and the 17 held-out points streamed without and with a calibration of the simulated rig.
"""
from __future__ import annotations

import argparse

from dataclasses import replace

import numpy as np
from observer_bench import update_cpu_us  # bench/, beside this script

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.momentum import linear_noise_bound, predicted_noise
from torque_estimator.estimation.observer.streams import WithoutEncoder
from torque_estimator.estimation.settings import BuiltEstimator, EstimatorSettings, build_estimator
from torque_estimator.evaluation.held_out import held_out_setpoints
from torque_estimator.evaluation.observer_study import held_out_streaming, perturbed_rig
from torque_estimator.evaluation.transient import STEP_SPEED, ensemble_noise, transient_figures
from worm_model.physics.parameters import Rig, load_rig

RANGE = 0.495  # [N m] the paper grid's calibrated range


def momentum(model: Rig, database: CalibrationDatabase | None = None) -> BuiltEstimator:
    """The momentum observer as estimator_node builds it, on the model ``model`` (the bench's rig, or perturbed)."""
    return build_estimator(EstimatorSettings("momentum"), rig=model, database=database)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--metrics-only", action="store_true", help="only the metric lines (make bench)")
    args = parser.parse_args()
    rig = load_rig(None)
    built = momentum(rig)
    estimator = built.estimator
    print(f"momentum_update_cpu: {update_cpu_us(rig, estimator=estimator, voltage=False):.1f} us", flush=True)
    f = transient_figures(rig, built, RANGE)
    print(f"momentum_step90: {f.step90_ms:g} ms\nmomentum_overshoot: {f.overshoot_pct:.1f} %\n"
          f"momentum_ramp_err: {f.ramp_err_pct:.2f} %\nmomentum_reversal_err: {f.reversal_err_pct:.2f} %", flush=True)
    blind = transient_figures(rig, replace(built, estimator=WithoutEncoder(estimator)), RANGE)
    print(f"momentum_step90_no_encoder: {blind.step90_ms:g} ms", flush=True)
    print(f"momentum_noise: {ensemble_noise(rig, built):.2e} N m\n"
          f"momentum_noise_predicted: {predicted_noise(rig, STEP_SPEED, 0.0, estimator.bandwidth):.2e} N m\n"
          f"momentum_linear_floor: {linear_noise_bound(rig, STEP_SPEED, 0.0, 5):.2e} N m", flush=True)
    grid = CalibrationGrid.paper(rig)
    speeds, torques = held_out_setpoints(grid, 17, 1)
    est, truth = held_out_streaming(rig, speeds, torques, estimator=estimator)
    error = 100 * np.abs(est - truth) / RANGE
    print(f"momentum_held_out_mean: {error.mean():.2f} %\nmomentum_held_out_max: {error.max():.2f} %", flush=True)
    if args.metrics_only:
        return 0
    database = calibrate_simulated(rig, grid, seed=0)
    print("robustness (the momentum observer's model perturbed; step90_ms, overshoot %; 17 held-out points "
          "streamed, mean/max % of the range, without -> with the calibration):")
    for case in (dict(), dict(mu=1.3), dict(mu=0.7), dict(kt=1.05), dict(kt=0.95), dict(inertia=1.2),
                 dict(inertia=0.8)):
        model = perturbed_rig(rig, **case)
        r = transient_figures(rig, momentum(model), RANGE)
        held = []
        for db in (None, database):
            est, truth = held_out_streaming(rig, speeds, torques, estimator=momentum(model, db).estimator)
            error = 100 * np.abs(est - truth) / RANGE
            held.append(f"{error.mean():.2f}/{error.max():.2f}")
        name = ",".join(f"{k} x{v}" for k, v in case.items()) or "nominal"
        print(f"  {name:14s} {r.step90_ms:5g} {r.overshoot_pct:6.1f}  held-out {held[0]} -> {held[1]} %", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
