"""Running residual cases: one case simulated and analysed as the ``residuals`` executable would, or a list of
them in worker processes."""

from __future__ import annotations

import math
import multiprocessing
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from collections.abc import Callable, Sequence
from pathlib import Path

from worm_model.physics.parameters import Rig, load_rig

import worm_model.residuals.analysis as an
from worm_model.residuals.free import get_value, read_free
from worm_model.residuals.model import prepare_signals

from torque_estimator.evaluation.residual_cases.case import Case, CaseResult
from torque_estimator.evaluation.residual_cases.rig_files import PERTURBATIONS, plant_rig, write_rig_file
from torque_estimator.evaluation.residual_cases.simulation import simulate


def run_case(case: Case, rig: Rig | None = None) -> CaseResult:
    """Simulate the case on ``rig`` (default: the case's) and analyse it with the rig file a user would write
    (:func:`write_rig_file`, read back as the ``residuals`` executable reads it)."""
    start = time.monotonic()
    plant = rig or plant_rig(case.rig, case.plant)
    data = simulate(case, plant)
    pert = PERTURBATIONS[case.perturbation]
    with tempfile.TemporaryDirectory(prefix="residual_case_") as folder:
        path = write_rig_file(Path(folder) / "rig.yaml", case.rig, pert)
        declared, free = load_rig(path), read_free(path)
    settings = an.Settings(reference_temperature=an.Settings().reference_temperature
                           + pert.get("reference_temperature", 0.0))
    signals = prepare_signals(declared, data, settings.alpha_time_constant, settings.reference_temperature)
    split = an.make_split(signals, settings, rig=declared)
    problem = an.Problem(declared, free, signals, data.current_drive, split, settings)
    result = an.analyse(problem)
    values = dict(result.final.free_values)
    return CaseResult(case, tuple(sorted(result.found)), result.rms_before, result.final.rms_held_out,
                      result.noise.rms, None if result.unexplained is None else result.unexplained.rms,
                      {p: v / get_value(declared, p) if get_value(declared, p) else math.nan
                       for p, v in values.items()},
                      time.monotonic() - start, values, {p: get_value(plant, p) for p in values})


def run_matrix(cases: Sequence[Case], rig: Rig | None = None,
               progress: Callable[[int, CaseResult], None] | None = None,
               workers: int | None = None) -> list[CaseResult]:
    """Every case's result, in the cases' order. The cases are independent and seeded, so they run in
    ``workers`` processes (default: one per CPU; 1: in this process) with the same results; ``progress``
    hears of each as it ends."""
    workers = min(len(cases), workers if workers is not None else (os.cpu_count() or 1))
    if workers <= 1:
        out = []
        for k, case in enumerate(cases):
            out.append(run_case(case, rig))
            if progress:
                progress(k + 1, out[-1])
        return out
    # spawn, not fork: the caller may hold threads (rclpy, pytest plug-ins) that a fork would copy mid-state
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(run_case, case, rig) for case in cases]
        for k, _done in enumerate(as_completed(futures)):
            if progress:
                progress(k + 1, _done.result())
        return [f.result() for f in futures]
