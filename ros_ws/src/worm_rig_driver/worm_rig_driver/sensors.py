"""The rig's sensors as the firmware reads them (paper section 3.1).

Hall-effect armature current sensors into the 10-bit ADC (noise, then
quantisation to one ADC step), tachogenerators on each motor (commutator
ripple and noise), and 500 pulse/rev two-channel encoders decoded 4x into
counts that wrap as int32. Vectorised over an ensemble of rigs; plain numpy.

Signs follow plant.py: positive worm rotation is the reference and gear
quantities are referred to it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_model.parameters import Rig

from .plant import PlantOutputs, PlantState

#: Commutator segments of the tachogenerators (assumption: a small 7-segment DC tacho).
TACHO_RIPPLE_ORDER = 7

STATUS_DRIVE_LIMIT = 1
STATUS_SIMULATED = 8


@dataclass
class Measurement:
    """One sample of every rig channel, as worm_msgs/RigSample carries it; arrays of shape (n,)."""

    current_drive: np.ndarray  # [A]
    current_load_1: np.ndarray  # [A]
    current_load_2: np.ndarray  # [A]
    omega_worm: np.ndarray  # [rad/s] drive tacho
    omega_gear: np.ndarray  # [rad/s] mean of the load tachos
    theta_worm: np.ndarray  # [rad] from the drive encoder, unwrapped
    theta_gear: np.ndarray  # [rad] from the load encoders, unwrapped
    count_drive: np.ndarray  # [count] int32, wraps
    count_load_1: np.ndarray
    count_load_2: np.ndarray
    voltage_drive: np.ndarray  # [V]
    tau_load: np.ndarray  # [N m] K_t,load x measured load currents
    status: np.ndarray  # uint32 bit set (RigSample.STATUS_*)


def wrap_int32(counts: np.ndarray) -> np.ndarray:
    """Wrap integer counts to signed 32 bit, as a free-running hardware counter does."""
    return ((np.asarray(counts, dtype=np.int64) + 2**31) % 2**32 - 2**31).astype(np.int32)


class SensorModel:
    """Turns the plant's true state into what the rig's sensors report."""

    def __init__(self, rig: Rig, rng: np.random.Generator) -> None:
        self.rig = rig
        self.rng = rng
        sensors = rig.sensors
        self.counts_per_rev = sensors.encoder_pulses_per_rev * sensors.encoder_decoding

    def _current(self, true_current: np.ndarray) -> np.ndarray:
        sensors = self.rig.sensors
        noisy = true_current + self.rng.normal(0.0, sensors.current_noise_std, np.shape(true_current))
        return np.round(noisy / sensors.current_lsb) * sensors.current_lsb

    def _tacho(self, omega: np.ndarray, theta: np.ndarray) -> np.ndarray:
        sensors = self.rig.sensors
        ripple = 1.0 + sensors.tacho_ripple * np.sin(TACHO_RIPPLE_ORDER * theta)
        return omega * ripple + self.rng.normal(0.0, sensors.tacho_noise_std, np.shape(omega))

    def _encoder(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Counts (wrapped int32) and the angle they resolve [rad]."""
        counts = np.floor(theta * self.counts_per_rev / (2.0 * np.pi)).astype(np.int64)
        return wrap_int32(counts), counts * (2.0 * np.pi / self.counts_per_rev)

    def measure(self, state: PlantState, outputs: PlantOutputs) -> Measurement:
        """Sample every channel of every rig once."""
        rig = self.rig
        ratio = rig.gearbox.ratio
        theta_gear_true = ratio * state.theta_worm
        omega_gear_true = ratio * state.omega_worm
        count_drive, theta_worm = self._encoder(state.theta_worm)
        count_load, theta_gear = self._encoder(theta_gear_true)
        load_1 = self._current(state.current_load)
        load_2 = self._current(state.current_load)
        tachos_gear = 0.5 * (self._tacho(omega_gear_true, theta_gear_true)
                             + self._tacho(omega_gear_true, theta_gear_true))
        status = np.where(outputs.drive_saturated, STATUS_DRIVE_LIMIT, 0) | STATUS_SIMULATED
        return Measurement(
            current_drive=self._current(state.current_drive),
            current_load_1=load_1,
            current_load_2=load_2,
            omega_worm=self._tacho(state.omega_worm, state.theta_worm),
            omega_gear=tachos_gear,
            theta_worm=theta_worm,
            theta_gear=theta_gear,
            count_drive=count_drive,
            count_load_1=count_load,
            count_load_2=count_load.copy(),
            voltage_drive=outputs.voltage_drive.copy(),
            tau_load=rig.load_motor.torque_constant * (load_1 + load_2) * rig.load_motor_count / 2.0,
            status=status.astype(np.uint32),
        )
