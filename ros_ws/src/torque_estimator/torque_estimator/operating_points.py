"""Quasi-static measurement of operating points, as the paper's experiments did.

For each (speed set-point, load-torque set-point) the drive motor is held at
speed by the PI controller while the load motors apply the torque; once the
steady-state criterion holds over a whole averaging window, the window's mean
and spread of every channel are kept. Calibration measures the grid this way,
evaluation measures held-out points the same way.

Runs an ensemble of simulated rigs side by side (one per point), so a full
17 x 16 x 2 grid settles in seconds. Plain numpy; no ROS.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Callable

import numpy as np

from worm_rig_driver.simulated_rig import SimulatedRig

from .speed_controller import SpeedController


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
    dt = sim.sample_period
    window = max(2, int(round(criterion.window / dt)))
    first_check = int(round(criterion.settle_time / dt)) + window
    last_sample = max(first_check, int(round(criterion.timeout / dt)))

    channels = ("omega_worm", "current_drive", "tau_load", "tau_true")
    buffers = {name: np.empty((window, n)) for name in channels}
    result = {name: np.full(n, np.nan) for name in channels}
    spread = {name: np.full(n, np.nan) for name in channels}
    settled = np.zeros(n, dtype=bool)

    sim.command(voltage_drive=0.0, load_torque=torque_sp)
    for k in range(1, last_sample + 1):
        measured = sim.sample()
        row = (k - 1) % window
        buffers["omega_worm"][row] = measured.omega_worm
        buffers["current_drive"][row] = measured.current_drive
        buffers["tau_load"][row] = measured.tau_load
        buffers["tau_true"][row] = sim.applied_load_torque
        out = controller.update(dt, speed_sp, measured.omega_worm)
        sim.command(voltage_drive=out.voltage)

        if k < first_check or k % window:
            continue
        means = {name: buf.mean(axis=0) for name, buf in buffers.items()}
        half = window // 2
        drift = np.abs(buffers["current_drive"][:half].mean(axis=0) - buffers["current_drive"][half:].mean(axis=0))
        steady = (np.abs(means["omega_worm"] - speed_sp) <= criterion.speed_tolerance * np.abs(speed_sp)
                  + criterion.speed_floor) & (drift <= criterion.current_drift)
        take = (steady & ~settled) | ((k + window > last_sample) & ~settled)
        for name, buf in buffers.items():
            result[name] = np.where(take, means[name], result[name])
            spread[name] = np.where(take, buf.std(axis=0), spread[name])
        settled |= steady
        if progress is not None:
            progress(float(settled.mean()))
        if settled.all():
            break

    return OperatingPoints(
        speed_setpoint=speed_sp, torque_setpoint=torque_sp,
        omega_worm=result["omega_worm"], omega_std=spread["omega_worm"],
        current_drive=result["current_drive"], current_std=spread["current_drive"],
        tau_load=result["tau_load"], tau_std=spread["tau_load"],
        tau_true=result["tau_true"], samples=np.full(n, window), settled=settled,
    )
