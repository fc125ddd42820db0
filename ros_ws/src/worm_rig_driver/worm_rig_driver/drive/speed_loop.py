"""The drive's speed loop: velocity PI with a feedforward torque, the way the rig runs it.

Designed in the torque domain and turned into an armature voltage through the
motor's Eq. 29:  V = R*tau_cmd/K_t + K_e*omega_ref.  The commanded motor torque
    tau_cmd = kp*e + integral(ki*e) + tau_ff
where tau_ff is a torque at the worm added by whoever commands the loop (the
controller node sends the estimated load reflected through the gearbox,
worm_model.physics.steady_state.balancing_torque). Anti-windup by conditional
integration: while the voltage is at its limit the integrator does not grow
further into the limit.

Two implementations of the same law, which a test keeps equal:
  * :class:`SpeedController` is vectorised (one controller per rig, arrays of
    shape (n,)), so batch calibration runs hundreds of rigs in one call;
  * :class:`PiLoop` is one controller in plain float math, for the 1 kHz loop of
    one live rig (sim_node, driver_node), where numpy's per-call overhead on
    1-element arrays would cost ~20x the arithmetic.
Plain Python; no ROS. Signs: positive speed/torque/voltage turn the worm in the
positive sense.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worm_model.physics.parameters import Rig


@dataclass(frozen=True)
class PiGains:
    """Gains of the speed loop: kp [N m s/rad], ki [N m/rad]."""

    kp: float
    ki: float

    def __post_init__(self) -> None:
        if not (self.kp >= 0 and self.ki >= 0):
            raise ValueError(f"PI gains must be >= 0, got kp={self.kp}, ki={self.ki}")


#: Gains for the bundled NMRV030 rig, chosen for robustness to loop delay (a graph of
#: Python processes can deliver samples late, in bursts): kp stays below the motor's own
#: back-EMF damping K_t*K_e/R ~ 1.6e-3 N m s/rad, so the proportional path alone can never
#: destabilise the loop, and the integral crossover sits near 12 rad/s, which keeps ~60 deg
#: of phase margin at 40 ms of delay (kp=2e-3, ki=0.05 limit-cycles from ~20 ms).
DEFAULT_GAINS = PiGains(kp=1e-3, ki=0.02)


@dataclass
class ControlOutput:
    """One update's result; arrays of shape (n,)."""

    voltage: np.ndarray  # [V] command for the drive motor, within the limit
    torque_command: np.ndarray  # [N m] motor torque asked for (incl. feedforward)
    feedforward_torque: np.ndarray  # [N m] reflected load torque added
    saturated: np.ndarray  # bool: the voltage hit its limit


class SpeedController:
    """PI speed controllers of n drive motors, vectorised (see module docstring)."""

    def __init__(self, rig: Rig, gains: PiGains, voltage_limit: float | None = None, n: int = 1) -> None:
        self.rig = rig
        self.gains = gains
        self.voltage_limit = rig.supply_voltage if voltage_limit is None else float(voltage_limit)
        if self.voltage_limit <= 0:
            raise ValueError(f"voltage_limit must be > 0, got {self.voltage_limit}")
        self.integral = np.zeros(n)

    def reset(self) -> None:
        """Forget the integrator (e.g. after a watchdog stop)."""
        self.integral[:] = 0.0

    def update(self, dt: float, omega_ref, omega_measured, tau_ff=0.0) -> ControlOutput:
        """One control period of dt [s].

        Args:
            omega_ref: worm speed set-point [rad/s].
            omega_measured: measured worm speed [rad/s]; a NaN (or inf) holds the integrator
                and drops the proportional term for that update.
            tau_ff: feedforward torque at the worm [N m], 0 for none; non-finite counts as 0.
        """
        motor = self.rig.drive_motor
        omega_ref = np.asarray(omega_ref, dtype=float)
        error = omega_ref - np.asarray(omega_measured, dtype=float)
        error = np.where(np.isfinite(error), error, 0.0)
        tau_ff = np.asarray(tau_ff, dtype=float)
        tau_ff = np.where(np.isfinite(tau_ff), tau_ff, 0.0)

        def voltage_for(integral: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            torque = self.gains.kp * error + integral + tau_ff
            return torque, motor.resistance * torque / motor.torque_constant + motor.back_emf_constant * omega_ref

        candidate = self.integral + self.gains.ki * error * dt
        _torque, v_candidate = voltage_for(candidate)
        # Integrate unless that drives the output further into its limit.
        winding_up = (np.abs(v_candidate) > self.voltage_limit) & (np.sign(error) == np.sign(v_candidate))
        self.integral = np.where(winding_up, self.integral, candidate)
        torque, voltage = voltage_for(self.integral)
        saturated = np.abs(voltage) > self.voltage_limit
        return ControlOutput(voltage=np.clip(voltage, -self.voltage_limit, self.voltage_limit),
                             torque_command=torque, feedforward_torque=np.broadcast_to(tau_ff, torque.shape),
                             saturated=saturated)


class PiLoop:
    """One drive motor's PI speed controller in plain float math (the law of SpeedController).

    Args:
        rig: rig parameters (the drive motor's R, K_t, K_e).
        gains: PI gains.
        voltage_limit: largest |V| commanded [V] (> 0).
    """

    def __init__(self, rig: Rig, gains: PiGains, voltage_limit: float) -> None:
        motor = rig.drive_motor
        self._r, self._kt, self._ke = motor.resistance, motor.torque_constant, motor.back_emf_constant
        self.gains = gains
        self.voltage_limit = float(voltage_limit)
        if not self.voltage_limit > 0:
            raise ValueError(f"voltage_limit must be > 0, got {voltage_limit}")
        self.integral = 0.0  # [N m]
        self.saturated = False

    def reset(self) -> None:
        """Forget the integrator (e.g. after a watchdog stop)."""
        self.integral = 0.0

    def update(self, dt: float, omega_ref: float, omega_measured: float, tau_ff: float = 0.0) -> float:
        """One control period of dt [s]: the drive voltage [V] within +-voltage_limit.

        A NaN measurement holds the integrator and drops the proportional term; a
        non-finite tau_ff counts as 0. ``saturated`` tells whether the limit was hit.
        """
        error = omega_ref - omega_measured
        if not math.isfinite(error):
            error = 0.0
        if not math.isfinite(tau_ff):
            tau_ff = 0.0
        kp, ki = self.gains.kp, self.gains.ki
        limit = self.voltage_limit
        candidate = self.integral + ki * error * dt
        # the same operations in the same order as SpeedController, so both give the same bits
        v_candidate = self._r * (kp * error + candidate + tau_ff) / self._kt + self._ke * omega_ref
        # Integrate unless that drives the output further into its limit.
        winding_up = abs(v_candidate) > limit and (error > 0) - (error < 0) == (v_candidate > 0) - (v_candidate < 0)
        if not winding_up:
            self.integral = candidate
        voltage = self._r * (kp * error + self.integral + tau_ff) / self._kt + self._ke * omega_ref
        self.saturated = abs(voltage) > limit
        return min(max(voltage, -limit), limit)


__all__ = ["DEFAULT_GAINS", "ControlOutput", "PiGains", "PiLoop", "SpeedController"]
