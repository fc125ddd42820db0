"""The fast road checked on the simulator: identify from one short run, estimate on held-out points.

The simulated rig runs with every default effect on (worm_rig_driver ``config/effects_all.yaml``)
and its true, bundled parameters; the rig file the user gives ``identify`` is the bundled one
off by realistic amounts (:data:`DECLARED_OFF`: mu x1.3, K_t x1.05, drags x2, each then carrying
a ``source:``; evaluation.residual_cases.rig_files.write_rig_file).  One excitation (identification.excitation,
<= 90 s of rig time) is recorded, identified, and written as an extended rig file; then, on the same
held-out points
(evaluation.held_out, 17 by default, measured on the same simulated rig):

* ``knn``: the paper's map calibrated point by point on that rig (544 points);
* ``declared``: the extended model of the rig file as given (nothing identified);
* ``identified``: the extended model identify wrote (extended_model estimator);
* ``observer``: the observer with the identified parameters (its ``model_file``).

Percentages are of the k-NN calibration's torque range, as in ``make evaluate``.  Also the rig
time each road costs: the identification's record, and a live calibration's (the sum over the
grid's points of the time each took to settle and be averaged: the batch path runs them side by
side, a live rig one after the other).  No ROS.
"""
from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from worm_model.physics.parameters import Rig
from worm_rig_driver.sim.effects import EFFECTS, EffectsConfig

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.calibration.operating_points import SteadyStateCriterion, SteadyStateDetector
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.evaluation.held_out import Evaluation, measure_held_out, score
from torque_estimator.evaluation.residual_cases.rig_files import write_rig_file
from torque_estimator.identification.excitation import DEFAULT_DURATION, default_excitation, total_duration
from torque_estimator.identification.fit import identify
from torque_estimator.identification.writing import write_identified
from torque_estimator.identification.simulated import record_on_simulator

#: the declared values' errors: mu x1.3, K_t x1.05, drags x2 (perturbation groups of evaluation.residual_cases)
DECLARED_OFF = {"mu": 1.3, "torque_constant": 1.05, "drags": 2.0}


def effects_all():
    """Every simulator effect at its default: what worm_rig_driver's config/effects_all.yaml holds."""
    return EffectsConfig.defaults(*EFFECTS)


@dataclass
class RoadResult:
    """Held-out evaluations per road and what each cost."""

    evaluations: dict[str, Evaluation]
    identification_rig_time: float  # [s]
    identification_wall_time: float  # [s] recording (simulated) + fit
    found: list[str]
    corrections: dict[str, tuple[float, float, float]]
    model_file: Path


def run_roads(rig: Rig, db, grid: CalibrationGrid, *, points: int = 17, seed: int = 1, effects=None,
              duration: float = DEFAULT_DURATION, out: Path | None = None) -> RoadResult:
    """Identify on the simulated rig with ``effects`` (default: all) from a declared file off by DECLARED_OFF,
    then score every road on ``points`` held-out points measured on the same rig (``db``: the k-NN's
    calibration on that rig; its torque range is the percentages')."""
    effects = effects_all() if effects is None else effects
    folder = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="identified_"))
    folder.mkdir(parents=True, exist_ok=True)
    declared_file = write_rig_file(folder / "declared_rig.yaml", "nmrv030", DECLARED_OFF)
    start = time.monotonic()
    timeline = default_excitation(rig, duration)
    data = record_on_simulator(rig, timeline, effects=effects, seed=seed + 2000)
    ident = identify(data, declared_file)
    model_file = folder / "identified_rig.yaml"
    write_identified(model_file, declared_file, ident, "simulated rig, effects_all.yaml")
    wall = time.monotonic() - start
    measured = measure_held_out(rig, grid, points, seed, effects=effects)
    # each road's estimator as estimator_node and `estimate` build it from the files a user has at that point
    settings = {"knn": EstimatorSettings("knn"),
                "declared": EstimatorSettings("extended_model", rig_file=str(declared_file)),
                "identified": EstimatorSettings("extended_model", model_file=str(model_file)),
                "observer": EstimatorSettings("observer", model_file=str(model_file))}
    evaluations = {name: score(build_estimator(s, database=db if name == "knn" else None).estimator, measured,
                               db.torque_range) for name, s in settings.items()}
    return RoadResult(evaluations, total_duration(timeline), wall, list(ident.analysis.found), ident.corrections,
                      model_file)


def live_grid_rig_time(rig: Rig, grid: CalibrationGrid, *, effects=None, seed: int = 0,
                       criterion: SteadyStateCriterion = SteadyStateCriterion()) -> float:
    """Rig time [s] a live calibration of ``grid`` takes: per point, the samples until its steady window
    is kept (or the timeout), summed over the points (a live rig measures them one after the other)."""
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController  # noqa: PLC0415
    from worm_rig_driver.sim.simulated_rig import SimulatedRig  # noqa: PLC0415

    speeds, torques, _index = grid.points()
    sim = SimulatedRig(rig, n=len(speeds), seed=seed, effects=effects, scalar=False)
    loop = SpeedController(rig, DEFAULT_GAINS, n=len(speeds))
    detector = SteadyStateDetector(criterion, sim.sample_period, speeds)
    done_at = np.full(len(speeds), np.nan)
    sim.command(voltage_drive=0.0, load_torque=torques)
    while not detector.finished:
        m = sim.sample()
        if detector.add(m.omega_worm, m.current_drive, m.tau_load):
            done_at = np.where(np.isnan(done_at) & detector.settled, detector.count, done_at)
        sim.command(voltage_drive=loop.update(sim.sample_period, speeds, m.omega_worm).voltage)
    done_at = np.where(np.isnan(done_at), detector.count, done_at)
    return float(done_at.sum() * sim.sample_period)


def table_lines(result: RoadResult, knn_points: int, grid_rig_time: float | None = None) -> list[str]:
    """The side-by-side table ``make evaluate`` prints, and its ``identify:`` line last."""
    ev = result.evaluations
    lines = [f"\nThe fast road: identify from one {result.identification_rig_time:.0f} s run vs the k-NN grid "
             f"(simulated rig, every default effect on; rig file off by mu x1.3, K_t x1.05, drags x2; "
             f"{len(ev['knn'].tau_true)} held-out points, % of the torque range)",
             "  road                                   held-out mean   max      rig time"]
    grid_time = f"{grid_rig_time:.0f} s" if grid_rig_time is not None else "-"
    rows = (("knn", f"k-NN on the {knn_points}-point grid", grid_time),
            ("declared", "extended model, rig file as declared", "0 s"),
            ("identified", "extended model, identified", f"{result.identification_rig_time:.0f} s"),
            ("observer", "observer, identified parameters", f"{result.identification_rig_time:.0f} s"))
    for key, label, cost in rows:
        lines.append(f"  {label:38s} {ev[key].mae_pct:8.2f} %  {ev[key].max_pct:6.2f} %   {cost}")
    lines.append(f"  found: {', '.join(result.found) or 'none'}; corrections: " + ", ".join(
        f"{p} {d:.4g} -> {v:.4g}" for p, (d, v, _ci) in result.corrections.items()))
    lines.append(f"identify: rig_time_s={result.identification_rig_time:.1f} "
                 f"identified_mae_pct={ev['identified'].mae_pct:.2f} identified_max_pct={ev['identified'].max_pct:.2f} "
                 f"observer_mae_pct={ev['observer'].mae_pct:.2f} observer_max_pct={ev['observer'].max_pct:.2f} "
                 f"knn_mae_pct={ev['knn'].mae_pct:.2f} knn_max_pct={ev['knn'].max_pct:.2f}")
    return lines


def evaluate_lines(rig: Rig, points: int = 17, seed: int = 1, k: int = 4, weighting: str = "inverse_distance",
                   with_grid_time: bool = True) -> list[str]:
    """What ``make evaluate`` prints for the fast road: calibrate the k-NN grid on the effects rig, identify,
    score all on the same held-out points."""
    effects = effects_all()
    grid = CalibrationGrid.paper(rig)
    db = calibrate_simulated(rig, grid, seed=seed - 1, effects=effects, batch_size=len(grid.speeds) * len(grid.torques))
    result = run_roads(rig, db, grid, points=points, seed=seed, effects=effects)
    knn = build_estimator(EstimatorSettings("knn", options={"k": k, "weighting": weighting}), database=db)
    measured = measure_held_out(rig, grid, points, seed, effects=effects)
    result.evaluations["knn"] = score(knn.estimator, measured, db.torque_range)
    grid_time = live_grid_rig_time(rig, grid, effects=effects) if with_grid_time else None
    return table_lines(result, len(db), grid_time)


__all__ = ["DECLARED_OFF", "RoadResult", "effects_all", "evaluate_lines", "live_grid_rig_time", "run_roads",
           "table_lines"]
