"""The sensors of ONE rig in plain float math: the fast path of sensors.SensorModel (issue 13).

:class:`ScalarSensors` reads one sample period exactly as
SensorModel.measure_period does for n = 1 (see sensors.py for the hardware: ADC
sequence with per-channel sampling instants, tacho ripple, noise, 10-bit
quantisation, 4x encoders with int32 wrap), with the same floating-point
operations in the same order, and returns the same Measurement (arrays of shape
(1,)). The constants (sampling instants, LSBs, counts per turn) are read from the
SensorModel it wraps, so the two cannot drift apart.

Noise: the vectorised path draws rng.normal(0, std, (1,)) six times per sample,
in channel order (current_drive, current_load_1, current_load_2, tacho_drive,
tacho_load_1, tacho_load_2). Drawing 6 x BLOCK standard normals at once from the
same Generator gives the same numbers in the same order (numpy's normal is
loc + scale * standard_normal), so both paths report the same samples for the same
seed; one block lasts BLOCK samples. The Generator is thereby ahead of the
samples returned so far by up to BLOCK - 1 samples' draws: whoever else draws
from SensorModel.rng mid-run gets different numbers than with the vectorised path.
"""
from __future__ import annotations

import math

import numpy as np

from worm_rig_driver.sim.effects import EffectStack, SenseContext
from worm_rig_driver.sim.sensors import (
    STATUS_DRIVE_LIMIT,
    STATUS_SIMULATED,
    TACHO_RIPPLE_ORDER,
    Measurement,
    SensorModel,
)

#: samples of noise drawn per call to the Generator
BLOCK = 1000

#: index of each quantity in a history entry (the plant's state at one substep boundary)
CURRENT_DRIVE, CURRENT_LOAD, OMEGA_WORM, THETA_WORM, OMEGA_GEAR, THETA_GEAR = range(6)

_empty, _float64, _int32, _uint32 = np.empty, np.float64, np.int32, np.uint32


def _array(x) -> np.ndarray:
    """A (1,) float array holding x (cheaper than np.array([x]) for one element)."""
    a = _empty(1)
    a[0] = x
    return a


class ScalarSensors:
    """SensorModel.measure_period for one rig, on a history of floats.

    Args:
        model: the rig's SensorModel (its rng, effects, ADC timing and scaling are used).
        substeps: plant steps per sample period (the history has substeps + 1 entries).

    Effects: each live effect with a ``sense`` hook must have ``sense_float``
    (scalar_plant.float_hooks_missing checks this).
    """

    def __init__(self, model: SensorModel, substeps: int) -> None:
        self.model = model
        rig = model.rig
        sensors = rig.sensors
        self._rng = model.rng
        self._std = (sensors.current_noise_std,) * 3 + (sensors.tacho_noise_std,) * 3
        self._noise: list[float] = []
        self._next = 0

        # Each channel's sampling instant as (k, frac) between history entries k and k + 1
        # (Trajectory.at with the period's duration and `substeps` steps).
        def where(signal: str) -> tuple[int, float]:
            x = min(max(model.sample_time[signal] / model.sample_period, 0.0), 1.0) * substeps
            k = min(int(x), substeps - 1)
            return k, x - k

        self._at = {signal: where(signal) for signal in model.sample_time}
        self._ripple = sensors.tacho_ripple
        self._half = model.adc.codes // 2
        self._current_lsb = sensors.current_lsb
        self._tacho_lsb = model.tacho_lsb
        self._cpr = model.counts_per_rev
        self._rad_per_count = 2.0 * np.pi / model.counts_per_rev
        self._load_torque_scale = rig.load_motor.torque_constant  # tau_load = K_t (i_1 + i_2) count / 2
        self._load_count = rig.load_motor_count
        self._supply = rig.supply_voltage
        fx: EffectStack | None = model.effects
        self._sense = [e.sense_float for e in fx.effects if "sense" in type(e).hooks()] if fx is not None else []

    def _draw(self) -> None:
        """The next BLOCK samples' noise, [std] * standard normal, flattened in the vectorised path's order."""
        z = self._rng.standard_normal((BLOCK, 6))
        self._noise = (0.0 + np.asarray(self._std) * z).ravel().tolist()  # = rng.normal(0.0, std)
        self._next = 0

    # --- one channel -------------------------------------------------------------------------------
    def _quantise(self, signal: float, lsb: float) -> float:
        """SensorModel._adc: nearest code (ties to even, as np.round), clipped to the converter's range."""
        try:
            code = round(signal / lsb)
        except (ValueError, OverflowError):  # NaN / inf: a diverged plant; numpy's answer
            return float(np.minimum(np.maximum(np.round(signal / lsb), -self._half), self._half - 1) * lsb)
        half = self._half
        return (-half if code < -half else (half - 1 if code > half - 1 else code)) * lsb

    def _encoder(self, theta: float) -> tuple[int, float]:
        """SensorModel._encoder: (count wrapped to int32, the angle the unwrapped count resolves [rad])."""
        try:
            count = math.floor(theta * self._cpr / (2.0 * math.pi))
        except (ValueError, OverflowError):  # NaN / inf: a diverged plant; numpy's answer
            count = int(np.floor(np.float64(theta) * self._cpr / (2.0 * np.pi)).astype(np.int64))
        return (count + 2**31) % 2**32 - 2**31, count * self._rad_per_count

    # --- a whole sample -------------------------------------------------------------------------------
    def measure(self, history: list[tuple[float, ...]], voltage_drive: float, saturated: bool,
                tick: float) -> Measurement:
        """Sample every channel over one period that started at sim time `tick` [s].

        Args:
            history: the plant's (current_drive, current_load, omega_worm, theta_worm,
                omega_gear, theta_gear) at the substep boundaries, substeps + 1 entries.
            voltage_drive: [V] the voltage the H-bridge applied in the last step.
            saturated: whether the requested voltage exceeded the supply.
            tick: [s] sim time of the period's start.
        """
        at = self._at

        def value(signal: str, index: int) -> float:  # Trajectory.at
            k, frac = at[signal]
            a = history[k][index]
            return a + frac * (history[k + 1][index] - a) if frac else a

        def tacho(signal: str, omega: int, theta: int) -> float:
            return value(signal, omega) * (1.0 + self._ripple * math.sin(TACHO_RIPPLE_ORDER * value(signal, theta)))

        signals = {
            "current_drive": value("current_drive", CURRENT_DRIVE),
            "current_load_1": value("current_load_1", CURRENT_LOAD),
            "current_load_2": value("current_load_2", CURRENT_LOAD),
            "tacho_drive": tacho("tacho_drive", OMEGA_WORM, THETA_WORM),
            "tacho_load_1": tacho("tacho_load_1", OMEGA_GEAR, THETA_GEAR),
            "tacho_load_2": tacho("tacho_load_2", OMEGA_GEAR, THETA_GEAR),
        }
        if self._sense:
            context = SenseContext({k: tick + v for k, v in self.model.sample_time.items()}, voltage_drive,
                                   self._supply)
            for sense in self._sense:
                sense(signals, context)

        if self._next == len(self._noise):
            self._draw()
        j = self._next
        self._next = j + 6
        n = self._noise
        quantise, lsb, tacho_lsb = self._quantise, self._current_lsb, self._tacho_lsb
        current_drive = quantise(signals["current_drive"] + n[j], lsb)
        load_1 = quantise(signals["current_load_1"] + n[j + 1], lsb)
        load_2 = quantise(signals["current_load_2"] + n[j + 2], lsb)
        tacho_drive = quantise(signals["tacho_drive"] + n[j + 3], tacho_lsb["tacho_drive"])
        tacho_load_1 = quantise(signals["tacho_load_1"] + n[j + 4], tacho_lsb["tacho_load_1"])
        tacho_load_2 = quantise(signals["tacho_load_2"] + n[j + 5], tacho_lsb["tacho_load_2"])
        count_drive, theta_worm = self._encoder(history[0][THETA_WORM])  # latched at the tick
        count_load, theta_gear = self._encoder(history[0][THETA_GEAR])

        counts = _empty(3, _int32)
        counts[0], counts[1], counts[2] = count_drive, count_load, count_load
        status = _empty(1, _uint32)
        status[0] = (STATUS_DRIVE_LIMIT if saturated else 0) | STATUS_SIMULATED
        return Measurement(
            current_drive=_array(current_drive),
            current_load_1=_array(load_1),
            current_load_2=_array(load_2),
            omega_worm=_array(tacho_drive),
            omega_gear=_array(0.5 * (tacho_load_1 + tacho_load_2)),
            theta_worm=_array(theta_worm),
            theta_gear=_array(theta_gear),
            count_drive=counts[0:1],
            count_load_1=counts[1:2],
            count_load_2=counts[2:3],
            voltage_drive=_array(voltage_drive),
            tau_load=_array(self._load_torque_scale * (load_1 + load_2) * self._load_count / 2.0),
            status=status,
            tacho_load_1=_array(tacho_load_1),
            tacho_load_2=_array(tacho_load_2),
        )
