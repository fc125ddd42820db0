"""The paper's calibration experiment (section 3.2) on a simulated rig.

Grid: constant worm speeds (both directions) x constant load torques spanning
resistive, pseudo-resistive and assistive loads; each point is held by the
speed controller until steady (operating_points.SteadyStateCriterion) and its
window averaged. The result is a CalibrationDatabase, the map the k-NN
estimator interpolates.

This is the fast batch path: batches of points run side by side on a
vectorised SimulatedRig in this process, with a journal after every batch
(calibration_journal) so an interrupted run resumes. The same grid, criterion
and journal drive a rig on the ROS graph point by point in live_calibration.
Plain numpy; no ROS.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from worm_model.physics.parameters import Rig, rig_to_dict
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.calibration.journal import CalibrationJournal
from torque_estimator.calibration.operating_points import (OperatingPoints, SteadyStateCriterion,
                                                            measure_operating_points)
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiGains, SpeedController


#: Points simulated side by side per batch: a quarter of the paper's grid. Bigger batches
#: are faster (a step of n rigs costs ~0.3 ms + 0.3 us x n), smaller ones journal more often.
DEFAULT_BATCH_SIZE = 136


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
                         progress: Callable[[float], None] | None = None, effects=None) -> OperatingPoints:
    """Measure operating points on simulated rigs, one rig per point, all at once.

    ``effects``: the simulator's effects the model lacks (SimulatedRig's ``effects``; None: none)."""
    speeds = np.asarray(speeds, dtype=float)
    sim = SimulatedRig(rig, n=len(speeds), seed=seed, effects=effects, scalar=False if effects else None)
    controller = SpeedController(rig, gains, n=len(speeds))
    return measure_operating_points(sim, controller, speeds, torques, criterion, progress)


def grid_settings(grid: CalibrationGrid, rig: Rig, criterion: SteadyStateCriterion) -> dict:
    """The settings every calibration run records in its journal: grid, criterion, rig parameters."""
    rig_values = {key: value for key, value in rig_to_dict(rig).items() if key != "source"}  # not where it was read
    return {"grid": {"speed_setpoints": grid.speeds.tolist(), "torque_setpoints": grid.torques.tolist()},
            "steady_state": criterion.to_dict(), "rig": rig_values}


def batch_seed(seed: int, batch: int) -> int:
    """Noise seed of one batch: a function of (seed, batch) only, so a batch measured after a
    resume draws exactly the noise it would have drawn in an uninterrupted run."""
    return int(np.random.SeedSequence([seed, batch]).generate_state(1)[0])


def calibrate_simulated(rig: Rig, grid: CalibrationGrid, *, seed: int = 0, gains: PiGains = DEFAULT_GAINS,
                        criterion: SteadyStateCriterion = SteadyStateCriterion(),
                        progress: Callable[[float], None] | None = None, batch_size: int = DEFAULT_BATCH_SIZE,
                        journal: Path | None = None, resume: bool = False,
                        drop_bad_points: bool = False, effects=None) -> CalibrationDatabase:
    """Run the calibration grid on the simulated rig and return the database.

    The plan's points (CalibrationGrid.points() order) are cut into batches of
    batch_size consecutive points; each batch runs side by side on its own
    SimulatedRig seeded with batch_seed(seed, batch), so results do not depend
    on which batches ran in which process.

    Args:
        progress: called with the fraction of the grid's points done.
        journal: journal file written after every batch (calibration_journal); None: none.
        resume: continue the journal at `journal` if it exists.
        drop_bad_points: measure again the points the journal holds with bad values
            (CalibrationJournal.open) instead of refusing it.
        effects: effects switched on in the simulator only (SimulatedRig's ``effects``); None: none.

    Raises:
        calibration_journal.JournalError: a journal exists and resume is False, or
            it was taken with other settings.
    """
    if batch_size < 1:
        raise ValueError(f"batch_size must be >= 1, got {batch_size}")
    speeds, torques, index = grid.points()
    n = len(speeds)
    settings = {"source": "simulator", **grid_settings(grid, rig, criterion), "seed": seed,
                "gains": {"kp": gains.kp, "ki": gains.ki}, "batch_size": batch_size}
    if effects is not None:  # only then: journals of runs without effects keep their settings
        settings["effects"] = effects if isinstance(effects, dict) else str(effects)
    book = CalibrationJournal.open(journal, settings, n, resume, drop_bad_points)
    pending = set(book.pending().tolist())
    for batch, first in enumerate(range(0, n, batch_size)):
        members = np.arange(first, min(first + batch_size, n))
        if not pending.intersection(members.tolist()):
            continue  # measured before the interruption
        done = len(book.points)
        report = None if progress is None else (lambda f, d=done, m=len(members): progress((d + f * m) / n))
        measured = measure_on_simulator(rig, speeds[members], torques[members], seed=batch_seed(seed, batch),
                                        gains=gains, criterion=criterion, progress=report, effects=effects)
        book.record(members, measured)
        if progress is not None:
            progress(len(book.points) / n)
    db = book.database(index, grid.speeds, grid.torques, rig_to_dict(rig), criterion.to_dict(),
                       notes=f"simulated rig, seed {seed}, PI gains kp={gains.kp} ki={gains.ki}, "
                             f"batches of {batch_size} points")
    return db
