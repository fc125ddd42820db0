"""The sensors of ONE rig in plain float math: the fast path of sensors.SensorModel.

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
    Measurement,
    SensorModel,
)

#: samples of noise drawn per call to the Generator
BLOCK = 1000

#: index of each quantity in a history entry (the plant's state at one substep boundary)
CURRENT_DRIVE, CURRENT_LOAD, OMEGA_WORM, THETA_WORM, OMEGA_GEAR, THETA_GEAR = range(6)

_empty, _int32, _uint32 = np.empty, np.int32, np.uint32
_TWO_PI = 2.0 * math.pi  # (= sensors' 2.0 * np.pi)


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

        #: (k, frac) of each channel in sensors.SIGNALS order: current_drive, current_load_1,
        #: current_load_2, tacho_drive, tacho_load_1, tacho_load_2
        self._instants = tuple(where(signal) for signal in ("current_drive", "current_load_1", "current_load_2",
                                                             "tacho_drive", "tacho_load_1", "tacho_load_2"))
        self._ripple = sensors.tacho_ripple
        self._ripple_order = model.ripple_order
        self._half = model.adc.codes // 2
        self._lsb = (sensors.current_lsb,) * 3 + tuple(model.tacho_lsb[k] for k in
                                                      ("tacho_drive", "tacho_load_1", "tacho_load_2"))
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

    # --- one channel (the slow path: a diverged plant's NaN or inf) ---------------------------------
    def _quantise(self, signal: float, lsb: float) -> float:
        """SensorModel._adc on any float, through numpy (NaN stays NaN)."""
        return float(np.minimum(np.maximum(np.round(signal / lsb), -self._half), self._half - 1) * lsb)

    def _count(self, theta: float) -> int:
        """SensorModel._encoder's unwrapped count on any float, through numpy."""
        with np.errstate(invalid="ignore"):
            return int(np.floor(np.float64(theta) * self._cpr / (2.0 * np.pi)).astype(np.int64))

    # --- a whole sample -------------------------------------------------------------------------------
    def measure(self, history: list[tuple[float, ...]], voltage_drive: float, saturated: bool,
                tick: float) -> Measurement:
        """Sample every channel over one period that started at sim time `tick` [s].

        The analog channels at their own instants, the effects on the sensors, noise and the ADC,
        then the encoders latched at the tick; packed as one sample.

        Args:
            history: the plant's (current_drive, current_load, omega_worm, theta_worm,
                omega_gear, theta_gear) at the substep boundaries, substeps + 1 entries.
            voltage_drive: [V] the voltage the H-bridge applied in the last step.
            saturated: whether the requested voltage exceeded the supply.
            tick: [s] sim time of the period's start.
        """
        analog = self._analog(history)
        if self._sense:
            analog = self._sensed(analog, voltage_drive, tick)
        converted = self._convert(analog)
        theta_worm, theta_gear = history[0][3], history[0][5]
        try:  # encoders, latched at the tick: floor of the counts
            count_drive = math.floor(theta_worm * self._cpr / _TWO_PI)
            count_load = math.floor(theta_gear * self._cpr / _TWO_PI)
        except (ValueError, OverflowError):
            count_drive, count_load = self._count(theta_worm), self._count(theta_gear)
        return self._pack(converted, count_drive, count_load, voltage_drive, saturated)

    def _analog(self, history: list[tuple[float, ...]]) -> tuple[float, ...]:
        """The six analog channels (three currents [A], three tachos [rad/s]), each at its own instant."""
        # Trajectory.at, a + frac (b - a) between the boundaries around each instant. Written out channel
        # by channel: a helper call each costs more than the arithmetic.
        instants, ripple = self._instants, self._ripple
        (k0, f0), (k1, f1), (k2, f2), (k3, f3), (k4, f4), (k5, f5) = instants
        a, b = history[k0], history[k0 + 1]
        current_drive = a[0] + f0 * (b[0] - a[0]) if f0 else a[0]
        a, b = history[k1], history[k1 + 1]
        load_1 = a[1] + f1 * (b[1] - a[1]) if f1 else a[1]
        a, b = history[k2], history[k2 + 1]
        load_2 = a[1] + f2 * (b[1] - a[1]) if f2 else a[1]
        # tachos: omega (1 + ripple sin(p theta)) of their own shaft, p the ripple order
        order = self._ripple_order
        a, b = history[k3], history[k3 + 1]
        omega, theta = (a[2] + f3 * (b[2] - a[2]), a[3] + f3 * (b[3] - a[3])) if f3 else (a[2], a[3])
        tacho_drive = omega * (1.0 + ripple * math.sin(order * theta))
        a, b = history[k4], history[k4 + 1]
        omega, theta = (a[4] + f4 * (b[4] - a[4]), a[5] + f4 * (b[5] - a[5])) if f4 else (a[4], a[5])
        tacho_load_1 = omega * (1.0 + ripple * math.sin(order * theta))
        a, b = history[k5], history[k5 + 1]
        omega, theta = (a[4] + f5 * (b[4] - a[4]), a[5] + f5 * (b[5] - a[5])) if f5 else (a[4], a[5])
        tacho_load_2 = omega * (1.0 + ripple * math.sin(order * theta))
        return current_drive, load_1, load_2, tacho_drive, tacho_load_1, tacho_load_2

    def _sensed(self, analog: tuple[float, ...], voltage_drive: float, tick: float) -> tuple[float, ...]:
        """The analog channels after the effects that act on the sensors (gain, offset, PWM ripple, ...)."""
        names = ("current_drive", "current_load_1", "current_load_2", "tacho_drive", "tacho_load_1",
                 "tacho_load_2")
        signals = dict(zip(names, analog))
        context = SenseContext({k: tick + v for k, v in self.model.sample_time.items()}, voltage_drive,
                               self._supply)
        for sense in self._sense:
            sense(signals, context)
        return tuple(signals[name] for name in names)

    def _convert(self, analog: tuple[float, ...]) -> tuple[float, ...]:
        """Noise, then the ADC: each channel to its nearest code (round(): ties to even, as np.round), clipped
        to the converter's range, back in SI units."""
        lsb, low, high = self._lsb, -self._half, self._half - 1
        if self._next == len(self._noise):
            self._draw()
        j = self._next
        self._next = j + 6
        noise = self._noise
        values = (analog[0] + noise[j], analog[1] + noise[j + 1], analog[2] + noise[j + 2],
                  analog[3] + noise[j + 3], analog[4] + noise[j + 4], analog[5] + noise[j + 5])
        try:
            c0, c1, c2, c3, c4, c5 = (round(values[0] / lsb[0]), round(values[1] / lsb[1]),
                                      round(values[2] / lsb[2]), round(values[3] / lsb[3]),
                                      round(values[4] / lsb[4]), round(values[5] / lsb[5]))
        except (ValueError, OverflowError):  # NaN or inf: a diverged plant
            c0, c1, c2, c3, c4, c5 = (self._quantise(v, q) / q for v, q in zip(values, lsb))
        # (clamped channel by channel: a generator over the six costs more than the arithmetic)
        return ((low if c0 < low else (high if c0 > high else c0)) * lsb[0],
                (low if c1 < low else (high if c1 > high else c1)) * lsb[1],
                (low if c2 < low else (high if c2 > high else c2)) * lsb[2],
                (low if c3 < low else (high if c3 > high else c3)) * lsb[3],
                (low if c4 < low else (high if c4 > high else c4)) * lsb[4],
                (low if c5 < low else (high if c5 > high else c5)) * lsb[5])

    def _pack(self, converted: tuple[float, ...], count_drive: int, count_load: int, voltage_drive: float,
              saturated: bool) -> Measurement:
        """One sample as the vectorised path's Measurement (1-element arrays); counts wrapped to int32 as
        the counter does, the angles from the unwrapped counts, as SensorModel._encoder's."""
        rad_per_count, load_scale, load_count = self._rad_per_count, self._load_torque_scale, self._load_count
        current_drive, load_1, load_2, tacho_drive, tacho_load_1, tacho_load_2 = converted
        # (1-element arrays: empty + item assignment is the cheapest way numpy makes them; a call
        # per array would cost as much again)
        # wrap_int32 (skipped inside the range: big-int arithmetic is not free)
        c_d = _empty(1, _int32)
        c_d[0] = count_drive if -2147483648 <= count_drive < 2147483648 else \
            (count_drive + 2147483648) % 4294967296 - 2147483648
        wrapped = count_load if -2147483648 <= count_load < 2147483648 else \
            (count_load + 2147483648) % 4294967296 - 2147483648
        c_l1 = _empty(1, _int32)
        c_l1[0] = wrapped
        c_l2 = _empty(1, _int32)
        c_l2[0] = wrapped
        status = _empty(1, _uint32)
        status[0] = (STATUS_DRIVE_LIMIT if saturated else 0) | STATUS_SIMULATED
        i_d = _empty(1)
        i_d[0] = current_drive
        i_l1 = _empty(1)
        i_l1[0] = load_1
        i_l2 = _empty(1)
        i_l2[0] = load_2
        w_d = _empty(1)
        w_d[0] = tacho_drive
        w_l1 = _empty(1)
        w_l1[0] = tacho_load_1
        w_l2 = _empty(1)
        w_l2[0] = tacho_load_2
        w_g = _empty(1)
        w_g[0] = 0.5 * (tacho_load_1 + tacho_load_2)
        th_w = _empty(1)
        th_w[0] = count_drive * rad_per_count
        th_g = _empty(1)
        th_g[0] = count_load * rad_per_count
        volts = _empty(1)
        volts[0] = voltage_drive
        tau = _empty(1)
        tau[0] = load_scale * (load_1 + load_2) * load_count / 2.0
        # (positional, in the field order: keywords cost a dataclass 3x as much)
        return Measurement(i_d, i_l1, i_l2, w_d, w_g, th_w, th_g, c_d, c_l1, c_l2, volts, tau, status, w_l1, w_l2)
