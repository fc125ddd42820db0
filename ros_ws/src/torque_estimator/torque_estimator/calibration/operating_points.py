"""Quasi-static measurement of operating points, as the paper's experiments did.

For each (speed set-point, load-torque set-point) the drive motor is held at
speed by the PI controller while the load motors apply the torque; once the
steady-state criterion holds over a whole averaging window, the window's mean
and spread of every channel are kept. Calibration measures the grid this way,
evaluation measures held-out points the same way.

SteadyStateDetector applies the criterion to samples as they come, for n
points at once: measure_operating_points runs an ensemble of simulated rigs
side by side (one per point, a full 17 x 16 x 2 grid settles in seconds);
live calibration (calibrate --live) feeds it one rig's samples off the graph.
Plain numpy; no ROS.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np

from worm_rig_driver.sim.simulated_rig import SimulatedRig

from worm_rig_driver.drive.speed_loop import SpeedController


@dataclass(frozen=True)
class SteadyStateCriterion:
    """When a point counts as steady, and how it is averaged.

    A point is steady when, over one averaging window (after settle_time):
    |mean speed - set-point| <= speed_tolerance*|set-point| + speed_floor, and the
    mean current of the window's two halves differ by at most current_drift.
    """

    window: float = 0.5  # [s] averaging window
    settle_time: float = 0.5  # [s] earliest start of the first window
    timeout: float = 8.0  # [s] give up (point kept, marked unsettled)
    speed_tolerance: float = 0.02  # [1] relative speed error allowed
    speed_floor: float = 0.5  # [rad/s] absolute speed error allowed on top
    current_drift: float = 0.01  # [A] allowed drift of the mean current within a window

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class OperatingPoints:
    """Mean and spread of each channel over each point's steady window; arrays of shape (n,)."""

    speed_setpoint: np.ndarray  # [rad/s]
    torque_setpoint: np.ndarray  # [N m]
    omega_worm: np.ndarray  # [rad/s] mean measured worm speed
    omega_std: np.ndarray
    current_drive: np.ndarray  # [A] mean measured drive current
    current_std: np.ndarray
    tau_load: np.ndarray  # [N m] mean load torque from the load motors' measured currents
    tau_std: np.ndarray
    tau_true: np.ndarray  # [N m] mean load torque actually applied (simulator truth)
    samples: np.ndarray  # samples averaged
    settled: np.ndarray  # bool: the criterion held (else: the last window at timeout)
    #: [rad] encoder worm angle of each sample of the kept window, shape (n, samples), time order;
    #: None when the angles were not given (an estimator that takes the gear ripple out uses them)
    theta_worm: np.ndarray | None = None


class SteadyStateDetector:
    """The criterion applied to n points fed one sample at a time (batch and live alike).

    Counting starts at the first sample added. Windows of ``window`` samples
    are checked when the count is a multiple of the window and at least
    settle_time + window; the first steady window of a point is kept. At the
    first check at or after ``timeout`` every point not yet steady keeps that
    last window and stays marked unsettled, and the detector is finished.

    Args:
        criterion: the steady-state criterion.
        sample_period: time between samples [s].
        speed_setpoints: worm speed set-points [rad/s], shape (n,).
    """

    CHANNELS = ("omega_worm", "current_drive", "tau_load", "tau_true")

    def __init__(self, criterion: SteadyStateCriterion, sample_period: float, speed_setpoints) -> None:
        self.criterion = criterion
        self.speed_setpoints = np.atleast_1d(np.asarray(speed_setpoints, dtype=float))
        n = len(self.speed_setpoints)
        self.window = max(2, int(round(criterion.window / sample_period)))
        self.first_check = int(round(criterion.settle_time / sample_period)) + self.window
        self.timeout_samples = int(round(criterion.timeout / sample_period))
        self.count = 0
        self._buffers = {name: np.empty((self.window, n)) for name in self.CHANNELS}
        self.mean = {name: np.full(n, np.nan) for name in self.CHANNELS}
        self.std = {name: np.full(n, np.nan) for name in self.CHANNELS}
        self.settled = np.zeros(n, dtype=bool)
        self.finished = False
        #: (window being filled, kept windows) of the angles [rad], (window, n) each; None until angles are given
        self._theta: tuple[np.ndarray, np.ndarray] | None = None

    def add(self, omega_worm, current_drive, tau_load, tau_true=np.nan, theta_worm=None) -> bool:
        """Feed one sample of every point: speed [rad/s], current [A], load torque [N m]
        (measured, and the applied truth if known), the encoder's worm angle [rad] if known
        (kept per window: OperatingPoints.theta_worm). Returns True when a window was checked."""
        if self.finished:
            raise RuntimeError("SteadyStateDetector is finished; start a new one for new points")
        row = self.count % self.window
        self.count += 1
        for name, value in zip(self.CHANNELS, (omega_worm, current_drive, tau_load, tau_true)):
            self._buffers[name][row] = value
        if theta_worm is not None:
            if self._theta is None:
                shape = (self.window, len(self.speed_setpoints))
                self._theta = (np.full(shape, np.nan), np.full(shape, np.nan))
            self._theta[0][row] = theta_worm
        if self.count < self.first_check or self.count % self.window:
            return False
        buffers = self._buffers
        means = {name: buf.mean(axis=0) for name, buf in buffers.items()}
        half = self.window // 2
        current = buffers["current_drive"]  # rows are in time order at a check (count % window == 0)
        drift = np.abs(current[:half].mean(axis=0) - current[half:].mean(axis=0))
        c = self.criterion
        steady = ((np.abs(means["omega_worm"] - self.speed_setpoints)
                   <= c.speed_tolerance * np.abs(self.speed_setpoints) + c.speed_floor)
                  & (drift <= c.current_drift))
        last = self.count >= self.timeout_samples
        take = ~self.settled & (steady | last)
        for name, buf in buffers.items():
            self.mean[name] = np.where(take, means[name], self.mean[name])
            self.std[name] = np.where(take, buf.std(axis=0), self.std[name])
        if self._theta is not None:
            self._theta[1][:, take] = self._theta[0][:, take]
        self.settled |= steady
        self.finished = last or bool(self.settled.all())
        return True

    def result(self, torque_setpoints) -> OperatingPoints:
        """The kept windows (call once finished; before, unfinished points are NaN)."""
        return OperatingPoints(
            speed_setpoint=self.speed_setpoints, torque_setpoint=np.asarray(torque_setpoints, dtype=float),
            omega_worm=self.mean["omega_worm"], omega_std=self.std["omega_worm"],
            current_drive=self.mean["current_drive"], current_std=self.std["current_drive"],
            tau_load=self.mean["tau_load"], tau_std=self.std["tau_load"],
            tau_true=self.mean["tau_true"], samples=np.full(len(self.speed_setpoints), self.window),
            settled=self.settled.copy(), theta_worm=None if self._theta is None else self._theta[1].T.copy())


def measure_operating_points(
    sim: SimulatedRig,
    controller: SpeedController,
    speed_setpoints,
    torque_setpoints,
    criterion: SteadyStateCriterion = SteadyStateCriterion(),
    progress: Callable[[float], None] | None = None,
) -> OperatingPoints:
    """Hold every rig of sim at its (speed, torque) set-point until steady; return the windows.

    Args:
        sim: simulated rigs, one per point (sim.n == number of points).
        controller: speed controller sized for sim.n rigs.
        speed_setpoints: worm speeds [rad/s], shape (n,).
        torque_setpoints: load torques [N m], shape (n,), positive opposing positive rotation.
        progress: called with the fraction of points settled so far.
    """
    speed_sp = np.asarray(speed_setpoints, dtype=float)
    torque_sp = np.asarray(torque_setpoints, dtype=float)
    n = sim.n
    if speed_sp.shape != (n,) or torque_sp.shape != (n,):
        raise ValueError(f"need {n} speed and torque set-points, got {speed_sp.shape} and {torque_sp.shape}")
    detector = SteadyStateDetector(criterion, sim.sample_period, speed_sp)
    sim.command(voltage_drive=0.0, load_torque=torque_sp)
    while not detector.finished:
        measured = sim.sample()
        checked = detector.add(measured.omega_worm, measured.current_drive, measured.tau_load,
                               sim.applied_load_torque, measured.theta_worm)
        out = controller.update(sim.sample_period, speed_sp, measured.omega_worm)
        sim.command(voltage_drive=out.voltage)
        if checked and progress is not None:
            progress(float(detector.settled.mean()))
    return detector.result(torque_sp)
