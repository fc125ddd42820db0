"""The plant of ONE rig in plain float math: the fast path of the live simulator.

:class:`ScalarPlant` is :class:`worm_rig_driver.sim.plant.RigPlant` for n = 1 with
every quantity a Python float instead of a 1-element numpy array. The model, the
frames and the signs are plant.py's (read its module docstring); so is the order
of every floating-point operation, so that both paths agree to round-off. They are
not always bit-identical: numpy's vectorised exp and pow (the friction law) may
differ from libm's in the last bit. test_scalar_path measures the agreement.

Why a second implementation: for one rig, numpy's fixed cost per call (~0.3-1 us)
times the ~100 array operations of a step made the 1 ms sample cost ~300 us; the
arithmetic itself is a few hundred float operations. Shared with plant.py rather
than copied: Eq. 28 on one flank (Eq28.on_flank, floats or arrays), the constants
(STANDSTILL_SPEED, ...) and the friction laws' coefficients
(worm_model.physics.friction.FLOAT_FRICTION_MODELS beside FRICTION_MODELS).

Effects: every effect of sim/effects/ has float twins of its hooks (``*_float``);
:func:`float_hooks_missing` names the live effects that lack one, and
SimulatedRig falls back to the vectorised plant when it is not empty. Hooks that
only set constants (inertia, backlash) and observe() are read through the
ordinary EffectStack, which this plant also keeps (``fx``), built for n = 1.

State: the floats are attributes (current_drive, omega_worm, ...); ``state`` is a
:class:`ScalarPlantState`, a PlantState look-alike whose fields are (1,) arrays
made on access. Writing into such an array (``state.current_load[:] = x``) or
assigning a field sets the plant's state before its next step, as it does on a
RigPlant.
"""
from __future__ import annotations

import math
from functools import partial

import numpy as np

from worm_model.effects.heat import mesh_heat_float
from worm_model.physics.friction import FLOAT_FRICTION_MODELS
from worm_model.physics.parameters import Rig

from worm_rig_driver.sim.effects import EFFECTS, EffectsConfig, EffectStack, as_config
from worm_rig_driver.sim.plant import (
    _CONTACT_TOLERANCE,
    _PROBE_SPEED,
    GEAR_STANDSTILL_SPEED,
    STANDSTILL_SPEED,
    Eq28,
    PlantOutputs,
)

#: the hooks a live effect must have as float twins (``<hook>_float``) for the scalar plant
FLOAT_HOOKS = ("worm_torque", "gear_torque", "friction", "drive_voltage", "advance", "sense")

#: state fields of a plant, with the type each float is cast to when written through ``state``
_STATE_FIELDS = {"current_drive": float, "omega_worm": float, "theta_worm": float, "current_load": float,
                 "omega_gear": float, "theta_gear": float, "contact": int}


def float_hooks_missing(effects: EffectsConfig) -> list[str]:
    """Names of the effects switched on that change a hook in FLOAT_HOOKS without its float twin."""
    missing = []
    for name in effects.names:
        cls = EFFECTS[name]
        if any(h in cls.hooks() and getattr(cls, h + "_float", None) is None for h in FLOAT_HOOKS):
            missing.append(name)
    return missing


def _reverses(omega: float, new_omega: float) -> bool:
    """plant._stop_at_zero's test for a moving shaft (omega != 0): sign(new_omega) != sign(omega).

    True when new_omega is 0, has the other sign, or is NaN (as np.sign's comparison).
    """
    return not new_omega > 0.0 if omega > 0.0 else not new_omega < 0.0


class ScalarPlantState:
    """PlantState of a ScalarPlant: each field a fresh (1,) array; writes reach the plant.

    A field read returns a new array holding the plant's float. Assigning a field,
    or writing into an array read since the last step (``state.current_load[:] = x``,
    as fil.harness does), sets the plant's state before its next step. Arrays kept
    across a step are snapshots, as RigPlant's are (it replaces its arrays each step).
    """

    __slots__ = ("_plant",)

    def __init__(self, plant: "ScalarPlant") -> None:
        self._plant = plant

    def gear(self, ratio: float) -> tuple[np.ndarray, np.ndarray]:
        """(omega_gear, theta_gear), as PlantState.gear (always set on a plant)."""
        return self.omega_gear, self.theta_gear


def _state_field(name: str, cast: type) -> property:
    dtype = np.int8 if cast is int else float

    def get(self: ScalarPlantState) -> np.ndarray:
        plant = self._plant
        plant._sync()  # an array read earlier may have been written: take it first
        array = np.array([getattr(plant, name)], dtype=dtype)
        plant._exported[name] = array
        return array

    def put(self: ScalarPlantState, value) -> None:
        plant = self._plant
        plant._sync()
        plant._exported.pop(name, None)
        setattr(plant, name, cast(np.asarray(value).reshape(-1)[0]))

    return property(get, put, doc=f"{name}, shape (1,) (see the class docstring)")


for _name, _cast in _STATE_FIELDS.items():
    setattr(ScalarPlantState, _name, _state_field(_name, _cast))


class ScalarPlant:
    """One rig's motor + gearbox + load motors (+ backlash), Eqs 28-30, in float math.

    RigPlant's constructor arguments but n, and its public attributes with n = 1
    (rig, n, load_current_time_constant, effects, fx, state, worm_inertia,
    gear_inertia, backlash). :meth:`step` takes and leaves floats; the outputs of
    the last step are float attributes (tau_in, tau_load, gear_load, alpha_worm,
    alpha_gear, mu, voltage_drive, drive_saturated, contact_out, worm_effect_torque,
    gear_effect_torque, impact_loss, heat), and :meth:`outputs` gives them as the
    PlantOutputs RigPlant.step returns.

    Raises:
        ValueError: an effect without the float hooks (see float_hooks_missing).
    """

    n = 1

    def __init__(self, rig: Rig, load_current_time_constant: float = 2e-3,
                 effects: EffectsConfig | dict | str | None = None) -> None:
        self.rig = rig
        self.load_current_time_constant = load_current_time_constant
        self.effects = as_config(effects)
        self.fx: EffectStack = EffectStack.build(self.effects, 1, rig)
        missing = float_hooks_missing(self.effects)
        if missing:
            raise ValueError(f"effects without float hooks, not on the scalar path: {', '.join(missing)}")
        self.worm_inertia, self.gear_inertia = self.fx.inertia(rig.total_worm_inertia, rig.total_gear_inertia)
        self.backlash = self.fx.backlash
        self._eq28 = Eq28(rig, self.worm_inertia, self.gear_inertia)
        self._on_flank = self._eq28.on_flank
        self._mu_law = partial(FLOAT_FRICTION_MODELS[rig.friction.model], rig.friction)  # mu(v_sliding)
        self._has_effects = bool(self.fx.effects)
        fx = self.fx.effects
        self._worm_fx = [e.worm_torque_float for e in fx if "worm_torque" in type(e).hooks()]
        self._gear_fx = [e.gear_torque_float for e in fx if "gear_torque" in type(e).hooks()]
        self._friction_fx = [e.friction_float for e in fx if "friction" in type(e).hooks()]
        self._voltage_fx = [e.drive_voltage_float for e in fx if "drive_voltage" in type(e).hooks()]
        self._advance_fx = [e.advance_float for e in fx if "advance" in type(e).hooks()]
        self._heat_fx = [(e.worm_torque_float if "worm_torque" in type(e).hooks() else None,
                          e.gear_torque_float if "gear_torque" in type(e).hooks() else None)
                         for e in fx if e.dissipative]
        self._needs_heat = self.fx.needs_heat

        # Constants, each computed as the vectorised plant computes it (same bits).
        gb, motor, load = rig.gearbox, rig.drive_motor, rig.load_motor
        self._ratio = gb.ratio
        # sliding_velocity: |w| r_w / cos(lambda)
        self._r_w, self._cos_lead = gb.worm_pitch_radius, float(np.cos(gb.lead_angle))
        self._kt, self._b, self._c = motor.torque_constant, motor.viscous_drag, motor.coulomb_drag
        self._r, self._ke = motor.resistance, motor.back_emf_constant
        self._count, self._kt_load = rig.load_motor_count, load.torque_constant
        self._load_scale = self._count * self._kt_load  # [N m/A] all load motors together
        self._load_b, self._load_c = load.viscous_drag, load.coulomb_drag
        # the Coulomb drags' low-speed rise (motor.coulomb_friction): (c_s, omega_s) per shaft, None without one
        self._rise = (motor.stribeck_rise, motor.stribeck_speed) if motor.stribeck_rise else None
        self._load_rise = (load.stribeck_rise, load.stribeck_speed) if load.stribeck_rise else None
        self._supply, self._max_load = rig.supply_voltage, rig.max_load_torque
        # what _forces reads, unpacked there in one go (attribute loads add up on this hot path)
        self._force_constants = (self._kt, self._b, self._c, self._ratio, self._count, self._load_b, self._load_c,
                                 self._r_w, self._cos_lead)
        # exp(-R dt/L) of the armature and 1 - exp(-dt/tau) of the load current, for the last
        # (dt, tau) (virtual_rig sets tau after construction); numpy's exp, as RigPlant's
        self._dt = self._tau = self._decay = self._blend = math.nan

        # State (PlantState.at_rest; teeth mid-gap with backlash).
        self.current_drive = self.omega_worm = self.theta_worm = self.current_load = 0.0
        self.omega_gear = self.theta_gear = 0.0
        self.contact = 0 if self.backlash > 0 else 1
        self._exported: dict[str, np.ndarray] = {}
        self.state = ScalarPlantState(self)
        self._target = 0.0  # [A] per load motor, the current loop's target (see _command)
        if self.backlash > 0:
            self._mechanics = self._step_with_backlash
        else:
            self._mechanics = self._step_rigid if self._has_effects else self._step_rigid_plain

        # Outputs of the last step.
        self.tau_in = self.tau_load = self.gear_load = self.alpha_worm = self.alpha_gear = self.mu = 0.0
        self.voltage_drive, self.drive_saturated, self.contact_out = 0.0, False, self.contact
        self.worm_effect_torque = self.gear_effect_torque = None
        self.impact_loss, self.heat = 0.0, None

    # --- state exchange with array users ------------------------------------------------------------
    def _sync(self) -> None:
        """Take the state arrays handed out by ``state`` back (they may have been written into)."""
        if self._exported:
            for name, array in self._exported.items():
                setattr(self, name, _STATE_FIELDS[name](array[0]))
            self._exported.clear()

    def outputs(self) -> PlantOutputs:
        """The last step's outputs as RigPlant.step returns them (arrays of shape (1,))."""
        def one(x):
            return None if x is None else np.array([x], dtype=float)

        return PlantOutputs(tau_in=one(self.tau_in), tau_load=one(self.tau_load), gear_load=one(self.gear_load),
                            alpha_worm=one(self.alpha_worm), mu=one(self.mu), voltage_drive=one(self.voltage_drive),
                            drive_saturated=np.array([self.drive_saturated]), alpha_gear=one(self.alpha_gear),
                            contact=np.array([self.contact_out], dtype=np.int8),
                            worm_effect_torque=one(self.worm_effect_torque),
                            gear_effect_torque=one(self.gear_effect_torque), impact_loss=one(self.impact_loss),
                            heat=one(self.heat))

    # --- torques on each shaft ------------------------------------------------------------------------
    def _forces(self, omega_worm: float, omega_gear: float, current: float, tau_load: float,
                engaged: bool | None = None, static: bool = False):
        """(tau_in, gear_load, mu, worm effect torque, gear effect torque): RigPlant._forces for floats."""
        kt, b, c, ratio, count, load_b, load_c, r_w, cos_lead = self._force_constants
        w = omega_worm
        g = ratio * (omega_gear / ratio)
        if self._rise is not None:
            c = c + self._rise[0] * math.exp(-abs(w) / self._rise[1])
        if self._load_rise is not None:
            load_c = load_c + self._load_rise[0] * math.exp(-abs(g) / self._load_rise[1])
        # motor.shaft_torque: K_t i - b w - c sign(w)
        tau_in = kt * current - b * w - c * (1.0 if w > 0.0 else (-1.0 if w < 0.0 else 0.0))
        # gear_side_load(rig, tau_load, omega_gear / ratio): the drag at ratio * (omega_gear / ratio)
        gear_load = tau_load + count * (load_b * g + load_c * (1.0 if g > 0.0 else (-1.0 if g < 0.0 else 0.0)))
        # friction.sliding_velocity: |w| r_w / cos(lambda)
        v_sliding = 0.0 if static else abs(w) * r_w / cos_lead
        mu = self._mu_law(v_sliding)
        if not self._has_effects:
            return tau_in, gear_load, mu, None, None
        mesh_load = abs(gear_load) if (engaged is None or engaged) else 0.0
        shaft = (w, self.theta_worm, omega_gear, self.theta_gear, current, mesh_load)
        worm_fx = gear_fx = None
        if self._worm_fx:
            worm_fx = self._worm_fx[0](*shaft)
            for f in self._worm_fx[1:]:
                worm_fx = worm_fx + f(*shaft)
        if self._gear_fx:
            gear_fx = self._gear_fx[0](*shaft)
            for f in self._gear_fx[1:]:
                gear_fx = gear_fx + f(*shaft)
        for f in self._friction_fx:
            mu = f(mu, v_sliding, *shaft)
        return (tau_in if worm_fx is None else tau_in + worm_fx,
                gear_load if gear_fx is None else gear_load + gear_fx, mu, worm_fx, gear_fx)

    def _acceleration(self, tau_in: float, gear_load: float, omega_worm: float, mu: float) -> tuple[float, int]:
        """Eq28.__call__ for floats: (alpha_worm, flank) with the self-consistent flank."""
        sigma = -1.0 if omega_worm < 0.0 else 1.0
        T, D = sigma * tau_in, sigma * gear_load
        a, ok = self._on_flank(mu, T, D, 1.0)
        if ok:
            return sigma * a, 1
        a_m, ok_m = self._on_flank(mu, T, D, -1.0)
        if ok_m or not D >= 0.0:
            return sigma * a_m, -1
        return sigma * a, 1  # neither flank consistent: s = sign(D) (+1 at 0), as Eq28

    def _breakaway(self, current: float, tau_load: float) -> tuple[float, float, int]:
        """RigPlant._breakaway for one coupled rig at rest: (direction, acceleration, flank)."""
        ratio = self._ratio
        for sigma in (1.0, -1.0):  # at most one direction starts (friction is dissipative)
            probe = sigma * _PROBE_SPEED
            tau_in, gear_load, mu, _, _ = self._forces(probe, ratio * probe, current, tau_load, static=True)
            alpha, flank = self._acceleration(tau_in, gear_load, probe, mu)
            if sigma * alpha > 0:
                return sigma, alpha, flank
        return 0.0, 0.0, 0

    def _set_step(self, dt: float) -> None:
        """The step's exponential factors, computed as RigPlant computes them (numpy's exp: same bits)."""
        motor = self.rig.drive_motor
        self._decay = float(np.exp(-motor.resistance * np.asarray(dt, dtype=float) / motor.inductance))
        self._blend = float(1.0 - np.exp(-dt / self.load_current_time_constant))
        self._dt, self._tau = dt, self.load_current_time_constant

    # --- public API ---------------------------------------------------------------------------------------
    def step(self, dt: float, voltage_drive: float, load_torque_command: float) -> None:
        """Advance the rig by dt [s] (RigPlant.step for floats; the outputs are attributes).

        Args:
            dt: step [s].
            voltage_drive: requested drive-motor voltage [V], clamped to +-supply.
            load_torque_command: requested load torque on the gear shaft [N m], positive
                opposing positive rotation, clamped to +-rig.max_load_torque.
        """
        self._command(dt, voltage_drive, load_torque_command)
        self._substep(dt)

    def advance(self, dt: float, steps: int, voltage_drive: float,
                load_torque_command: float) -> list[tuple[float, float, float, float, float, float]]:
        """`steps` calls of step(dt, ...) with the commands held: one sample period of SimulatedRig.

        Returns:
            the state (current_drive, current_load, omega_worm, theta_worm, omega_gear,
            theta_gear) before the first step and after each, steps + 1 entries (what
            ScalarSensors.measure samples the channels from).
        """
        self._command(dt, voltage_drive, load_torque_command)
        history = [(self.current_drive, self.current_load, self.omega_worm, self.theta_worm, self.omega_gear,
                    self.theta_gear)]
        for _ in range(steps):
            self._substep(dt)
            history.append((self.current_drive, self.current_load, self.omega_worm, self.theta_worm,
                            self.omega_gear, self.theta_gear))
        return history

    def _command(self, dt: float, voltage_drive: float, load_torque_command: float) -> None:
        """What step() does before integrating, the same for every step with the same commands."""
        if self._exported:
            self._sync()  # state arrays handed out (and maybe written into) since the last step
        if dt != self._dt or self.load_current_time_constant != self._tau:
            self._set_step(dt)
        supply = self._supply
        requested = voltage_drive
        voltage = -supply if requested < -supply else (supply if requested > supply else requested)
        self.drive_saturated = abs(requested) > supply
        if self._voltage_fx:
            for f in self._voltage_fx:
                voltage = f(voltage, supply)
        self.voltage_drive = voltage
        # Load motors: current-controlled, sharing the commanded torque equally.
        limit = self._max_load
        command = -limit if load_torque_command < -limit else (limit if load_torque_command > limit
                                                               else load_torque_command)
        self._target = command / self._load_scale  # [A] per load motor

    def _substep(self, dt: float) -> None:
        """One step of dt with the commands _command set."""
        # load currents approach the target with the current loop's time constant
        self.current_load = current_load = self.current_load + (self._target - self.current_load) * self._blend
        self.tau_load = tau_load = self._load_scale * current_load

        # Drive motor armature (Eq. 29), exact over dt with the speed held (motor.exact_current_step).
        i_ss = (self.voltage_drive - self._ke * self.omega_worm) / self._r
        self.current_drive = i_ss + (self.current_drive - i_ss) * self._decay

        self._mechanics(dt, tau_load)
        if self._needs_heat:
            for f in self._advance_fx:
                f(dt, self.heat)

    # --- rigid mesh (no backlash) ---------------------------------------------------------------------
    def _step_rigid(self, dt: float, tau_load: float) -> None:
        ratio = self._ratio
        omega = self.omega_worm
        if self._has_effects:
            self.omega_gear, self.theta_gear = ratio * omega, ratio * self.theta_worm  # effects read them
        tau_in, gear_load, mu, worm_fx, gear_fx = self._forces(omega, ratio * omega, self.current_drive, tau_load)
        moving = abs(omega) > STANDSTILL_SPEED
        if moving:
            alpha, flank = self._acceleration(tau_in, gear_load, omega, mu)
            sigma = 1.0 if omega > 0.0 else -1.0
            new_omega = omega + alpha * dt
            # would reverse inside the step: stop at zero (_reverses, written out on this hot path)
            if (not new_omega > 0.0) if omega > 0.0 else (not new_omega < 0.0):
                new_omega = 0.0
        else:
            sigma, alpha, flank = self._breakaway(self.current_drive, tau_load)
            if sigma == 0.0:
                omega = 0.0  # static friction holds it: a residual creep speed is zeroed
            new_omega = omega + alpha * dt
        if self._needs_heat:
            self.heat = self._heat(omega, ratio * omega, tau_in, gear_load, alpha, ratio * alpha, sigma != 0.0)
        self.theta_worm = self.theta_worm + 0.5 * (omega + new_omega) * dt
        self.omega_worm = new_omega
        self.omega_gear, self.theta_gear = ratio * new_omega, ratio * self.theta_worm
        if sigma != 0.0:
            self.contact = flank if sigma > 0.0 else -flank  # sigma * flank
        # outputs (tau_load is set by _substep)
        self.tau_in, self.gear_load, self.alpha_worm, self.alpha_gear, self.mu = (
            tau_in, gear_load, alpha, ratio * alpha, mu)
        self.contact_out, self.worm_effect_torque, self.gear_effect_torque, self.impact_loss = (
            self.contact, worm_fx, gear_fx, 0.0)

    def _step_rigid_plain(self, dt: float, tau_load: float) -> None:
        """_step_rigid without effects, for a moving worm written out (else it calls _step_rigid).

        The live sim_node's common case: inlining _forces and _acceleration here saves
        ~6 % of a sample. Same operations in the same order as the general methods
        (test_scalar_path pins the two bit for bit); Eq. 28 is still Eq28.on_flank.
        """
        omega = self.omega_worm
        if not abs(omega) > STANDSTILL_SPEED:
            return self._step_rigid(dt, tau_load)  # at rest: breakaway
        kt, b, c, ratio, count, load_b, load_c, r_w, cos_lead = self._force_constants
        sigma = 1.0 if omega > 0.0 else -1.0
        g = ratio * ((ratio * omega) / ratio)
        if self._rise is not None:
            c = c + self._rise[0] * math.exp(-abs(omega) / self._rise[1])
        if self._load_rise is not None:
            load_c = load_c + self._load_rise[0] * math.exp(-abs(g) / self._load_rise[1])
        # _forces(omega, ratio * omega, ...)
        tau_in = kt * self.current_drive - b * omega - c * sigma
        gear_load = tau_load + count * (load_b * g + load_c * (1.0 if g > 0.0 else (-1.0 if g < 0.0 else 0.0)))
        mu = self._mu_law(abs(omega) * r_w / cos_lead)
        # _acceleration: Eq. 28 with the self-consistent flank
        T, D = sigma * tau_in, sigma * gear_load
        a, ok = self._on_flank(mu, T, D, 1.0)
        flank = 1
        if not ok:
            a_m, ok_m = self._on_flank(mu, T, D, -1.0)
            if ok_m or not D >= 0.0:
                a, flank = a_m, -1
        alpha = sigma * a
        new_omega = omega + alpha * dt
        if (not new_omega > 0.0) if omega > 0.0 else (not new_omega < 0.0):  # _reverses: stop at zero
            new_omega = 0.0
        self.theta_worm = self.theta_worm + 0.5 * (omega + new_omega) * dt
        self.omega_worm = new_omega
        self.omega_gear, self.theta_gear = ratio * new_omega, ratio * self.theta_worm
        self.contact = flank if sigma > 0.0 else -flank
        self.tau_in, self.gear_load, self.alpha_worm, self.alpha_gear, self.mu = (
            tau_in, gear_load, alpha, ratio * alpha, mu)
        self.contact_out, self.worm_effect_torque, self.gear_effect_torque, self.impact_loss = (
            self.contact, None, None, 0.0)

    # --- mesh with a dead zone ----------------------------------------------------------------------------
    def _step_with_backlash(self, dt: float, tau_load: float) -> None:
        """RigPlant._step_with_backlash for one rig (see plant.py for the physics)."""
        ratio = self._ratio
        half = 0.5 * self.backlash
        jw, jg = self.worm_inertia, self.gear_inertia
        current = self.current_drive
        omega, omega_g, contact = self.omega_worm, self.omega_gear, self.contact
        engaged = contact != 0
        tau_in, gear_load, mu, worm_fx, gear_fx = self._forces(omega, omega_g, current, tau_load, engaged)
        moving = abs(omega) > STANDSTILL_SPEED

        # Coupled candidate (Eq. 28) and the contact side it implies: sigma * flank.
        if moving:
            alpha_c, flank = self._acceleration(tau_in, gear_load, omega, mu)
            implied = (1 if omega > 0.0 else -1) * flank
        else:
            alpha_c, implied = 0.0, 0  # (RigPlant's Eq. 28 at omega = 1 here is never used)
            if engaged:
                direction, alpha_c, flank_start = self._breakaway(current, tau_load)
                implied = int(direction) * flank_start
        if engaged and implied == contact:
            self._advance_in_contact(dt, tau_load, omega, moving, alpha_c, tau_in, gear_load, mu, worm_fx, gear_fx)
            return

        # Each shaft on its own (teeth apart), with its own stick at rest.
        if self._has_effects:
            free_tau_in, free_gear_load, _, free_worm_fx, free_gear_fx = self._forces(
                omega, omega_g, current, tau_load, False)
        else:
            free_tau_in, free_gear_load, free_worm_fx, free_gear_fx = tau_in, gear_load, None, None
        net_w, stuck_w = free_tau_in, False
        if abs(omega) <= STANDSTILL_SPEED:  # worm at rest: starts the way its probe torque pushes
            net_w = self._forces(_PROBE_SPEED, omega_g, current, tau_load, False)[0]
            if not net_w > 0:
                down = self._forces(-_PROBE_SPEED, omega_g, current, tau_load, False)[0]
                net_w = down if down < 0 else 0.0
            stuck_w = net_w == 0.0
        net_g, stuck_g = -free_gear_load, False
        if abs(omega_g) <= GEAR_STANDSTILL_SPEED:  # gear torque as a drive (+ along + rotation) = -gear_load
            net_g = -self._forces(omega, _PROBE_SPEED * ratio, current, tau_load, False)[1]
            if not net_g > 0:
                down = -self._forces(omega, -_PROBE_SPEED * ratio, current, tau_load, False)[1]
                net_g = down if down < 0 else 0.0
            stuck_g = net_g == 0.0
        alpha_wf, alpha_gf = net_w / jw, net_g / jg

        # Separation: the coupled solution wants the other flank, or (stuck together)
        # the free accelerations pull the teeth apart.
        relative = ratio * alpha_wf - alpha_gf
        if engaged and ((implied != 0 and implied != contact) or (implied == 0 and contact * relative < 0)):
            contact, engaged = 0, False

        # Integrate: coupled with Eq. 28, or free shaft by shaft.
        if engaged:
            omega_c = 0.0 if (not moving and implied == 0) else omega
            new_c = omega_c + alpha_c * dt
            if moving and _reverses(omega_c, new_c):
                new_c = 0.0
            omega_w0, omega_g0, new_w, new_g = omega_c, ratio * omega_c, new_c, ratio * new_c
            theta_w = self.theta_worm + 0.5 * (omega_w0 + new_w) * dt
            theta_g = ratio * theta_w - contact * half
        else:
            omega_w0 = 0.0 if stuck_w else omega
            new_w = omega_w0 + alpha_wf * dt
            if abs(omega) > STANDSTILL_SPEED and _reverses(omega_w0, new_w):  # (moving: omega_w0 = omega)
                new_w = 0.0
            omega_g0 = 0.0 if stuck_g else omega_g
            new_g = omega_g0 + alpha_gf * dt
            if abs(omega_g) > GEAR_STANDSTILL_SPEED and _reverses(omega_g0, new_g):
                new_g = 0.0
            theta_w = self.theta_worm + 0.5 * (omega_w0 + new_w) * dt
            theta_g = self.theta_gear + 0.5 * (omega_g0 + new_g) * dt

        # Impacts: a free rig reaching a flank while closing (or past it) engages it.
        impact_loss = 0.0
        if not engaged:
            position = ratio * theta_w - theta_g
            closing = ratio * new_w - new_g
            hit_fwd = position >= half - _CONTACT_TOLERANCE and (closing > 0 or position > half + _CONTACT_TOLERANCE)
            hit_back = position <= -half + _CONTACT_TOLERANCE and (closing < 0
                                                                   or position < -half - _CONTACT_TOLERANCE)
            if hit_fwd or hit_back:
                side = 1 if hit_fwd else -1
                common = (jw * new_w + ratio * jg * new_g) / (jw + ratio ** 2 * jg)  # momentum through the mesh
                # (x * x, not x ** 2: numpy squares by multiplying, libm's pow need not round alike)
                before = 0.5 * (jw * (new_w * new_w) + jg * (new_g * new_g))
                after = 0.5 * (jw + ratio ** 2 * jg) * (common * common)
                impact_loss = before - after
                new_w, new_g = common, ratio * common
                theta_g = ratio * theta_w - side * half
                contact = side

        if engaged:
            alpha_w, alpha_g = alpha_c, ratio * alpha_c
        else:
            alpha_w, alpha_g = alpha_wf, alpha_gf
            tau_in, gear_load, worm_fx, gear_fx = free_tau_in, free_gear_load, free_worm_fx, free_gear_fx
        if self._needs_heat:
            self.heat = self._heat(omega_w0, omega_g0, tau_in, gear_load, alpha_w, alpha_g, engaged)
        self.theta_worm, self.omega_worm = theta_w, new_w
        self.theta_gear, self.omega_gear = theta_g, new_g
        self.contact = contact
        self.tau_in, self.gear_load, self.alpha_worm, self.alpha_gear, self.mu = (
            tau_in, gear_load, alpha_w, alpha_g, mu)
        self.contact_out, self.worm_effect_torque, self.gear_effect_torque, self.impact_loss = (
            contact if engaged else 0, worm_fx, gear_fx, impact_loss)

    def _advance_in_contact(self, dt, tau_load, omega, moving, alpha, tau_in, gear_load, mu, worm_fx,
                            gear_fx) -> None:
        """The rig keeps its flank and moves (the common case): Eq. 28, no free shaft."""
        ratio = self._ratio
        new_omega = omega + alpha * dt
        if moving and _reverses(omega, new_omega):
            new_omega = 0.0
        if self._needs_heat:
            self.heat = self._heat(omega, ratio * omega, tau_in, gear_load, alpha, ratio * alpha, True)
        self.theta_worm = self.theta_worm + 0.5 * (omega + new_omega) * dt
        self.omega_worm = new_omega
        self.omega_gear = ratio * new_omega
        self.theta_gear = ratio * self.theta_worm - self.contact * (0.5 * self.backlash)
        self.tau_in, self.gear_load, self.alpha_worm, self.alpha_gear, self.mu = (
            tau_in, gear_load, alpha, ratio * alpha, mu)
        self.contact_out, self.worm_effect_torque, self.gear_effect_torque, self.impact_loss = (
            self.contact, worm_fx, gear_fx, 0.0)

    def _heat(self, omega, omega_g, tau_in, gear_load, alpha_w, alpha_g, engaged: bool) -> float:
        """RigPlant._heat for floats: mesh friction power (while touching) + dissipative shaft effects [W]."""
        mesh = mesh_heat_float(tau_in - self.worm_inertia * alpha_w, omega, gear_load + self.gear_inertia * alpha_g,
                               omega_g)
        shaft = (omega, self.theta_worm, omega_g, self.theta_gear, self.current_drive,
                 abs(gear_load) if engaged else 0.0)
        power = 0.0
        for worm, gear in self._heat_fx:  # EffectStack.heat: power - worm torque w + gear torque w_g
            power = power - (worm(*shaft) if worm else 0.0) * omega + (gear(*shaft) if gear else 0.0) * omega_g
        return (mesh if engaged else 0.0) + power
