"""The paper's calibration experiment (section 3.2) on a simulated rig.

Grid: constant worm speeds (both directions) x constant load torques spanning
resistive, pseudo-resistive and assistive loads; each point is held by the
speed controller until steady (operating_points.SteadyStateCriterion) and its
window averaged. The result is a CalibrationDatabase, the map the k-NN
estimator interpolates. Plain numpy; no ROS.
"""
from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Callable

import numpy as np

from worm_model.parameters import Rig, rig_to_dict
from worm_rig_driver.simulated_rig import SimulatedRig

from .calibration_database import CalibrationDatabase
from .operating_points import OperatingPoints, SteadyStateCriterion, measure_operating_points
from .speed_controller import DEFAULT_GAINS, PiGains, SpeedController


@dataclass(frozen=True)
class CalibrationGrid:
    """Speeds [rad/s] (signed: both directions listed) x load torques [N m]."""

    speeds: np.ndarray
    torques: np.ndarray

    @classmethod
    def paper(cls, rig: Rig, n_speeds: int = 17, n_torques: int = 16, speed_min: float = 20.0,
              speed_max: float = 340.0, torque_fraction: float = 0.9) -> "CalibrationGrid":
        """The paper's 17 speeds x 16 torques, in both directions of rotation.

        Torques span +-torque_fraction of what the load motors can make
        (Rig.max_load_torque), so both signs, hence all three modes, are covered.
        """
        if not (0 < speed_min < speed_max) or n_speeds < 1 or n_torques < 2 or not 0 < torque_fraction <= 1:
            raise ValueError("grid needs 0 < speed_min < speed_max, n_speeds >= 1, n_torques >= 2, "
                             "0 < torque_fraction <= 1")
        magnitudes = np.linspace(speed_min, speed_max, n_speeds)
        tau_max = torque_fraction * rig.max_load_torque
        return cls(speeds=np.concatenate([-magnitudes[::-1], magnitudes]),
                   torques=np.linspace(-tau_max, tau_max, n_torques))

    def points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(speed set-point, torque set-point, (speed index, torque index)) of every grid point."""
        si, ti = np.meshgrid(np.arange(len(self.speeds)), np.arange(len(self.torques)), indexing="ij")
        index = np.column_stack((si.ravel(), ti.ravel()))
        return self.speeds[index[:, 0]], self.torques[index[:, 1]], index


def measure_on_simulator(rig: Rig, speeds, torques, *, seed: int = 0, gains: PiGains = DEFAULT_GAINS,
                         criterion: SteadyStateCriterion = SteadyStateCriterion(),
                         progress: Callable[[float], None] | None = None) -> OperatingPoints:
    """Measure operating points on simulated rigs, one rig per point, all at once."""
    speeds = np.asarray(speeds, dtype=float)
    sim = SimulatedRig(rig, n=len(speeds), seed=seed)
    controller = SpeedController(rig, gains, n=len(speeds))
    return measure_operating_points(sim, controller, speeds, torques, criterion, progress)


def calibrate_simulated(rig: Rig, grid: CalibrationGrid, *, seed: int = 0, gains: PiGains = DEFAULT_GAINS,
                        criterion: SteadyStateCriterion = SteadyStateCriterion(),
                        progress: Callable[[float], None] | None = None) -> CalibrationDatabase:
    """Run the calibration grid on the simulated rig and return the database."""
    speeds, torques, index = grid.points()
    measured = measure_on_simulator(rig, speeds, torques, seed=seed, gains=gains, criterion=criterion,
                                    progress=progress)
    unsettled = np.flatnonzero(~measured.settled)
    return CalibrationDatabase(
        omega_worm=measured.omega_worm, current_drive=measured.current_drive, tau_load=measured.tau_load,
        omega_std=measured.omega_std, current_std=measured.current_std, tau_std=measured.tau_std,
        samples=measured.samples, speed_setpoints=grid.speeds, torque_setpoints=grid.torques,
        setpoint_index=index, rig=rig_to_dict(rig),
        created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
        steady_state={**criterion.to_dict(), "unsettled_points": unsettled.tolist()},
        notes=f"simulated rig, seed {seed}, PI gains kp={gains.kp} ki={gains.ki}",
    )
