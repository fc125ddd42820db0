"""What the sensors read: gain and offset errors of the current sensors and tachos, the PWM's ripple and resolution."""
from __future__ import annotations

import math

import numpy as np

from worm_rig_driver.sim.effects.hooks import simulates, EffectBase, SenseContext, _sign


@simulates
class SensorGain(EffectBase):
    """Gain errors of the Hall current sensors and tachogenerators: reading = (1 + gain) x true.

    Changes only the readings, never the plant. Residual signature: proportional to i (or omega).
    """

    name = "sensor_gain"

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        for key, gain in (("current_drive", "drive_current"), ("current_load_1", "load_current"),
                          ("current_load_2", "load_current"), ("tacho_drive", "drive_tacho"),
                          ("tacho_load_1", "load_tacho"), ("tacho_load_2", "load_tacho")):
            signals[key] = signals[key] * (1.0 + self.p[gain])

    sense_float = sense  # plain arithmetic: the same code serves floats


@simulates
class SensorOffset(EffectBase):
    """Zero offsets of the Hall current sensors and tachos: reading = true + offset.

    Changes only the readings, never the plant. Residual signature: a constant.
    """

    name = "sensor_offset"

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        for key, offset in (("current_drive", "drive_current"), ("current_load_1", "load_current"),
                            ("current_load_2", "load_current"), ("tacho_drive", "drive_tacho"),
                            ("tacho_load_1", "load_tacho"), ("tacho_load_2", "load_tacho")):
            signals[key] = signals[key] + self.p[offset]

    sense_float = sense  # plain arithmetic: the same code serves floats


@simulates
class Pwm(EffectBase):
    """The H-bridge's PWM: duty quantised to the timer's levels, and the armature current ripple.

    The plant integrates the average-duty voltage: the PWM period (50 us) is 16x
    shorter than L/R (0.8 ms), so the mean current obeys Eq. 29 with V = duty x
    supply. What the average hides is (1) the duty resolution of the timer and
    (2) the triangular current ripple, peak to peak V_s d (1 - d) / (L f_pwm) for
    sign-magnitude PWM, which the ADC sees at whatever phase it samples (the ADC
    and PWM timers are not synchronised), reduced by the Hall sensor's output filter.
    """

    name = "pwm"

    def drive_voltage(self, voltage: np.ndarray, supply: float) -> np.ndarray:
        levels = self.p["duty_levels"]
        if levels == 0:
            return voltage
        return np.round(voltage / supply * levels) / levels * supply

    def drive_voltage_float(self, voltage: float, supply: float) -> float:
        levels = self.p["duty_levels"]
        if levels == 0 or voltage != voltage:
            return voltage
        return round(voltage / supply * levels) / levels * supply  # (round: ties to even, as np.round)

    def sense(self, signals: dict[str, np.ndarray], context: SenseContext) -> None:
        f = self.p["frequency"]
        duty = np.clip(np.abs(context.voltage_drive) / context.supply_voltage, 0.0, 1.0)
        ripple_pp = context.supply_voltage * duty * (1.0 - duty) / (self.rig.drive_motor.inductance * f)
        attenuation = 1.0 / math.sqrt(1.0 + (f / self.p["filter_cutoff"]) ** 2)
        phase = (context.channel_time["current_drive"] * f) % 1.0
        rising = phase < duty  # switch on: the current rises for d/f, then falls
        with np.errstate(divide="ignore", invalid="ignore"):
            shape = np.where(rising, -0.5 + phase / duty, 0.5 - (phase - duty) / (1.0 - duty))
        shape = np.where((duty <= 0.0) | (duty >= 1.0), 0.0, shape)
        signals["current_drive"] = signals["current_drive"] + np.sign(context.voltage_drive) * attenuation \
            * ripple_pp * shape

    def sense_float(self, signals: dict[str, float], context: SenseContext) -> None:
        f = self.p["frequency"]
        duty = abs(context.voltage_drive) / context.supply_voltage
        duty = 0.0 if duty < 0.0 else (1.0 if duty > 1.0 else duty)
        if duty <= 0.0 or duty >= 1.0:
            return  # no ripple at 0 % or 100 % duty (signal + 0.0, as the array hook)
        ripple_pp = context.supply_voltage * duty * (1.0 - duty) / (self.rig.drive_motor.inductance * f)
        attenuation = 1.0 / math.sqrt(1.0 + (f / self.p["filter_cutoff"]) ** 2)
        phase = (context.channel_time["current_drive"] * f) % 1.0
        shape = -0.5 + phase / duty if phase < duty else 0.5 - (phase - duty) / (1.0 - duty)
        signals["current_drive"] = signals["current_drive"] + _sign(context.voltage_drive) * attenuation \
            * ripple_pp * shape
