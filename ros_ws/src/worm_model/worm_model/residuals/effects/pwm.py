"""The PWM regressor: the current ripple the ADC samples at a phase fixed by the firmware's timing."""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from worm_model.effects import VOCABULARY
from worm_model.effects.vocabulary import PWM_FREQUENCY
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects.base import Coefficient, GridParameter, _Base, regresses
from worm_model.residuals.model import Signals, evaluate


#: [s] from the firmware's sample tick to the instant the ADC holds the drive current: the drive current is
#: the first conversion of the tick's sequence (firmware/adc_mux.c: step 0 = current of motor 0), held 1.5
#: ADC clocks after its start, ADC clock 16 MHz / 128 (adc_mux_init's prescaler): 1.5 x 8 us = 12 us
#: (worm_rig_driver sim/sensors.py AdcChain.sample_times()["current_drive"], the instant the simulator
#: samples the current at and hands to its pwm effect as channel_time).
CURRENT_HOLD_DELAY = 1.5 * 128 / 16e6


def firmware_sampling_phase(frequency: float = PWM_FREQUENCY, sample_rate: float = 1000.0) -> float | None:
    """PWM phase [periods, 0..1) at which the firmware's ADC samples the drive current; None if it walks.

    The 1 kHz tick (timer 0: 16 MHz / 64 / 250) and the PWM (timers 4/5: 16 MHz / 800) run from the same
    crystal, so a tick is exactly ``frequency / sample_rate`` = 20 PWM periods and every sample falls at the
    same phase, ``CURRENT_HOLD_DELAY x frequency`` = 12 us / 50 us = 0.24 in the simulator (its PWM and its
    ticks both start at t = 0, no interrupt latency).  On the real board the offset between timer 0 and
    timers 4/5 (started one after the other at boot) and the tick ISR's latency move it: hence a grid
    parameter of :class:`Pwm`, fitted from the data.  A frequency that is not a whole multiple of the sample
    rate makes the phase walk from sample to sample (None): the ripple then averages out and is noise.
    """
    periods = frequency / sample_rate
    if abs(periods - round(periods)) > 1e-9 * max(periods, 1.0):
        return None
    return (CURRENT_HOLD_DELAY * frequency) % 1.0


def sampled_ripple(duty: FloatArray, phase: float) -> FloatArray:
    """The PWM ripple the ADC samples at ``phase`` [periods], per unit of V_s / (L f) [1], as a function of duty d.

    Sign-magnitude PWM: the armature current rises for d / f and falls for (1 - d) / f, a triangle of
    peak to peak V_s d (1 - d) / (L f) about its mean (L f >> R).  Sampled at phase p of the period
    (switch-on at p = 0) the deviation from the mean is d (1 - d) x shape, shape = -1/2 + p/d while p < d
    (rising), 1/2 - (p - d)/(1 - d) after (falling) -- the simulator's pwm effect.  Multiplied out, without
    a division at d = 0 or 1 (where the ripple vanishes):

        d (1 - d) shape = p (1 - d) - d (1 - d) / 2 - max(p - d, 0)

    (for the current in the direction of the voltage; the caller applies sign(V)).  ``duty`` is clipped to [0, 1].
    """
    d = np.clip(duty, 0.0, 1.0)
    return phase * (1.0 - d) - 0.5 * d * (1.0 - d) - np.maximum(phase - d, 0.0)


@regresses
class Pwm(_Base):
    """Simulator ``pwm``: the PWM current ripple, sampled by the ADC at a phase fixed by the firmware's timing.

    The plant (and the declared model) carry the mean armature current; the ADC samples the
    triangular PWM ripple on top of it (:func:`sampled_ripple`), attenuated by the Hall sensor's
    first-order filter.  Because a sample period is a whole number of PWM periods the sampling phase
    p is the same on every sample, so what is left in the current is not noise but a *bias* that
    depends on the operating point through the duty d = |V| / V_s:

        current += sign(V) x amplitude x sampled_ripple(d, p)                       [A]
        amplitude = V_s / (L f) / sqrt(1 + (f / f_c)^2)                             [A]

    f the PWM frequency (:data:`PWM_FREQUENCY`), L the drive motor's inductance, V_s the supply,
    f_c the current sensor filter's cut-off.  V [V] is the drive voltage the model implies at steady
    state, V = R i_true + K_e omega_worm (Eq. 29 without L di/dt, which the 1 kHz means do not
    resolve): i_true from the declared model (model.evaluate), i.e. without the other effects'
    channels (their few tens of mA move d by ~R x 0.03 / 24 ~ 0.2 %), and the measured current is
    not used, so the regressor is free of the current noise.  The analysis caches the shapes with
    the first rig it screens them on (its refit of the declared model): later corrections of a few
    % move d by less than the phase grid's step.  Signs: V and the current + drive
    + rotation (model.py); the bias has the sign of V (the ripple triangle is the same in either
    direction of the bridge).

    Parameters: ``amplitude`` [A], linear; ``phase`` [periods, 0..1) on a grid of ``phases`` steps
    (1/50 = 1 us: the simulator's 0.24 lies on it).  The grid values also carry ``frequency`` [Hz]
    and ``full_ripple`` = V_s / (L f) [A], the rig's unfiltered ripple scale, so that
    :meth:`simulator_entry` (which gets no rig) can turn the amplitude into a filter cut-off.

    Translation: the simulator's entry has ``frequency``, ``duty_levels`` and ``filter_cutoff``, and
    no phase: its phase is fixed by the (simulated) firmware's timing (:func:`firmware_sampling_phase`).
    So :meth:`from_simulator_entry` takes the phase from that timing, and :meth:`simulator_entry`
    writes the fitted amplitude as a filter cut-off and loses the fitted phase (on the real board it
    may differ from the simulator's).  ``duty_levels`` (the duty resolution) is left to the
    simulator's default: a duty step of V_s / 800 moves the speed, not the steady current.  Much of
    the bias's constant and linear part, p (1 - d) sign(V) = p sign(V) - p V / V_s, is the same
    function of the data as the refitted Coulomb drag, viscous drag and K_t; its d (1 - d) and hinge
    max(p - d, 0) terms are what the analysis sees.
    """

    name = "pwm"
    description = ("PWM current ripple sampled at a fixed phase of the PWM period: a bias "
                   "sign(V) A [p (1 - d) - d (1 - d)/2 - max(p - d, 0)] at duty d = |R i + K_e omega| / V_s")
    frequency: ClassVar[float] = PWM_FREQUENCY
    phases: ClassVar[int] = 50
    #: the declared default filter cut-off [Hz]
    filter_cutoff: ClassVar[float] = VOCABULARY["pwm"].default("filter_cutoff")
    #: cut-off [Hz] written for an amplitude at or beyond the unfiltered ripple (the simulator's largest plausible Hz)
    max_filter_cutoff: ClassVar[float] = 1e5
    #: cut-off [Hz] written for an amplitude <= 0, which the simulator cannot make: no ripple to speak of
    min_filter_cutoff: ClassVar[float] = 1e-3
    parameters = (Coefficient("amplitude", "A", "V_s / (L f) x the current sensor filter's attenuation"),)
    grid_parameters = (GridParameter("phase", "1", "PWM phase of the drive current's ADC sampling instant "
                                                  "[periods, 0 = switch-on]"),)

    def full_ripple(self, rig: Rig, frequency: float | None = None) -> float:
        """V_s / (L f) [A]: four times the largest peak-to-peak ripple (at d = 1/2), before the sensor's filter."""
        return rig.supply_voltage / (rig.drive_motor.inductance * (frequency or self.frequency))

    def drive_voltage(self, rig: Rig, signals: Signals) -> FloatArray:
        """V = R i_true + K_e omega_worm [V] by the declared model at steady state (class docstring)."""
        m = rig.drive_motor
        v = m.resistance * evaluate(rig, signals).current_true + m.back_emf_constant * signals.omega
        return np.where(np.isfinite(v), v, 0.0)  # a sample the model cannot evaluate gets no ripple

    def duty(self, rig: Rig, signals: Signals) -> FloatArray:
        """|V| / V_s [1], clipped to [0, 1] (beyond it the bridge is saturated: no ripple)."""
        return np.clip(np.abs(self.drive_voltage(rig, signals)) / rig.supply_voltage, 0.0, 1.0)

    def grid(self, rig, signals):
        full = self.full_ripple(rig)
        return [{"phase": k / self.phases, "frequency": self.frequency, "full_ripple": full}
                for k in range(self.phases)]

    def unavailable(self, rig, signals):
        if firmware_sampling_phase(self.frequency, rig.sensors.sample_rate_hz) is None:
            return (f"the PWM ({self.frequency:g} Hz) is not a whole multiple of the sample rate "
                    f"({rig.sensors.sample_rate_hz:g} Hz): the sampling phase walks and the ripple averages out")
        return None

    def shapes(self, rig, signals, grid):
        v = self.drive_voltage(rig, signals)
        d = np.clip(np.abs(v) / rig.supply_voltage, 0.0, 1.0)
        return {"current": (np.sign(v) * sampled_ripple(d, grid["phase"]))[:, None]}

    def signature(self, rig, signals, grid):
        return "modelled duty |R i + K_e omega| / V_s [1]", self.duty(rig, signals)

    def simulator_entry(self, values, grid):
        # amplitude = full / sqrt(1 + (f / f_c)^2)  ->  f_c = f a / sqrt(1 - a^2), a = amplitude / full
        f = float(grid.get("frequency", self.frequency))
        a = float(values["amplitude"]) / float(grid["full_ripple"])
        if a <= 0.0:
            cutoff = self.min_filter_cutoff
        elif a >= 1.0:
            cutoff = self.max_filter_cutoff
        else:
            cutoff = min(max(f * a / math.sqrt(1.0 - a * a), self.min_filter_cutoff), self.max_filter_cutoff)
        return {"frequency": f, "filter_cutoff": cutoff}

    def from_simulator_entry(self, entry, rig):
        f = float(entry.get("frequency", self.frequency))
        cutoff = float(entry.get("filter_cutoff", self.filter_cutoff))
        full = self.full_ripple(rig, f)
        phase = firmware_sampling_phase(f, rig.sensors.sample_rate_hz)
        # a walking sampling phase (f not a multiple of the sample rate) leaves no bias: amplitude 0
        amplitude = 0.0 if phase is None else full / math.sqrt(1.0 + (f / cutoff) ** 2)
        return {"amplitude": amplitude}, {"phase": 0.0 if phase is None else phase, "frequency": f,
                                          "full_ripple": full}
