"""A simulated rig sampled like the real one: plant + sensors + a sample clock.

The same object serves the live sim_node (n = 1, advanced in real time) and
batch work such as calibration (n rigs side by side, as fast as numpy goes).
Deterministic for a given seed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_model.internal_forces import internal_forces
from worm_model.modes import Flank, Mode
from worm_model.parameters import Rig

from .plant import STANDSTILL_SPEED, PlantOutputs, RigPlant
from .sensors import Measurement, SensorModel


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
    mode: np.ndarray  # worm_model.modes.Mode values
    flank: np.ndarray  # worm_model.modes.Flank values


def true_mode(flank: np.ndarray, tau_load: np.ndarray, omega_worm: np.ndarray) -> np.ndarray:
    """Mode from the engaged flank (physics.md section 3): the flank decides, not a threshold."""
    load_in_frame = np.sign(omega_worm) * tau_load
    mode = np.where(flank < 0, Mode.ASSISTIVE,
                    np.where(load_in_frame >= 0, Mode.RESISTIVE, Mode.PSEUDO_RESISTIVE))
    return np.where(np.abs(omega_worm) > STANDSTILL_SPEED, mode, Mode.STANDSTILL).astype(np.int8)


class SimulatedRig:
    """n simulated rigs with the paper's sensors, advanced one sample period at a time.

    Args:
        rig: rig parameters.
        n: rigs side by side (each gets its own commands and noise).
        seed: seed of the sensor noise; same seed, same commands -> same samples.
        substeps: integration steps per sample period.
    """

    def __init__(self, rig: Rig, n: int = 1, seed: int = 0, substeps: int = 2) -> None:
        if substeps < 1:
            raise ValueError(f"substeps must be >= 1, got {substeps}")
        self.rig = rig
        self.n = n
        self.plant = RigPlant(rig, n)
        self.sensors = SensorModel(rig, np.random.default_rng(seed))
        self.sample_period = 1.0 / rig.sensors.sample_rate_hz
        self.substeps = substeps
        self.seq = 0
        self.time = 0.0
        self.voltage_drive = np.zeros(n)
        self.load_torque = np.zeros(n)
        self._last: PlantOutputs | None = None

    def command(self, voltage_drive=None, load_torque=None) -> None:
        """Set the drive voltage [V] and/or the load torque [N m] held until changed."""
        if voltage_drive is not None:
            self.voltage_drive = np.broadcast_to(np.asarray(voltage_drive, float), (self.n,)).copy()
        if load_torque is not None:
            self.load_torque = np.broadcast_to(np.asarray(load_torque, float), (self.n,)).copy()

    def sample(self) -> Measurement:
        """Advance one sample period and return what the sensors read at its end."""
        dt = self.sample_period / self.substeps
        for _ in range(self.substeps):
            self._last = self.plant.step(dt, self.voltage_drive, self.load_torque)
        self.seq += 1
        self.time += self.sample_period
        return self.sensors.measure(self.plant.state, self._last)

    @property
    def applied_load_torque(self) -> np.ndarray:
        """Load torque [N m] the load motors applied in the last step (cheap part of the truth)."""
        if self._last is None:
            raise RuntimeError("applied_load_torque needs at least one sample()")
        return self._last.tau_load

    def truth(self) -> Truth:
        """Ground truth at the last sample (call after sample())."""
        if self._last is None:
            raise RuntimeError("truth() needs at least one sample()")
        out, state = self._last, self.plant.state
        forces = internal_forces(self.rig.gearbox, out.tau_in, out.gear_load, state.omega_worm,
                                 out.alpha_worm, worm_inertia=self.rig.total_worm_inertia,
                                 gear_inertia=self.rig.total_gear_inertia)
        flank = np.where(np.abs(state.omega_worm) > STANDSTILL_SPEED, forces.flank, Flank.NONE)
        return Truth(
            tau_load=out.tau_load.copy(), tau_in=out.tau_in.copy(),
            omega_worm=state.omega_worm.copy(), current_drive=state.current_drive.copy(),
            normal_force=forces.normal_force, friction_force=forces.friction_force,
            mu=forces.mu, mode=true_mode(flank, out.tau_load, state.omega_worm),
            flank=flank.astype(np.int8),
        )
