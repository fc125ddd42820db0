"""Held-out evaluation of an estimator, like the paper's Table 3 and Figure 13.

Operating points not in the calibration grid (random speeds and torques, both
signs, both directions) are measured quasi-statically on the simulated rig the
same way calibration was; the estimator maps each measured (omega, i) to tau_d,
and the error is reported as a percentage of the calibrated torque range.
Plain numpy; no ROS.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_model.parameters import Rig

from .calibration import CalibrationGrid, measure_on_simulator
from .estimator import TorqueEstimator


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
        return float(np.mean(self.error_pct))

    @property
    def max_pct(self) -> float:
        return float(np.max(self.error_pct))


def held_out_setpoints(grid: CalibrationGrid, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n random (speed, torque) set-points inside the grid's span but off its nodes.

    Speeds are drawn between the smallest and largest calibrated magnitudes
    with a random direction; torques within the calibrated span. A draw closer
    than 20 % of a grid step to a grid node in both coordinates is redrawn.
    """
    rng = np.random.default_rng(seed)
    magnitudes = np.unique(np.abs(grid.speeds))
    speed_step = np.min(np.diff(magnitudes)) if len(magnitudes) > 1 else magnitudes[0]
    torque_step = np.min(np.diff(grid.torques))
    speeds, torques = [], []
    while len(speeds) < n:
        speed = rng.uniform(magnitudes[0], magnitudes[-1]) * rng.choice((-1.0, 1.0))
        torque = rng.uniform(grid.torques[0], grid.torques[-1])
        near_speed = np.min(np.abs(np.abs(speed) - magnitudes)) < 0.2 * speed_step
        near_torque = np.min(np.abs(torque - grid.torques)) < 0.2 * torque_step
        if not (near_speed and near_torque):
            speeds.append(speed)
            torques.append(torque)
    return np.array(speeds), np.array(torques)


def evaluate_held_out(rig: Rig, estimator: TorqueEstimator, grid: CalibrationGrid, torque_range: float,
                      n: int = 17, seed: int = 1) -> Evaluation:
    """Measure n held-out points on the simulated rig and estimate each (seed differs from calibration's)."""
    speeds, torques = held_out_setpoints(grid, n, seed)
    measured = measure_on_simulator(rig, speeds, torques, seed=seed + 1000)
    result = estimator.estimate(measured.omega_worm, measured.current_drive)
    return Evaluation(omega_worm=measured.omega_worm, current_drive=measured.current_drive,
                      tau_true=measured.tau_true, tau_estimated=np.asarray(result.torque),
                      flags=np.asarray(result.flags), torque_range=torque_range)
