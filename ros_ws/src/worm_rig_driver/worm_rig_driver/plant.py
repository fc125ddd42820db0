"""Rigid-body plant of the paper's rig: drive motor + worm gearbox + load motors.

Vectorised over an ensemble of independent rigs (state arrays of shape (n,)),
so one call advances a single live rig (sim_node) or a whole calibration grid
at once (batch calibration). Plain numpy; no ROS.

Frames and signs (physics.md section 2): positive worm rotation is the
reference; gear quantities are referred to it (omega_gear = i * omega_worm,
whatever the helix hand). The load torque tau_load on the gear shaft is
positive when it opposes positive rotation.

What acts on the two shafts:
  worm shaft  tau_in = K_t*i - b*omega - c*sign(omega)            (Eq. 29, section 7)
  gear shaft  D_fixed = tau_em,load + count*(b_l*omega_g + c_l*sign(omega_g))
where tau_em,load = count * K_t,load * i_load is what the load motors' current
says (the calibration's "known" tau_d) and the rest is the load motors' own drag,
which the mesh must also overcome. That gear-side drag is what gives the rig a
non-zero switching torque (physics.md section 5).

Near zero speed the worm is held by static friction unless the applied torques
break it away (tested in both frames of motion), so stick-slip produces no
numerical chatter: a speed that would cross zero inside a step stops at zero.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from worm_model.dynamics import worm_acceleration
from worm_model.friction import friction_coefficient
from worm_model.gear_side import gear_side_load
from worm_model.motor import exact_current_step, shaft_torque
from worm_model.parameters import Rig

#: Below this worm speed [rad/s] a worm counts as standing still.
STANDSTILL_SPEED = 1e-3
#: Probe speed [rad/s] used to evaluate the dynamics in a frame of motion at rest.
_PROBE_SPEED = 1e-6


@dataclass
class PlantState:
    """State of n rigs; every field has shape (n,). SI units."""

    current_drive: np.ndarray  # [A]
    omega_worm: np.ndarray  # [rad/s]
    theta_worm: np.ndarray  # [rad], unwrapped
    current_load: np.ndarray  # [A] per load motor (they share the load equally)

    @classmethod
    def at_rest(cls, n: int) -> "PlantState":
        zeros = np.zeros(n)
        return cls(zeros.copy(), zeros.copy(), zeros.copy(), zeros.copy())


@dataclass
class PlantOutputs:
    """Quantities of the last step that sensors and ground truth need; shape (n,)."""

    tau_in: np.ndarray  # [N m] torque delivered to the worm shaft
    tau_load: np.ndarray  # [N m] load motors' electromagnetic torque on the gear shaft
    gear_load: np.ndarray  # [N m] everything the gear shaft carries (load + its drags)
    alpha_worm: np.ndarray  # [rad/s^2]
    mu: np.ndarray  # [1] mesh friction coefficient in force
    voltage_drive: np.ndarray  # [V] applied (after the H-bridge's limit)
    drive_saturated: np.ndarray  # bool: the requested voltage exceeded the supply


@dataclass
class RigPlant:
    """Integrates the coupled motor + gearbox dynamics (Eqs 28-30) of n rigs.

    Args:
        rig: rig parameters (worm_model.parameters.Rig).
        n: number of independent rigs simulated side by side.
        load_current_time_constant: [s] closed-loop time constant of the load
            motors' current control (assumption: a fast analogue/PWM current loop).
    """

    rig: Rig
    n: int = 1
    load_current_time_constant: float = 2e-3
    state: PlantState = field(init=False)

    def __post_init__(self) -> None:
        self.state = PlantState.at_rest(self.n)

    # --- the pieces of one step -------------------------------------------------
    def _acceleration(self, tau_in, gear_load, omega_worm, mu) -> np.ndarray:
        alpha, _flank = worm_acceleration(
            self.rig.gearbox, mu, tau_in, gear_load, omega_worm,
            self.rig.total_worm_inertia, self.rig.total_gear_inertia,
        )
        return alpha

    def _breakaway(self, current: np.ndarray, tau_load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For rigs at rest: direction (+1/-1, or 0 if it stays stuck) and acceleration.

        Each frame of motion is probed with the drags acting against that motion
        and the static friction coefficient; friction being dissipative, at most
        one direction can accelerate.
        """
        direction = np.zeros(self.n)
        alpha = np.zeros(self.n)
        mu_static = friction_coefficient(self.rig.friction, self.rig.gearbox, np.zeros(self.n))
        for sigma in (1.0, -1.0):
            probe = np.full(self.n, sigma * _PROBE_SPEED)
            tau_in = shaft_torque(self.rig.drive_motor, current, probe)
            gear_load = gear_side_load(self.rig, tau_load, probe)
            alpha_sigma = self._acceleration(tau_in, gear_load, probe, mu_static)
            starts = (direction == 0) & (sigma * alpha_sigma > 0)
            direction = np.where(starts, sigma, direction)
            alpha = np.where(starts, alpha_sigma, alpha)
        return direction, alpha

    # --- public API ------------------------------------------------------------
    def step(self, dt: float, voltage_drive, load_torque_command) -> PlantOutputs:
        """Advance every rig by dt [s].

        Args:
            dt: step [s]; the armature current is integrated exactly, the
                mechanics semi-implicitly (keep dt well below the mechanical
                time constant, ~10 ms on the paper's rig).
            voltage_drive: requested drive-motor voltage [V], clamped to the supply.
            load_torque_command: requested load torque on the gear shaft [N m],
                positive opposing positive rotation; clamped to what the load
                motors' rated current can make.
        """
        rig, s = self.rig, self.state
        supply = rig.supply_voltage
        requested = np.broadcast_to(np.asarray(voltage_drive, dtype=float), (self.n,))
        voltage = np.clip(requested, -supply, supply)
        saturated = np.abs(requested) > supply

        # Load motors: current-controlled, sharing the commanded torque equally.
        load = rig.load_motor
        count = rig.load_motor_count
        target = np.clip(np.asarray(load_torque_command, dtype=float),
                         -rig.max_load_torque, rig.max_load_torque) / (count * load.torque_constant)
        blend = 1.0 - np.exp(-dt / self.load_current_time_constant)
        s.current_load = s.current_load + (target - s.current_load) * blend
        tau_load = count * load.torque_constant * s.current_load

        # Drive motor armature (Eq. 29), exact over dt with the speed held.
        s.current_drive = exact_current_step(rig.drive_motor, voltage, s.current_drive, s.omega_worm, dt)

        # Mechanics (Eq. 28/30).
        omega = s.omega_worm
        tau_in = shaft_torque(rig.drive_motor, s.current_drive, omega)
        gear_load = gear_side_load(self.rig, tau_load, omega)
        mu = friction_coefficient(rig.friction, rig.gearbox, omega)
        moving = np.abs(omega) > STANDSTILL_SPEED
        alpha = self._acceleration(tau_in, gear_load, np.where(moving, omega, 1.0), mu)
        if not np.all(moving):
            direction, alpha_start = self._breakaway(s.current_drive, tau_load)
            alpha = np.where(moving, alpha, alpha_start)
            # Static friction holds a worm that cannot break away: a residual creep
            # speed below STANDSTILL_SPEED (left by a deceleration that stopped
            # just short of zero) is zeroed rather than kept forever.
            omega = np.where(~moving & (direction == 0), 0.0, omega)

        new_omega = omega + alpha * dt
        # A moving worm that would reverse inside the step stops at zero instead:
        # whether it restarts (either way) is the breakaway test of the next step.
        crossed = moving & (np.sign(new_omega) != np.sign(omega))
        new_omega = np.where(crossed, 0.0, new_omega)
        s.theta_worm = s.theta_worm + 0.5 * (omega + new_omega) * dt
        s.omega_worm = new_omega

        return PlantOutputs(tau_in=tau_in, tau_load=tau_load, gear_load=gear_load,
                            alpha_worm=alpha, mu=mu, voltage_drive=voltage,
                            drive_saturated=saturated)
