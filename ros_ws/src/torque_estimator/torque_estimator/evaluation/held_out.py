"""Held-out evaluation of an estimator, like the paper's Table 3 and Figure 13, and its sweeps.

Operating points not in the calibration grid (random speeds and torques, both
signs, both directions) are measured quasi-statically on the simulated rig the
same way calibration was; the estimator maps each measured (omega, i) to tau_d,
and the error is reported as a percentage of the calibrated torque range
(max - min of the database's tau_load). The truth is the load torque the
simulated load motors applied, averaged over the same window.

Sweeps redo this while changing one thing: the estimator's k (and weighting),
the grid density (points per axis of the calibration), or the sensor noise
(both calibration and held-out points measured with it).
Plain numpy; no ROS.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from worm_model.physics.parameters import Rig

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated, measure_on_simulator
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.base import EstimateFlags, TorqueEstimator
from torque_estimator.estimation.registry import make_estimator
from torque_estimator.calibration.operating_points import OperatingPoints


@dataclass
class Evaluation:
    """Per-point results and the summary; arrays of shape (n,)."""

    omega_worm: np.ndarray  # [rad/s] measured mean speed
    current_drive: np.ndarray  # [A] measured mean current
    tau_true: np.ndarray  # [N m] applied load torque (simulator truth)
    tau_estimated: np.ndarray  # [N m]
    flags: np.ndarray  # EstimateFlags bits
    torque_range: float  # [N m] calibrated range the percentages refer to

    @property
    def error_pct(self) -> np.ndarray:
        """|estimate - truth| as % of the calibrated torque range."""
        return 100.0 * np.abs(self.tau_estimated - self.tau_true) / self.torque_range

    @property
    def mae_pct(self) -> float:
        """Mean of error_pct [%]."""
        return float(np.mean(self.error_pct))

    @property
    def max_pct(self) -> float:
        """Largest error_pct [%]."""
        return float(np.max(self.error_pct))


def held_out_setpoints(grid: CalibrationGrid, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n random (speed, torque) set-points inside the grid's span but off its nodes.

    The four quadrants (direction of rotation x sign of the torque) take turns,
    so any n >= 4 has both directions and both torque signs, i.e. resistive and
    assistive loads each way. Speed magnitudes are drawn uniformly between the
    smallest and largest calibrated ones, torques uniformly within the
    calibrated span on their side of zero. A draw closer than 20 % of a grid
    step to a grid node in both coordinates is redrawn.
    """
    rng = np.random.default_rng(seed)
    magnitudes = np.unique(np.abs(grid.speeds))
    speed_step = np.min(np.diff(magnitudes)) if len(magnitudes) > 1 else magnitudes[0]
    torque_step = np.min(np.diff(grid.torques))
    low, high = grid.torques[0], grid.torques[-1]
    speeds, torques = [], []
    while len(speeds) < n:
        quadrant = len(speeds) % 4
        direction = 1.0 if quadrant in (0, 3) else -1.0
        positive = quadrant < 2
        speed = direction * rng.uniform(magnitudes[0], magnitudes[-1])
        torque = rng.uniform(max(0.0, low), high) if positive else rng.uniform(low, min(0.0, high))
        near_speed = np.min(np.abs(np.abs(speed) - magnitudes)) < 0.2 * speed_step
        near_torque = np.min(np.abs(torque - grid.torques)) < 0.2 * torque_step
        if not (near_speed and near_torque):
            speeds.append(speed)
            torques.append(torque)
    return np.array(speeds), np.array(torques)


def measure_held_out(rig: Rig, grid: CalibrationGrid, n: int = 17, seed: int = 1, effects=None) -> OperatingPoints:
    """Measure n held-out points (held_out_setpoints(grid, n, seed)) on the simulated rig
    (with ``effects`` switched on in the simulator, if given).

    The noise seed differs from any calibration's (seed + 1000).
    """
    speeds, torques = held_out_setpoints(grid, n, seed)
    return measure_on_simulator(rig, speeds, torques, seed=seed + 1000, effects=effects)


def score(estimator: TorqueEstimator, measured: OperatingPoints, torque_range: float) -> Evaluation:
    """Estimate every measured point and compare with the applied load (an estimator that takes the gear
    ripple out, ``uses_angle``, also gets each window's encoder angles, as it gets every sample's live)."""
    if getattr(estimator, "uses_angle", False) and measured.theta_worm is not None:
        result = estimator.estimate(measured.omega_worm, measured.current_drive, theta_worm=measured.theta_worm)
    else:
        result = estimator.estimate(measured.omega_worm, measured.current_drive)
    return Evaluation(omega_worm=measured.omega_worm, current_drive=measured.current_drive,
                      tau_true=measured.tau_true, tau_estimated=np.asarray(result.torque),
                      flags=np.asarray(result.flags), torque_range=torque_range)


def evaluate_held_out(rig: Rig, estimator: TorqueEstimator, grid: CalibrationGrid, torque_range: float,
                      n: int = 17, seed: int = 1) -> Evaluation:
    """Measure n held-out points on the simulated rig and estimate each (seed differs from calibration's)."""
    return score(estimator, measure_held_out(rig, grid, n, seed), torque_range)


def flag_names(flags: int) -> str:
    """'AMBIGUOUS,OUT_OF_CALIBRATION' for a flags value, '-' for none."""
    return ",".join(f.name for f in EstimateFlags if f and int(flags) & f) or "-"


def format_table(ev: Evaluation, indent: str = "  ") -> list[str]:
    """The paper's Table 3 layout: speed, current, true and estimated tau_d, error %, one row per test."""
    lines = [f"{indent} #  speed [rad/s]  current [A]  true τ_d [N·m]  est. τ_d [N·m]  error [%]  flags"]
    for i in range(len(ev.tau_true)):
        lines.append(f"{indent}{i + 1:2d} {ev.omega_worm[i]:14.1f} {ev.current_drive[i]:12.3f} "
                     f"{ev.tau_true[i]:15.4f} {ev.tau_estimated[i]:15.4f} {ev.error_pct[i]:10.2f}  "
                     f"{flag_names(ev.flags[i])}")
    return lines


# --- sweeps ------------------------------------------------------------------------------------------

@dataclass
class SweepResult:
    """One sweep: the values of the swept quantity and the errors at each, in % of the torque range."""

    name: str  # what was swept
    unit: str
    values: np.ndarray
    mae_pct: dict[str, np.ndarray]  # curve label -> mean error at each value
    max_pct: dict[str, np.ndarray]  # curve label -> largest error at each value


def sweep_k(db: CalibrationDatabase, measured: OperatingPoints, ks, method: str = "knn",
            weightings=("inverse_distance", "uniform")) -> SweepResult:
    """Error against the number of neighbours k, for each weighting, on one set of measured points."""
    ks = np.asarray(ks, dtype=int)
    mae, worst = {}, {}
    for weighting in weightings:
        evs = [score(make_estimator(method, db, k=int(k), weighting=weighting), measured, db.torque_range)
               for k in ks]
        mae[weighting] = np.array([ev.mae_pct for ev in evs])
        worst[weighting] = np.array([ev.max_pct for ev in evs])
    return SweepResult("neighbours k", "1", ks, mae, worst)


def _same_grid(db: CalibrationDatabase | None, grid: CalibrationGrid) -> bool:
    return (db is not None and np.array_equal(db.speed_setpoints, grid.speeds)
            and np.array_equal(db.torque_setpoints, grid.torques))


def _calibrate_once(rig: Rig, grid: CalibrationGrid, seed: int) -> CalibrationDatabase:
    # The whole grid in one batch: a sweep calibrates many grids and one batch is the fastest.
    return calibrate_simulated(rig, grid, seed=seed, batch_size=len(grid.speeds) * len(grid.torques))


def sweep_grid_density(rig: Rig, sizes, measured: OperatingPoints, *, seed: int = 0, method: str = "knn",
                       options: dict | None = None, reference: CalibrationDatabase | None = None,
                       progress: Callable[[], None] | None = None) -> SweepResult:
    """Error against the grid density: calibrate CalibrationGrid.paper(rig, speeds, torques) for each
    (speeds per direction, torques) in sizes; score all on the same measured held-out points.
    The swept value is the number of calibration points. A size whose grid is the reference
    database's uses that database (so the sweep passes through the main evaluation's figure)."""
    mae, worst, counts = [], [], []
    for n_speeds, n_torques in sizes:
        grid = CalibrationGrid.paper(rig, n_speeds, n_torques)
        db = reference if _same_grid(reference, grid) else _calibrate_once(rig, grid, seed)
        ev = score(make_estimator(method, db, **(options or {})), measured, db.torque_range)
        counts.append(len(db))
        mae.append(ev.mae_pct)
        worst.append(ev.max_pct)
        if progress is not None:
            progress()
    return SweepResult("calibration points", "1", np.array(counts), {method: np.array(mae)},
                       {method: np.array(worst)})


def with_noise(rig: Rig, factor: float) -> Rig:
    """The rig with its current and tachogenerator noise scaled by factor (ripple and ADC step kept)."""
    s = rig.sensors
    return replace(rig, sensors=replace(s, current_noise_std=factor * s.current_noise_std,
                                        tacho_noise_std=factor * s.tacho_noise_std))


def sweep_noise(rig: Rig, grid: CalibrationGrid, factors, n_points: int, *, seed: int = 0, method: str = "knn",
                options: dict | None = None,
                reference: tuple[CalibrationDatabase, OperatingPoints] | None = None,
                progress: Callable[[], None] | None = None) -> SweepResult:
    """Error against sensor noise: for each factor, calibrate and measure the held-out points on a rig
    whose current and speed noise are that many times the rig's. Factor 1 uses the reference
    (database, held-out points measured on the rig itself) when given. With no noise at all the
    current ADC's step is not dithered any more, so window means are quantised: the error does not
    fall to 0."""
    mae, worst = [], []
    for factor in factors:
        if factor == 1.0 and reference is not None and _same_grid(reference[0], grid):
            db, measured = reference
        else:
            noisy = with_noise(rig, float(factor))
            db = _calibrate_once(noisy, grid, seed)
            measured = measure_held_out(noisy, grid, n_points, seed + 1)
        ev = score(make_estimator(method, db, **(options or {})), measured, db.torque_range)
        mae.append(ev.mae_pct)
        worst.append(ev.max_pct)
        if progress is not None:
            progress()
    return SweepResult("sensor noise (x the rig's)", "1", np.asarray(factors, dtype=float),
                       {method: np.array(mae)}, {method: np.array(worst)})


__all__ = ["Evaluation", "SweepResult", "held_out_setpoints", "measure_held_out", "score", "evaluate_held_out",
           "flag_names", "format_table", "sweep_k", "sweep_grid_density", "sweep_noise", "with_noise"]
