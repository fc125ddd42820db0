"""Figures of the load observer (torque_estimator.estimation.observer) on the simulated rig; no ROS, never asserts.

    python bench/observer_bench.py [--seeds N] [--cpu-only]

Prints: ``observer_update_cpu: <x> us``, the median CPU time (time.process_time) of one
LoadObserver.update on a steady 8 V, 0.1 N m run of the simulated rig (what the live graph pays
per 1 ms sample; --cpu-only prints only this line), then the step response to a 0 -> 0.2 N m
load step at 150 rad/s (ensemble over seeds; a true step, and with the rig's 2 ms load loop), the
steady noise against the filter's prediction and
the Cramer-Rao-type bound, the step-size bound (jump_bound), errors over a speed ramp and
through a +150 -> -150 rad/s reversal, the 17 held-out points streamed, the robustness table
(observer's model perturbed: mu ±30 %, K_t ±5 %, J ±20 %; its step figures, and the 17 held-out
points streamed without and with a calibration of the simulated rig, whose measured model error
the observer then adds: estimation/calibration_bias.py) and the closed loop of
controller_bench (firmware timing, seed 1) with feedforward off / observer / ideal.
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.base import StreamingEstimator
from torque_estimator.evaluation.closed_loop import run_scenario
from torque_estimator.evaluation.held_out import held_out_setpoints
from torque_estimator.estimation.observer import equivalent_window, jump_bound, predicted_noise, \
    steady_state_bound
from torque_estimator.evaluation.observer_study import held_out_streaming, perturbed_rig, profile_error, step_response
from torque_estimator.demo.run_analysis import load_step_responses
from torque_estimator.evaluation.scenario import DEMO_SCENARIO
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from worm_model.physics.parameters import Rig, load_rig
from worm_rig_driver.sim.simulated_rig import SimulatedRig

RANGE = 0.495


def update_cpu_us(rig: Rig, samples: int = 3000, repeats: int = 3, estimator: StreamingEstimator | None = None,
                  voltage: bool = True) -> float:
    """Median CPU time [us] of one update of ``estimator``'s stream (None: the observer, LoadObserver) over
    ``repeats`` fresh streams fed the same ``samples`` measurements (8 V, 0.1 N m, seed 0; ``voltage`` False:
    NaN for the voltage), each call timed on its own."""
    sim = SimulatedRig(rig, n=1, seed=0)
    sim.command(voltage_drive=8.0, load_torque=0.1)
    inputs = []
    for _ in range(samples):
        m = sim.sample()
        inputs.append({"voltage_drive": float(m.voltage_drive[0]) if voltage else math.nan,
                       "current_drive": float(m.current_drive[0]), "omega_worm": float(m.omega_worm[0]),
                       "theta_worm": float(m.theta_worm[0])})
    clock, per_update = time.process_time, []
    estimator = estimator or build_estimator(EstimatorSettings("observer"), rig=rig).estimator
    for _ in range(repeats):
        update = estimator.stream(1.0 / rig.sensors.sample_rate_hz).update
        for sample in inputs:
            start = clock()
            update(**sample)
            per_update.append(clock() - start)
    return 1e6 * statistics.median(per_update)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--cpu-only", action="store_true", help="print only observer_update_cpu")
    args = parser.parse_args()
    rig = load_rig(None)
    print(f"observer_update_cpu: {update_cpu_us(rig):.1f} us", flush=True)
    if args.cpu_only:
        return 0
    for ideal in (True, False):
        r = step_response(rig, seeds=args.seeds, ideal_step=ideal)
        print(f"step 0->0.2 N m at 150 rad/s ({'true step' if ideal else 'rig load loop, 2 ms'}): "
              f"step90_ms={r.step90_ms:g} (ensemble mean; applied load itself {r.truth90_ms:g}) per seed "
              f"{sorted(r.per_seed90_ms.astype(int).tolist())} overshoot={r.overshoot_pct:.1f} % "
              f"5 ms p10/p90={r.spread_5ms[0]:.2f}/{r.spread_5ms[1]:.2f} of the step")
        if ideal:
            nominal = r
    print(f"steady noise at 150 rad/s: measured {nominal.steady_std:.2e} N m, predicted (4-state, constant load) "
          f"{predicted_noise(rig, 150.0, 0.0):.2e}, bound (steady Kalman, random-walk load) "
          f"{steady_state_bound(rig, 150.0, 0.0):.2e}; equivalent window {equivalent_window(rig, 150.0, 0.0):.0f} "
          f"samples")
    print("jump bound, 1 sigma of a 0.2 N m step after n samples [%]:",
          " ".join(f"{n + 1}:{100 * v:.0f}" for n, v in enumerate(jump_bound(rig, 150.0, 0.1, 6) / 0.2)))
    ramp = profile_error(rig, lambda t: 50 + 250 * min(max(t - 0.5, 0.0), 1.0), 0.1, 1.6, start=0.5)
    print(f"ramp 50->300 rad/s in 1 s at 0.1 N m: mean {100 * ramp[0] / RANGE:.2f} % max {100 * ramp[1] / RANGE:.2f} %")
    for substeps in (2, 20):
        for load in (0.1, -0.1):
            rev = profile_error(rig, lambda t: 150.0 if t < 0.6 else -150.0, load, 1.2, start=0.6,
                                substeps=substeps)
            print(f"reversal +150->-150 at {load:+.1f} N m, simulator substeps {substeps}: "
                  f"mean {100 * rev[0] / RANGE:.2f} % max {100 * rev[1] / RANGE:.1f} %")
    speeds, torques = held_out_setpoints(CalibrationGrid.paper(rig), 17, 1)
    est, truth = held_out_streaming(rig, speeds, torques)
    error = 100 * np.abs(est - truth) / RANGE
    print(f"17 held-out points streamed: mean {error.mean():.3f} % max {error.max():.3f} % of the range")
    database = calibrate_simulated(rig, CalibrationGrid.paper(rig), seed=0)
    print("robustness (observer's model perturbed; step90_ms, overshoot %, steady bias N m, steady std N m; "
          "17 held-out points streamed, mean/max % of the range, without -> with the calibration):")
    for case in (dict(), dict(mu=1.3), dict(mu=0.7), dict(kt=1.05), dict(kt=0.95), dict(inertia=1.2),
                 dict(inertia=0.8)):
        model = perturbed_rig(rig, **case)
        r = step_response(rig, seeds=args.seeds, observer_rig=model)
        held = []
        for db in (None, database):
            est, truth = held_out_streaming(rig, speeds, torques, estimator=build_estimator(
                EstimatorSettings("observer"), rig=model, database=db).estimator)
            error = 100 * np.abs(est - truth) / RANGE
            held.append(f"{error.mean():.2f}/{error.max():.2f}")
        name = ",".join(f"{k} x{v}" for k, v in case.items()) or "nominal"
        print(f"  {name:14s} {r.step90_ms:5g} {r.overshoot_pct:6.1f} {r.steady_bias:+.4f} {r.steady_std:.5f}  "
              f"per-seed median {np.median(r.per_seed90_ms):g} max {np.max(r.per_seed90_ms):g}  "
              f"held-out {held[0]} -> {held[1]} %")
    runs = run_scenario(rig, DEMO_SCENARIO, ("off", "estimate", "truth"),
                        estimator=build_estimator(EstimatorSettings("observer")), seed=1)
    for mode, run in runs.items():
        steps = load_step_responses(DEMO_SCENARIO, run.t, run.omega_true, run.setpoint)
        print(f"closed loop firmware timing, ff {mode}: worst dip {max(s.peak_dip for s in steps):.2f} rad/s "
              f"IAE {sum(s.iae for s in steps):.3f} rad")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
