"""Live calibration's core: one rig on the graph, the grid's points one after the other.

The rig (sim_node now, driver_node on the real rig: both publish
worm_msgs/RigSamples on /rig/samples) is held at each point by controller_node,
which tracks the speed set-point published on /controller/speed_setpoint,
while the load motors apply the point's torque (/rig/load_command). This
module only decides what to measure and when a point is done; the ROS shell
(calibration_node) moves the messages. Per point:

  1. the shell commands the current point's load torque and speed set-point,
     waits until controller_node's drive commands carry the new set-point,
     then calls :meth:`PointByPoint.start`;
  2. every sample goes to :meth:`PointByPoint.add`, which applies the same
     SteadyStateDetector as the batch path (settle time, windows, timeout);
     samples with a NaN/inf channel are skipped and counted;
  3. when the point is steady (or timed out), its window's means and spreads
     go into the journal (written atomically), and the next pending point
     becomes current.

The plan order and the journal are the batch path's (calibration_journal), so
``calibrate --live --resume`` continues an interrupted live run, and the
database is built the same way. Plain Python/numpy; no ROS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from worm_model.physics.parameters import Rig, rig_to_dict

from torque_estimator.calibration.batch import CalibrationGrid, grid_settings
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.calibration.journal import CalibrationJournal
from torque_estimator.calibration.operating_points import SteadyStateCriterion, SteadyStateDetector
from torque_estimator.session.topics import TOPICS  # recorded in the journal's settings

@dataclass(frozen=True)
class Point:
    """One point of the plan: its plan index, worm speed [rad/s] and load torque [N m]."""

    plan_index: int
    speed: float
    torque: float


def live_settings(grid: CalibrationGrid, rig: Rig, criterion: SteadyStateCriterion) -> dict:
    """The journal settings of a live calibration."""
    return {"source": "live", **grid_settings(grid, rig, criterion), "topics": dict(TOPICS)}


class PointByPoint:
    """Sequences the journal's pending points on one rig fed sample by sample (see module docstring).

    Args:
        grid: the calibration grid (its points() order is the plan).
        journal: the run's journal; points already in it are not measured again.
        criterion: steady-state criterion.
        sample_period: the rig's sample period [s] (windows are counted in samples).
    """

    def __init__(self, grid: CalibrationGrid, journal: CalibrationJournal, criterion: SteadyStateCriterion,
                 sample_period: float) -> None:
        self.grid = grid
        self.journal = journal
        self.criterion = criterion
        self.sample_period = sample_period
        self._speeds, self._torques, self._index = grid.points()
        self._queue = [int(i) for i in journal.pending()]
        self._detector: SteadyStateDetector | None = None
        #: samples skipped because a channel was NaN/inf
        self.skipped_samples = 0

    @property
    def current(self) -> Point | None:
        """The point being measured or about to be; None when every point is done."""
        if not self._queue:
            return None
        i = self._queue[0]
        return Point(i, float(self._speeds[i]), float(self._torques[i]))

    @property
    def measuring(self) -> bool:
        """start() was called for the current point and it is not finished yet."""
        return self._detector is not None

    @property
    def point_progress(self) -> float:
        """Samples taken for the current point as a fraction of its timeout (0 when not measuring)."""
        if self._detector is None:
            return 0.0
        return min(1.0, self._detector.count / max(1, self._detector.timeout_samples))

    def start(self) -> None:
        """The rig runs at the current point's set-points from now on: start counting samples."""
        point = self.current
        if point is None:
            raise RuntimeError("no point left to measure")
        self._detector = SteadyStateDetector(self.criterion, self.sample_period, [point.speed])

    def add(self, omega_worm: float, current_drive: float, tau_load: float) -> bool:
        """Feed one sample: worm speed [rad/s], drive current [A], measured load torque [N m].

        Ignored unless measuring. Returns True when this sample finished the
        current point (it is then in the journal and the next point is current).
        """
        detector = self._detector
        if detector is None:
            return False
        if not (math.isfinite(omega_worm) and math.isfinite(current_drive) and math.isfinite(tau_load)):
            self.skipped_samples += 1
            return False
        detector.add(omega_worm, current_drive, tau_load)
        if not detector.finished:
            return False
        point = self.current
        assert point is not None
        self.journal.record([point.plan_index], detector.result([point.torque]))
        self._queue.pop(0)
        self._detector = None
        return True

    def database(self, rig: Rig) -> CalibrationDatabase:
        """The finished calibration database (every point measured)."""
        return self.journal.database(self._index, self.grid.speeds, self.grid.torques, rig_to_dict(rig),
                                     self.criterion.to_dict(),
                                     notes=f"live rig on the ROS graph ({TOPICS['samples']}), held by "
                                           f"controller_node, sample period {self.sample_period:g} s")


__all__ = ["Point", "PointByPoint", "live_settings"]
