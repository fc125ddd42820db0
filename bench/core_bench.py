"""Benchmarks of the plain-numpy cores (no ROS): calibration, simulator, k-NN, internal forces.

    python bench/core_bench.py

Prints to stdout, in this order:
  calibration_grid_time: <x> s           full 17 x 16 x 2 calibration on the simulated rig
  sim_realtime_factor: <x>               simulated s per wall s, one SimulatedRig (n=1) stepped in a loop
                                         (batch mode: as fast as it goes, no pacing; best of 3 runs), on
                                         the path SimulatedRig picks for n=1 as the live sim_node does:
                                         the scalar one
  sim_vectorised_n1_realtime_factor: <x> the same on the vectorised path (scalar=False), for comparison
  sim_effects_realtime_factor: <x>       sim_realtime_factor with every effect plug-in on (config/effects_all.yaml;
                                         every effect has float hooks, so also the scalar path)
  sim_ensemble_realtime_factor: <x>      rig-seconds per wall s, 544 rigs stepped together
  knn_estimate_latency_p50: <x> us       one k-NN estimate(omega, i) call on the calibration database
                                         (built as estimator_node builds it)
  model_forces_throughput: <x> samples/s internal_forces on 10^6 samples
Progress goes to stderr. Never asserts.
"""
from __future__ import annotations

import sys
import time

import numpy as np

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from worm_model.physics.internal_forces import internal_forces
from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.effects import EFFECTS, EffectsConfig
from worm_rig_driver.sim.simulated_rig import SimulatedRig


def info(text: str) -> None:
    print(f"[core_bench] {text}", file=sys.stderr, flush=True)


def metric(name: str, value: float, unit: str = "", fmt: str = ".3g") -> None:
    print(f"{name}: {value:{fmt}}{' ' + unit if unit else ''}", flush=True)


def bench_calibration(rig):
    grid = CalibrationGrid.paper(rig)
    start = time.perf_counter()
    db = calibrate_simulated(rig, grid)
    elapsed = time.perf_counter() - start
    info(f"calibration: {len(db)} points ({len(grid.speeds)} speeds x {len(grid.torques)} torques), "
         f"{len(db.steady_state['unsettled_points'])} unsettled, range {db.torque_range:.3f} N m")
    metric("calibration_grid_time", elapsed, "s", ".2f")
    return db


def step_rate(rig, n: int, sim_seconds: float, effects=None, scalar: bool | None = None, repeats: int = 1) -> float:
    """Simulated seconds per wall second of n rigs (at a speed, under load) stepped sample by sample.

    scalar: SimulatedRig's switch (None: the path it picks). The best of `repeats`
    runs of sim_seconds each (the machine may be shared).
    """
    sim = SimulatedRig(rig, n=n, seed=0, effects=effects, scalar=scalar)
    sim.command(voltage_drive=np.full(n, 6.0), load_torque=np.full(n, 0.1))
    for _ in range(50):  # warm-up
        sim.sample()
    steps = int(round(sim_seconds / sim.sample_period))
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(steps):
            sim.sample()
        walls.append(time.perf_counter() - start)
    wall = min(walls)
    info(f"SimulatedRig n={n}, substeps={sim.substeps}, {'scalar' if sim.scalar else 'vectorised'} path, "
         f"effects: {', '.join(sim.effects.names) or 'none'}: {steps} samples in {wall:.3f} s "
         f"({wall / steps * 1e6:.1f} us per sample; best of {repeats})")
    return steps * sim.sample_period / wall


def bench_knn(db) -> float:
    est = build_estimator(EstimatorSettings("knn"), database=db).estimator
    rng = np.random.default_rng(1)
    idx = rng.integers(0, len(db), 20000)
    omegas = (db.omega_worm[idx] * rng.uniform(0.9, 1.1, idx.size)).tolist()
    currents = (db.current_drive[idx] * rng.uniform(0.9, 1.1, idx.size)).tolist()
    for w, i in zip(omegas[:500], currents[:500]):  # warm-up
        est.estimate(w, i)
    times = []
    clock = time.perf_counter_ns
    for w, i in zip(omegas, currents):
        t0 = clock()
        est.estimate(w, i)
        times.append(clock() - t0)
    times.sort()
    info(f"knn: {len(times)} single-sample calls, p90 {times[int(0.9 * len(times))] / 1e3:.1f} us")
    return times[len(times) // 2] / 1e3


def bench_forces(rig, n: int = 10**6) -> float:
    rng = np.random.default_rng(2)
    omega = rng.uniform(-340, 340, n)
    tau_in = rng.uniform(-0.05, 0.05, n)
    tau_d = rng.uniform(-0.25, 0.25, n)
    alpha = rng.normal(0, 50, n)
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        internal_forces(rig.gearbox, tau_in, tau_d, omega, alpha,
                        worm_inertia=rig.total_worm_inertia, gear_inertia=rig.total_gear_inertia)
        best = min(best, time.perf_counter() - start)
    info(f"internal_forces on {n} samples: best of 3 {best:.3f} s")
    return n / best


def main() -> int:
    rig = load_rig(None)
    db = bench_calibration(rig)
    metric("sim_realtime_factor", step_rate(rig, 1, 20.0, repeats=3), "", ".2f")
    metric("sim_vectorised_n1_realtime_factor", step_rate(rig, 1, 5.0, scalar=False), "", ".2f")
    metric("sim_effects_realtime_factor", step_rate(rig, 1, 10.0, EffectsConfig.defaults(*EFFECTS), repeats=3),
           "", ".2f")
    metric("sim_ensemble_realtime_factor", len(db) * step_rate(rig, len(db), 1.0), "", ".1f")
    metric("knn_estimate_latency_p50", bench_knn(db), "us", ".1f")
    metric("model_forces_throughput", bench_forces(rig), "samples/s", ".3g")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
