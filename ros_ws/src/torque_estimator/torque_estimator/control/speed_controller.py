"""Velocity PI controller for the drive motor, with load-torque feedforward.

Designed in the torque domain and turned into an armature voltage through the
motor's Eq. 29:  V = R*tau_cmd/K_t + K_e*omega_ref.  The commanded motor torque
    tau_cmd = kp*e + integral(ki*e) + tau_ff
where tau_ff is the estimated load torque tau_d reflected through the gearbox
to the worm (Eq. 28 with a_w = 0, worm_model.physics.dynamics.reflected_input_torque).
Anti-windup by conditional integration: while the voltage is at its limit the
integrator does not grow further into the limit.

Vectorised: the state holds one controller per rig (shape (n,)), so batch
calibration runs hundreds of rigs in one call. Plain numpy; no ROS.
Signs: positive speed/torque/voltage turn the worm in the positive sense; tau_d
is positive when it opposes positive rotation.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.parameters import Rig

from torque_estimator.estimation.base import EstimateFlags


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


def feedforward_torque(rig: Rig, tau_load, omega_worm) -> np.ndarray:
    """Input torque at the worm [N m] that balances load tau_load [N m] at speed omega_worm [rad/s].

    Eq. 28 quasi-statically with the friction coefficient of the rig's friction
    model at that speed; NaN loads give no feedforward (0), never NaN.
    """
    tau_load = np.asarray(tau_load, dtype=float)
    mu = friction_coefficient(rig.friction, rig.gearbox, omega_worm)
    torque = reflected_input_torque(rig.gearbox, mu, np.nan_to_num(tau_load), omega_worm)
    return np.where(np.isfinite(tau_load), torque, 0.0)


class SpeedController:
    """PI speed controller of n drive motors (see module docstring)."""

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
            omega_measured: measured worm speed [rad/s]; a NaN holds the integrator
                and drops the proportional term for that update.
            tau_ff: feedforward torque at the worm [N m] (feedforward_torque()), 0 for none.
        """
        motor = self.rig.drive_motor
        omega_ref = np.asarray(omega_ref, dtype=float)
        error = np.nan_to_num(omega_ref - np.asarray(omega_measured, dtype=float))
        tau_ff = np.nan_to_num(np.asarray(tau_ff, dtype=float))

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


class FeedforwardGate:
    """Which load estimate the controller may feed forward (controller_node's rule, plain).

    The latest estimate offered is held. It is used for a control period at
    time ``now`` only if feedforward is enabled, its torque is finite, it is not
    flagged INVALID_INPUT or OUT_OF_CALIBRATION (an extrapolated value is not
    trusted as a command), and it is at most ``timeout`` [s] older than ``now``
    (the sample being controlled): a stalled estimator must not leave a stale
    torque in the loop. Otherwise the PI alone holds the speed.
    AMBIGUOUS and TRANSIENT estimates are used: the nearest branch is the best
    guess, and a transient estimate still points the right way.
    """

    UNUSABLE = EstimateFlags.INVALID_INPUT | EstimateFlags.OUT_OF_CALIBRATION

    def __init__(self, timeout: float, enabled: bool = True) -> None:
        self.timeout = timeout
        self.enabled = enabled
        self._torque: float | None = None
        self._flags = 0
        self._stamp = 0.0

    def offer(self, torque: float, flags: int, stamp: float) -> None:
        """Hold a new estimate: τ_d [N m], EstimateFlags bits, stamp of the sample it came from [s]."""
        self._torque, self._flags, self._stamp = float(torque), int(flags), float(stamp)

    def load(self, now: float) -> float | None:
        """The usable held τ_d [N m] for a control period at time ``now`` [s], or None."""
        torque = self._torque
        if not self.enabled or torque is None or self._flags & self.UNUSABLE or not np.isfinite(torque):
            return None
        return torque if now - self._stamp <= self.timeout else None
