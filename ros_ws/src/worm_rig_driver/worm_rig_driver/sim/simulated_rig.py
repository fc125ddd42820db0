"""A simulated rig sampled like the real one: plant + effects + sensors + a sample clock.

The same object serves the live sim_node (n = 1, advanced in real time) and
batch work such as calibration (n rigs side by side, as fast as numpy goes).
Deterministic for a given seed: the seed drives the sensor noise only; the plant
and the effects are deterministic.

Two implementations of the same model: the vectorised one (plant.RigPlant
+ sensors.SensorModel, numpy over n rigs) and, for one rig, a scalar one in plain
float math (scalar_plant.ScalarPlant + scalar_sensors.ScalarSensors, ~10 us instead
of ~300 us per sample: for n = 1 numpy's cost per call, not the physics, dominated). n = 1 takes the scalar
path unless an active effect lacks the float hooks (then the vectorised one); the
two agree to round-off and draw the same noise for the same seed (test_scalar_path).

Timing of one sample (the firmware's): the tick at the start of the period latches
the encoders and starts the ADC sequence, each analogue channel is held at its own
instant inside the period (sensors.AdcChain), and the sample is complete at the
period's end, which is when sample() returns it. truth() is the plant at that end.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worm_model.physics.internal_forces import internal_forces, internal_forces_float
from worm_model.physics.modes import Flank, Mode
from worm_model.physics.parameters import Rig
from worm_model.rig_data.samples import RigSample

from worm_rig_driver.sim.effects import EffectsConfig, as_config
from worm_rig_driver.sim.plant import STANDSTILL_SPEED, PlantOutputs, RigPlant
from worm_rig_driver.sim.scalar_plant import ScalarPlant, float_hooks_missing
from worm_rig_driver.sim.scalar_sensors import ScalarSensors
from worm_rig_driver.sim.sensors import AdcChain, Measurement, SensorModel, Trajectory

#: plant state fields recorded at every substep boundary for the ADC's sampling instants
_RECORDED = ("current_drive", "current_load", "omega_worm", "theta_worm", "omega_gear", "theta_gear")


@dataclass
class Truth:
    """What only a simulator knows, for one sample; arrays of shape (n,)."""

    tau_load: np.ndarray  # [N m] load torque the load motors apply (positive opposing + rotation)
    tau_in: np.ndarray  # [N m] torque delivered to the worm shaft
    omega_worm: np.ndarray  # [rad/s]
    current_drive: np.ndarray  # [A]
    normal_force: np.ndarray  # [N]
    friction_force: np.ndarray  # [N]
    mu: np.ndarray  # [1]
    mode: np.ndarray  # worm_model.physics.modes.Mode values
    flank: np.ndarray  # worm_model.physics.modes.Flank values
    omega_gear: np.ndarray | None = None  # [rad/s] worm-referenced (differs from i*omega_worm in the backlash)
    theta_worm: np.ndarray | None = None  # [rad]
    theta_gear: np.ndarray | None = None  # [rad] worm-referenced
    contact: np.ndarray | None = None  # int8: +1/-1 the side the teeth touch (fixed frame), 0 apart
    effects: dict | None = None  # observable effect states, e.g. {"oil_temperature": [degC]}


def rig_sample(m: Measurement, seq: int, stamp_ns: int = 0, status_bits: int = 0, command_seq: int = 0,
               frame_id: str = "", k: int = 0) -> RigSample:
    """Rig ``k``'s reading of a SimulatedRig measurement as the rig publishes it: sample ``seq`` stamped
    ``stamp_ns`` [ns], its status with ``status_bits`` (the rig loop's: watchdog, drive limit) added."""
    return RigSample(
        seq, stamp_ns, float(m.current_drive[k]), float(m.current_load_1[k]), float(m.current_load_2[k]),
        float(m.omega_worm[k]), float(m.omega_gear[k]), float(m.theta_worm[k]), float(m.theta_gear[k]),
        int(m.count_drive[k]), int(m.count_load_1[k]), int(m.count_load_2[k]), float(m.voltage_drive[k]),
        float(m.tau_load[k]), int(m.status[k]) | status_bits, command_seq, frame_id)


def true_mode(flank: np.ndarray, tau_load: np.ndarray, omega_worm: np.ndarray) -> np.ndarray:
    """Mode from the engaged flank (physics.md section 3): the flank decides, not a threshold."""
    load_in_frame = np.sign(omega_worm) * tau_load
    mode = np.where(flank < 0, Mode.ASSISTIVE,
                    np.where(load_in_frame >= 0, Mode.RESISTIVE, Mode.PSEUDO_RESISTIVE))
    return np.where(np.abs(omega_worm) > STANDSTILL_SPEED, mode, Mode.STANDSTILL).astype(np.int8)


def true_mode_float(flank: int, tau_load: float, omega_worm: float) -> int:
    """true_mode for one sample of floats (the scalar path's truth)."""
    if not abs(omega_worm) > STANDSTILL_SPEED:
        return int(Mode.STANDSTILL)
    if flank < 0:
        return int(Mode.ASSISTIVE)
    load_in_frame = (1.0 if omega_worm > 0.0 else -1.0) * tau_load
    return int(Mode.RESISTIVE if load_in_frame >= 0 else Mode.PSEUDO_RESISTIVE)


class SimulatedRig:
    """n simulated rigs with the paper's sensors, advanced one sample period at a time.

    Args:
        rig: rig parameters.
        n: rigs side by side (each gets its own commands and noise).
        seed: seed of the sensor noise; same seed, same commands -> same samples.
        substeps: integration steps per sample period.
        effects: effects the model lacks, switched on in the simulator only
            (effects.EffectsConfig, an ``effects`` mapping, or a worm_rig_effects
            file); None = the paper's model exactly.
        adc: multiplexer/ADC timing and scaling of the analogue channels.
        scalar: which implementation steps the rig(s): None (default) = the scalar
            one for n = 1 when every active effect has float hooks (all of
            effects.EFFECTS do), else the vectorised one; True = scalar (n must be
            1); False = vectorised. ``self.scalar`` tells which one runs. Both
            expose the same ``plant`` (state, fx, inertias, ...) and ``sensors``;
            the scalar path draws the noise from sensors.rng in blocks of
            scalar_sensors.BLOCK samples (same numbers, drawn ahead).

    Raises:
        ValueError: substeps < 1, the ADC sequence does not fit in a sample period,
            or scalar=True with n != 1 or with an effect that has no float hooks.
        effects.EffectsError: a bad effects file or mapping.
    """

    def __init__(self, rig: Rig, n: int = 1, seed: int = 0, substeps: int = 2,
                 effects: EffectsConfig | dict | str | None = None, adc: AdcChain = AdcChain(),
                 scalar: bool | None = None) -> None:
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1, got {substeps}")
        self.rig = rig
        self.n = n
        effects = as_config(effects)
        if scalar is None:
            scalar = n == 1 and not float_hooks_missing(effects)
        elif scalar and n != 1:
            raise ValueError(f"the scalar path simulates one rig, got n={n}")
        #: True when the scalar (float) implementation runs, False for the vectorised one
        self.scalar = bool(scalar)
        self.plant = ScalarPlant(rig, effects=effects) if self.scalar else RigPlant(rig, n, effects=effects)
        self.effects = self.plant.effects
        self.sensors = SensorModel(rig, np.random.default_rng(seed), self.plant.fx, adc)
        self._scalar_sensors = ScalarSensors(self.sensors, substeps) if self.scalar else None
        self.sample_period = 1.0 / rig.sensors.sample_rate_hz
        self.substeps = substeps
        self.seq = 0
        self.time = 0.0
        self.voltage_drive = np.zeros(n)
        self.load_torque = np.zeros(n)
        self._last: PlantOutputs | None = None
        self._stepped = False

    def command(self, voltage_drive=None, load_torque=None) -> None:
        """Set the drive voltage [V] and/or the load torque [N m] held until changed."""
        if self.n == 1 and isinstance(voltage_drive, float) and load_torque is None:
            # the live rig's loop sets one float every sample: skip numpy's broadcasting for it
            self.voltage_drive = np.array((voltage_drive,))
            return
        if voltage_drive is not None:
            self.voltage_drive = np.broadcast_to(np.asarray(voltage_drive, float), (self.n,)).copy()
        if load_torque is not None:
            self.load_torque = np.broadcast_to(np.asarray(load_torque, float), (self.n,)).copy()

    def sample(self) -> Measurement:
        """Advance one sample period and return what the sensors read during it."""
        if self.scalar:
            return self._sample_scalar()
        dt = self.sample_period / self.substeps
        state = self.plant.state
        history = {name: np.empty((self.substeps + 1, self.n)) for name in _RECORDED}
        for name in _RECORDED:
            history[name][0] = getattr(state, name)
        for k in range(1, self.substeps + 1):
            self._last = self.plant.step(dt, self.voltage_drive, self.load_torque)
            for name in _RECORDED:
                history[name][k] = getattr(state, name)
        tick = self.time
        self.seq += 1
        # the clock counts samples, so it does not drift by summing periods
        self.time = self.seq * self.sample_period
        return self.sensors.measure_period(Trajectory(self.sample_period, history), self._last, tick)

    def _sample_scalar(self) -> Measurement:
        """sample() on the scalar path: the same steps and readings in float math."""
        plant = self.plant
        history = plant.advance(self.sample_period / self.substeps, self.substeps, self.voltage_drive.item(0),
                                self.load_torque.item(0))
        self._stepped = True
        tick = self.time
        self.seq += 1
        self.time = self.seq * self.sample_period
        return self._scalar_sensors.measure(history, plant.voltage_drive, plant.drive_saturated, tick)

    def _last_outputs(self, what: str) -> PlantOutputs:
        if self.scalar:
            if not self._stepped:
                raise RuntimeError(f"{what} needs at least one sample()")
            return self.plant.outputs()
        if self._last is None:
            raise RuntimeError(f"{what} needs at least one sample()")
        return self._last

    @property
    def applied_load_torque(self) -> np.ndarray:
        """Load torque [N m] the load motors applied in the last step (cheap part of the truth)."""
        if self.scalar and self._stepped:
            return np.array([self.plant.tau_load])
        return self._last_outputs("applied_load_torque").tau_load

    def truth(self) -> Truth:
        """Ground truth at the end of the last sample period (call after sample()).

        Contact forces come from Eqs 19-23 with everything that acts on each shaft
        (effects included) and the true inertias; while the teeth are apart in the
        backlash, N = F_f = 0, mu = NaN and the flank is NONE.
        """
        if self.scalar:
            return self._truth_scalar()
        out, state = self._last_outputs("truth()"), self.plant.state
        forces = internal_forces(self.rig.gearbox, out.tau_in, out.gear_load, state.omega_worm,
                                 out.alpha_worm, worm_inertia=self.plant.worm_inertia,
                                 gear_inertia=self.plant.gear_inertia)
        moving = np.abs(state.omega_worm) > STANDSTILL_SPEED
        apart = out.contact == 0
        flank = np.where(moving & ~apart, forces.flank, Flank.NONE)
        normal = np.where(apart, 0.0, forces.normal_force)
        friction = np.where(apart, 0.0, forces.friction_force)
        mu = np.where(apart, np.nan, forces.mu)
        return Truth(
            tau_load=out.tau_load.copy(), tau_in=out.tau_in.copy(),
            omega_worm=state.omega_worm.copy(), current_drive=state.current_drive.copy(),
            normal_force=normal, friction_force=friction,
            mu=mu, mode=true_mode(flank, out.tau_load, state.omega_worm),
            flank=flank.astype(np.int8), omega_gear=state.omega_gear.copy(), theta_worm=state.theta_worm.copy(),
            theta_gear=state.theta_gear.copy(), contact=np.asarray(out.contact).copy(),
            effects=self.plant.fx.observe(),
        )

    def _truth_scalar(self) -> Truth:
        """truth() on the scalar path: the same quantities from the plant's floats (no array passes)."""
        if not self._stepped:
            raise RuntimeError("truth() needs at least one sample()")
        p = self.plant
        p._sync()  # (state arrays written into since the last step count, as on RigPlant)
        omega = p.omega_worm
        normal, friction, mu, flank = internal_forces_float(self.rig.gearbox, p.tau_in, p.gear_load, omega,
                                                            p.alpha_worm, worm_inertia=p.worm_inertia,
                                                            gear_inertia=p.gear_inertia)
        apart = p.contact_out == 0
        if apart:
            normal, friction, mu = 0.0, 0.0, math.nan
        if apart or not abs(omega) > STANDSTILL_SPEED:
            flank = int(Flank.NONE)

        def one(x, dtype=float):
            return np.array([x], dtype=dtype)

        return Truth(
            tau_load=one(p.tau_load), tau_in=one(p.tau_in), omega_worm=one(omega), current_drive=one(p.current_drive),
            normal_force=one(normal), friction_force=one(friction), mu=one(mu),
            mode=one(true_mode_float(flank, p.tau_load, omega), np.int8), flank=one(flank, np.int8),
            omega_gear=one(p.omega_gear), theta_worm=one(p.theta_worm), theta_gear=one(p.theta_gear),
            contact=one(p.contact_out, np.int8), effects=p.fx.observe(),
        )
