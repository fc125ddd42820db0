"""Rigid-body plant of the paper's rig: drive motor + worm gearbox + load motors, with backlash.

Vectorised over an ensemble of independent rigs (state arrays of shape (n,)),
so one call advances a single live rig (sim_node) or a whole calibration grid
at once (batch calibration). Plain numpy; no ROS.

Frames and signs (physics.md section 2): positive worm rotation is the
reference; gear quantities are referred to it (omega_gear = i * omega_worm in
contact, whatever the helix hand). The load torque tau_load on the gear shaft is
positive when it opposes positive rotation.

What acts on the two shafts:
  worm shaft  tau_in = K_t*i - b*omega - c(omega)*sign(omega) + effects     (Eq. 29, section 7)
  gear shaft  gear_load = tau_em,load + count*(b_l*omega_g + c_l(omega_g)*sign(omega_g)) + effects
  (c(omega): the Coulomb drag with its low-speed rise, worm_model.physics.motor.coulomb_friction)
where tau_em,load = count * K_t,load * i_load is what the load motors' current
says (the calibration's "known" tau_d) and the rest is the load motors' own drag,
which the mesh must also overcome. That gear-side drag is what gives the rig a
non-zero switching torque (physics.md section 5). "effects" are the plug-ins of
sim/effects/ (bearing drag, ripples, ...), all zero for the paper's model.

Drive: the BTS7960B H-bridge switches the supply; the plant integrates the
average-duty voltage (clamped to +-supply). The PWM period (50 us at the
firmware's 20 kHz) is 16x shorter than the armature's L/R (0.8 ms) and far shorter than the mechanics,
so the mean current obeys Eq. 29 with V = duty * supply; the duty resolution
and the ripple the ADC sees are the `pwm` effect. The armature current is
integrated exactly over each step with the speed held (motor.exact_current_step).

Mesh: without backlash the gear is rigidly tied to the worm and Eq. 28 (with the
self-consistent flank) moves both. With backlash (the `backlash` effect sets the
clearance) the mesh is a dead zone: the mesh position p = i*theta_worm -
theta_gear lies in [-gap/2, +gap/2]; at +gap/2 the worm pushes the gear forward
(contact side +1), at -gap/2 backward (-1). While in contact, Eq. 28 holds; when
the contact force would have to pull (the flank Eq. 28 picks is on the other
side), the teeth separate and each shaft moves under its own torques until the
other side is hit, a perfectly inelastic impact (restitution 0: oil-damped
bronze teeth; no bounce, hence no chatter) that conserves the momentum
J_w*omega_w + i*J_g*omega_g through the frictionless lever of the mesh. The
energy the impact dissipates is reported (impact_loss).

Near zero speed a shaft is held by static friction unless the applied torques
break it away (tested in both directions), so stick-slip produces no numerical
chatter: a speed that would cross zero inside a step stops at zero.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from worm_model.effects.heat import mesh_heat
from worm_model.physics.friction import FRICTION_MODELS, sliding_velocity
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.motor import exact_current_step, shaft_torque
from worm_model.physics.parameters import Rig

from worm_rig_driver.sim.effects import EffectsConfig, EffectStack, ShaftState, as_config

#: Below this worm speed [rad/s] a worm counts as standing still.
STANDSTILL_SPEED = 1e-3
#: Below this gear speed [rad/s] a gear apart from the worm counts as standing still.
GEAR_STANDSTILL_SPEED = 1e-5
#: Probe speed [rad/s] used to evaluate the dynamics in a frame of motion at rest.
_PROBE_SPEED = 1e-6
#: Mesh positions within this of a flank [rad at the gear] count as touching it.
_CONTACT_TOLERANCE = 1e-12


@dataclass
class PlantState:
    """State of n rigs; every field has shape (n,). SI units.

    The gear fields default to the rigid mesh (omega_gear = i omega_worm, theta_gear
    = i theta_worm) when left None; RigPlant always fills them.
    """

    current_drive: np.ndarray  # [A]
    omega_worm: np.ndarray  # [rad/s]
    theta_worm: np.ndarray  # [rad], unwrapped
    current_load: np.ndarray  # [A] per load motor (they share the load equally)
    omega_gear: np.ndarray | None = None  # [rad/s] gear about its own axis, worm-referenced sign
    theta_gear: np.ndarray | None = None  # [rad], unwrapped, worm-referenced sign
    contact: np.ndarray | None = None  # int8: +1 worm pushes the gear forward, -1 backward, 0 apart

    @classmethod
    def at_rest(cls, n: int) -> "PlantState":
        zeros = np.zeros(n)
        return cls(zeros.copy(), zeros.copy(), zeros.copy(), zeros.copy(), zeros.copy(), zeros.copy(),
                   np.ones(n, dtype=np.int8))

    def gear(self, ratio: float) -> tuple[np.ndarray, np.ndarray]:
        """(omega_gear, theta_gear), from the worm through the ratio where not set."""
        omega = ratio * self.omega_worm if self.omega_gear is None else self.omega_gear
        theta = ratio * self.theta_worm if self.theta_gear is None else self.theta_gear
        return omega, theta


@dataclass
class PlantOutputs:
    """Quantities of the last step that sensors and ground truth need; shape (n,).

    tau_in and gear_load are everything acting on each shaft besides the mesh
    (effects included): with the true inertias, Eqs 19-23 recover the contact forces.
    """

    tau_in: np.ndarray  # [N m] torque delivered to the worm shaft (motor + worm-side effects)
    tau_load: np.ndarray  # [N m] load motors' electromagnetic torque on the gear shaft
    gear_load: np.ndarray  # [N m] everything the gear shaft carries (load + its drags + gear-side effects)
    alpha_worm: np.ndarray  # [rad/s^2]
    mu: np.ndarray  # [1] mesh friction coefficient in force (kinetic, or static at rest)
    voltage_drive: np.ndarray  # [V] average voltage applied (after the H-bridge's limit)
    drive_saturated: np.ndarray  # bool: the requested voltage exceeded the supply
    alpha_gear: np.ndarray | None = None  # [rad/s^2] worm-referenced
    contact: np.ndarray | None = None  # int8 contact side at the start of the step (0: teeth apart)
    worm_effect_torque: np.ndarray | None = None  # [N m] part of tau_in from effects
    gear_effect_torque: np.ndarray | None = None  # [N m] part of gear_load from effects
    impact_loss: np.ndarray | None = None  # [J] dissipated by flank impacts in this step
    heat: np.ndarray | None = None  # [W] made inside the gearbox (only when an effect needs it)


class Eq28:
    """Eq. 28 with the self-consistent flank, as worm_model.physics.dynamics.worm_acceleration computes it.

    The same algebra with the gearbox's trigonometry and the inertias computed once:
    the plant calls it several times per step for up to thousands of rigs, and
    worm_acceleration's generality (broadcasting any argument) costs more than the
    arithmetic. test_plant checks the two agree.
    """

    def __init__(self, rig: Rig, worm_inertia: float, gear_inertia: float) -> None:
        gb = rig.gearbox
        # plain floats (same values as numpy's): the scalar plant runs on_flank on floats,
        # where numpy scalars would cost more than the arithmetic
        cphi = float(np.cos(gb.normal_pressure_angle))
        self.sl, self.cl = float(np.sin(gb.lead_angle)), float(np.cos(gb.lead_angle))
        self.cs, self.cc = cphi * self.sl, cphi * self.cl
        self.k, self.ratio = gb.radius_ratio, gb.ratio
        self.jw, self.jg = worm_inertia, gear_inertia
        self.jg_i = self.jg * self.ratio  # J_g i [kg m^2]
        self.jg_i_k = self.jg_i * self.k  # J_g i (r_w/r_g) [kg m^2]

    def on_flank(self, mu, T, D, s):
        """Eq. 28 on flank s (+1.0 driving / -1.0 coast) in the frame of motion: (a_w [rad/s^2], N >= 0?).

        T, D: input and load torque in the frame of motion [N m]. The flank is
        consistent where the contact force it implies, N = (J_g i a_w + D) / (r_g
        (s cos(phi_n) cos(lambda) - mu sin(lambda))), is >= 0. Floats or arrays: the
        vectorised plant (__call__) and the scalar one (scalar_plant) share this algebra.
        """
        den = s * self.cc - mu * self.sl
        K = (s * self.cs + mu * self.cl) / den  # flank factor K_s(mu)
        a = (T - self.k * K * D) / (self.jw + self.jg_i_k * K)
        return a, (self.jg_i * a + D) * den >= 0.0

    def __call__(self, mu, tau_in, tau_d, omega_worm) -> tuple[np.ndarray, np.ndarray]:
        """(alpha_worm [rad/s^2], flank int8) in the fixed frame; sigma = sign(omega), +1 at 0."""
        sigma = np.where(omega_worm < 0.0, -1.0, 1.0)
        T, D = sigma * tau_in, sigma * tau_d
        a_p, ok_p = self.on_flank(mu, T, D, 1.0)
        a_m, ok_m = self.on_flank(mu, T, D, -1.0)
        flank = np.where(ok_p, 1, np.where(ok_m, -1, np.where(D >= 0.0, 1, -1))).astype(np.int8)
        return sigma * np.where(flank == 1, a_p, a_m), flank


def _stop_at_zero(omega: np.ndarray, new_omega: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """A moving shaft that would reverse inside the step stops at zero (restart: next step's breakaway)."""
    crossed = moving & (np.sign(new_omega) != np.sign(omega))
    return np.where(crossed, 0.0, new_omega)


@dataclass
class RigPlant:
    """Integrates the coupled motor + gearbox dynamics (Eqs 28-30) of n rigs.

    Args:
        rig: rig parameters (worm_model.physics.parameters.Rig).
        n: number of independent rigs simulated side by side.
        load_current_time_constant: [s] closed-loop time constant of the load
            motors' current control (assumption: a fast analogue/PWM current loop).
        effects: effects the model lacks (effects.EffectsConfig, an ``effects``
            mapping or a file path); None = the paper's model exactly.
    """

    rig: Rig
    n: int = 1
    load_current_time_constant: float = 2e-3
    effects: EffectsConfig | None = None
    state: PlantState = field(init=False)

    def __post_init__(self) -> None:
        self.effects = as_config(self.effects)
        self.fx: EffectStack = EffectStack.build(self.effects, self.n, self.rig)
        self.state = PlantState.at_rest(self.n)
        #: true total inertias of each shaft [kg m^2] (the rig file's unless inertia_error)
        self.worm_inertia, self.gear_inertia = self.fx.inertia(self.rig.total_worm_inertia,
                                                               self.rig.total_gear_inertia)
        #: mesh clearance at the gear [rad]; 0 = rigid mesh
        self.backlash = self.fx.backlash
        self._has_effects = bool(self.fx.effects)
        self._friction_law = FRICTION_MODELS[self.rig.friction.model]
        if self.backlash > 0:
            self.state.contact[:] = 0  # assembled with the teeth in the middle of the clearance
        self._eq28 = Eq28(self.rig, self.worm_inertia, self.gear_inertia)

    # --- torques on each shaft ------------------------------------------------------------------------
    def _forces(self, omega_worm, omega_gear, current, tau_load, engaged=None, static=False):
        """(tau_in, gear_load, mu, worm effect torque, gear effect torque) at these speeds, fixed frame.

        engaged: bool array, where the teeth touch (None: everywhere); the mesh load the
        effects see is 0 elsewhere. static: mu at zero sliding speed (breakaway).
        """
        rig = self.rig
        tau_in = shaft_torque(rig.drive_motor, current, omega_worm)
        gear_load = gear_side_load(rig, tau_load, omega_gear / rig.gearbox.ratio)
        v_sliding = np.zeros(self.n) if static else sliding_velocity(rig.gearbox, omega_worm)
        mu = self._friction_law(rig.friction, v_sliding)
        if not self._has_effects:
            return tau_in, gear_load, mu, None, None
        fx, s = self.fx, self.state
        mesh_load = np.abs(gear_load) if engaged is None else np.where(engaged, np.abs(gear_load), 0.0)
        shafts = ShaftState(omega_worm, s.theta_worm, omega_gear, s.theta_gear, current, mesh_load)
        worm_fx = fx.worm_torque(shafts) if fx.has_worm_torque else None
        gear_fx = fx.gear_torque(shafts) if fx.has_gear_torque else None
        if fx.has_friction:
            mu = fx.friction(mu, v_sliding, shafts)
        return (tau_in if worm_fx is None else tau_in + worm_fx,
                gear_load if gear_fx is None else gear_load + gear_fx, mu, worm_fx, gear_fx)

    def _acceleration(self, tau_in, gear_load, omega_worm, mu):
        return self._eq28(mu, tau_in, gear_load, omega_worm)

    def _breakaway(self, current, tau_load) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For coupled rigs at rest: direction (+1/-1, or 0 if it stays stuck), acceleration, flank.

        Each frame of motion is probed with the drags acting against that motion
        and the static friction coefficient; friction being dissipative, at most
        one direction can accelerate.
        """
        direction = np.zeros(self.n)
        alpha = np.zeros(self.n)
        flank = np.zeros(self.n, dtype=np.int8)
        ratio = self.rig.gearbox.ratio
        for sigma in (1.0, -1.0):
            probe = np.full(self.n, sigma * _PROBE_SPEED)
            tau_in, gear_load, mu, _, _ = self._forces(probe, ratio * probe, current, tau_load, static=True)
            alpha_sigma, flank_sigma = self._acceleration(tau_in, gear_load, probe, mu)
            starts = (direction == 0) & (sigma * alpha_sigma > 0)
            direction = np.where(starts, sigma, direction)
            alpha = np.where(starts, alpha_sigma, alpha)
            flank = np.where(starts, flank_sigma, flank)
        return direction, alpha, flank

    # --- public API ---------------------------------------------------------------------------------------
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
        if self.fx.has_voltage:
            voltage = self.fx.drive_voltage(voltage, supply)

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

        if self.backlash > 0:
            out = self._step_with_backlash(dt, tau_load)
        else:
            out = self._step_rigid(dt, tau_load)
        out.voltage_drive = voltage
        out.drive_saturated = saturated
        if self.fx.needs_heat:
            self.fx.advance(dt, out.heat)
        return out

    # --- rigid mesh (no backlash): Eq. 28 moves both shafts ---------------------------------------------
    def _step_rigid(self, dt: float, tau_load: np.ndarray) -> PlantOutputs:
        s, ratio = self.state, self.rig.gearbox.ratio
        omega = s.omega_worm
        if self._has_effects:
            s.omega_gear, s.theta_gear = ratio * omega, ratio * s.theta_worm  # exact tie (effects read them)
        tau_in, gear_load, mu, worm_fx, gear_fx = self._forces(omega, ratio * omega, s.current_drive, tau_load)
        moving = np.abs(omega) > STANDSTILL_SPEED
        alpha, flank = self._acceleration(tau_in, gear_load, np.where(moving, omega, 1.0), mu)
        if not np.all(moving):
            direction, alpha_start, flank_start = self._breakaway(s.current_drive, tau_load)
            alpha = np.where(moving, alpha, alpha_start)
            flank = np.where(moving, flank, flank_start)
            # Static friction holds a worm that cannot break away: a residual creep
            # speed below STANDSTILL_SPEED (left by a deceleration that stopped
            # just short of zero) is zeroed rather than kept forever.
            omega = np.where(~moving & (direction == 0), 0.0, omega)
            sigma = np.where(moving, np.sign(omega), direction)
        else:
            sigma = np.sign(omega)

        new_omega = _stop_at_zero(omega, omega + alpha * dt, moving)
        heat = self._heat(omega, ratio * omega, tau_in, gear_load, alpha, ratio * alpha, sigma != 0) \
            if self.fx.needs_heat else None
        s.theta_worm = s.theta_worm + 0.5 * (omega + new_omega) * dt
        s.omega_worm = new_omega
        s.omega_gear, s.theta_gear = ratio * new_omega, ratio * s.theta_worm
        s.contact = np.where(sigma != 0, (sigma * flank).astype(np.int8), s.contact).astype(np.int8)
        return PlantOutputs(tau_in=tau_in, tau_load=tau_load, gear_load=gear_load, alpha_worm=alpha, mu=mu,
                            voltage_drive=None, drive_saturated=None, alpha_gear=ratio * alpha,
                            contact=s.contact,
                            worm_effect_torque=worm_fx, gear_effect_torque=gear_fx,
                            impact_loss=np.zeros(self.n), heat=heat)

    # --- mesh with a dead zone -----------------------------------------------------------------------------
    def _free_acceleration(self, tau, speed, threshold, probe_torque) -> tuple[np.ndarray, np.ndarray]:
        """Acceleration numerator of a shaft on its own: (net torque, stuck) with stick at rest.

        tau: torque on the shaft at its speed (+ along + rotation); probe_torque(sigma)
        gives it at a probe speed in direction sigma. A shaft at rest starts in the
        direction whose probe torque pushes that way, else it is stuck (torque 0).
        """
        at_rest = np.abs(speed) <= threshold
        if not at_rest.any():
            return tau, at_rest & False
        up, down = probe_torque(1.0), probe_torque(-1.0)
        start = np.where(up > 0, up, np.where(down < 0, down, 0.0))
        stuck = at_rest & (start == 0.0)
        return np.where(at_rest, start, tau), stuck

    def _step_with_backlash(self, dt: float, tau_load: np.ndarray) -> PlantOutputs:
        s, ratio, n = self.state, self.rig.gearbox.ratio, self.n
        half = 0.5 * self.backlash
        jw, jg = self.worm_inertia, self.gear_inertia
        current = s.current_drive
        omega, omega_g, contact = s.omega_worm, s.omega_gear, s.contact.copy()
        engaged = contact != 0
        tau_in, gear_load, mu, worm_fx, gear_fx = self._forces(omega, omega_g, current, tau_load, engaged)
        moving = np.abs(omega) > STANDSTILL_SPEED

        # Coupled candidate (Eq. 28) and the contact side it implies: sigma * flank.
        alpha_c, flank = self._acceleration(tau_in, gear_load, np.where(moving, omega, 1.0), mu)
        implied = np.where(moving, np.sign(omega) * flank, 0.0)
        resting = engaged & ~moving
        if resting.any():
            direction, alpha_start, flank_start = self._breakaway(current, tau_load)
            alpha_c = np.where(moving, alpha_c, alpha_start)
            implied = np.where(moving, implied, direction * flank_start)
        if np.all(engaged & (implied == contact)):
            return self._advance_in_contact(dt, tau_load, omega, moving, alpha_c, tau_in, gear_load, mu,
                                            worm_fx, gear_fx)

        # Each shaft on its own (teeth apart), with its own stick at rest.
        def worm_probe(sigma):
            probe = np.full(n, sigma * _PROBE_SPEED)
            return self._forces(probe, omega_g, current, tau_load, np.zeros(n, bool))[0]

        def gear_probe(sigma):  # gear torque as a drive (+ along + rotation) = -gear_load
            probe = np.full(n, sigma * _PROBE_SPEED * ratio)
            return -self._forces(omega, probe, current, tau_load, np.zeros(n, bool))[1]

        free_tau_in, free_gear_load, _, free_worm_fx, free_gear_fx = self._forces(
            omega, omega_g, current, tau_load, np.zeros(n, bool)) if self._has_effects else \
            (tau_in, gear_load, None, None, None)
        net_w, stuck_w = self._free_acceleration(free_tau_in, omega, STANDSTILL_SPEED, worm_probe)
        net_g, stuck_g = self._free_acceleration(-free_gear_load, omega_g, GEAR_STANDSTILL_SPEED, gear_probe)
        alpha_wf, alpha_gf = net_w / jw, net_g / jg

        # Separation: the coupled solution wants the other flank, or (stuck together)
        # the free accelerations pull the teeth apart. Both tests agree with N >= 0
        # for positive effective inertias (see module docstring), so no ping-pong.
        relative = ratio * alpha_wf - alpha_gf
        separate = engaged & (((implied != 0) & (implied != contact))
                              | ((implied == 0) & (contact * relative < 0)))
        contact = np.where(separate, 0, contact).astype(np.int8)
        engaged = contact != 0

        # Integrate: coupled rigs with Eq. 28, free rigs shaft by shaft.
        stuck_c = engaged & ~moving & (implied == 0)
        omega_c = np.where(stuck_c, 0.0, omega)
        new_c = _stop_at_zero(omega_c, omega_c + alpha_c * dt, moving)
        omega_wf = np.where(stuck_w, 0.0, omega)
        new_wf = _stop_at_zero(omega_wf, omega_wf + alpha_wf * dt, ~(np.abs(omega) <= STANDSTILL_SPEED))
        omega_gf = np.where(stuck_g, 0.0, omega_g)
        new_gf = _stop_at_zero(omega_gf, omega_gf + alpha_gf * dt, ~(np.abs(omega_g) <= GEAR_STANDSTILL_SPEED))
        omega_w0 = np.where(engaged, omega_c, omega_wf)
        omega_g0 = np.where(engaged, ratio * omega_c, omega_gf)
        new_w = np.where(engaged, new_c, new_wf)
        new_g = np.where(engaged, ratio * new_c, new_gf)
        theta_w = s.theta_worm + 0.5 * (omega_w0 + new_w) * dt
        theta_g = np.where(engaged, ratio * theta_w - contact * half, s.theta_gear + 0.5 * (omega_g0 + new_g) * dt)

        # Impacts: a free rig reaching a flank while closing (or past it) engages it.
        position = ratio * theta_w - theta_g
        closing = ratio * new_w - new_g
        hit_fwd = (position >= half - _CONTACT_TOLERANCE) & ((closing > 0) | (position > half + _CONTACT_TOLERANCE))
        hit_back = (position <= -half + _CONTACT_TOLERANCE) & ((closing < 0)
                                                               | (position < -half - _CONTACT_TOLERANCE))
        hit = ~engaged & (hit_fwd | hit_back)
        impact_loss = np.zeros(n)
        if hit.any():
            side = np.where(hit_fwd, 1, -1).astype(np.int8)
            common = (jw * new_w + ratio * jg * new_g) / (jw + ratio ** 2 * jg)
            before = 0.5 * (jw * new_w ** 2 + jg * new_g ** 2)
            after = 0.5 * (jw + ratio ** 2 * jg) * common ** 2
            impact_loss = np.where(hit, before - after, 0.0)
            new_w = np.where(hit, common, new_w)
            new_g = np.where(hit, ratio * common, new_g)
            theta_g = np.where(hit, ratio * theta_w - side * half, theta_g)
            contact = np.where(hit, side, contact).astype(np.int8)

        alpha_w = np.where(engaged, alpha_c, alpha_wf)
        alpha_g = np.where(engaged, ratio * alpha_c, alpha_gf)
        heat = self._heat(omega_w0, omega_g0, tau_in, gear_load, alpha_w, alpha_g, engaged) \
            if self.fx.needs_heat else None
        if worm_fx is not None:
            worm_fx = np.where(engaged, worm_fx, free_worm_fx)
        if gear_fx is not None:
            gear_fx = np.where(engaged, gear_fx, free_gear_fx)
        s.theta_worm, s.omega_worm = theta_w, new_w
        s.theta_gear, s.omega_gear = theta_g, new_g
        out_contact = np.where(engaged, contact, 0).astype(np.int8)
        s.contact = contact
        return PlantOutputs(tau_in=np.where(engaged, tau_in, free_tau_in),
                            tau_load=tau_load, gear_load=np.where(engaged, gear_load, free_gear_load),
                            alpha_worm=alpha_w, mu=mu, voltage_drive=None, drive_saturated=None,
                            alpha_gear=alpha_g, contact=out_contact, worm_effect_torque=worm_fx,
                            gear_effect_torque=gear_fx, impact_loss=impact_loss, heat=heat)

    def _advance_in_contact(self, dt, tau_load, omega, moving, alpha, tau_in, gear_load, mu, worm_fx,
                            gear_fx) -> PlantOutputs:
        """Every rig keeps its flank and moves (the common case): Eq. 28 for all, no free shaft."""
        s, ratio = self.state, self.rig.gearbox.ratio
        new_omega = _stop_at_zero(omega, omega + alpha * dt, moving)
        heat = self._heat(omega, ratio * omega, tau_in, gear_load, alpha, ratio * alpha, s.contact != 0) \
            if self.fx.needs_heat else None
        s.theta_worm = s.theta_worm + 0.5 * (omega + new_omega) * dt
        s.omega_worm = new_omega
        s.omega_gear = ratio * new_omega
        s.theta_gear = ratio * s.theta_worm - s.contact * (0.5 * self.backlash)
        return PlantOutputs(tau_in=tau_in, tau_load=tau_load, gear_load=gear_load, alpha_worm=alpha, mu=mu,
                            voltage_drive=None, drive_saturated=None, alpha_gear=ratio * alpha,
                            contact=s.contact.copy(), worm_effect_torque=worm_fx, gear_effect_torque=gear_fx,
                            impact_loss=np.zeros(self.n), heat=heat)

    def _heat(self, omega, omega_g, tau_in, gear_load, alpha_w, alpha_g, engaged) -> np.ndarray:
        """Power [W] made inside the gearbox: mesh friction plus dissipative shaft effects.

        Mesh friction = power into the mesh from the worm minus power out to the gear
        (worm_model.effects.heat): (tau_in - J_w a_w) w - (gear_load + J_g a_g) i w, which is F_f V_s (>= 0).
        """
        mesh = mesh_heat(tau_in - self.worm_inertia * alpha_w, omega, gear_load + self.gear_inertia * alpha_g, omega_g)
        s = self.state
        shafts = ShaftState(omega, s.theta_worm, omega_g, s.theta_gear, s.current_drive,
                            np.where(engaged, np.abs(gear_load), 0.0))
        return np.where(engaged, mesh, 0.0) + self.fx.heat(shafts)
