"""The oil temperature of a drive without a sensor: the model's oil law fed by the drive's own losses.

    C dT/dt = P - (T - T_amb) / R_th,     tau = R_th C                        (T [degC], P [W])

(worm_model.effects.oil, the law the simulator's oil steps too). P is the heat made in the gearbox, estimated
from the drive's signals and the health model (worm_model.health.model): the mesh's loss at the measured speed
and load, plus the shares of the shaft drags that heat the oil (settings.Thermal). The estimate is T_amb +
offset + rise, integrated exactly for P held over each step:

    offset <- offset e^(-dt/tau)                  (the start's distance from ambient, decaying)
    rise   <- R_th P + (rise - R_th P) e^(-dt/tau)

Its standard uncertainty combines what the model cannot know, each term as it propagates. From a
cold start (the oil at the hall's temperature, assumed ``ambient``):

    sigma_T^2 = sigma_amb^2 + (sigma_0 e^(-t/tau))^2 + (sigma_P rise)^2

sigma_amb: the hall's own uncertainty (the start and the steady state share it); sigma_0: how far
the oil may be from the hall at the start (a cold night), decaying; sigma_P: the heat's and R_th's
relative uncertainty, together (settings.Thermal). From a known temperature T_0 (+- s_0) instead,
(s_0 e^(-t/tau))^2 + (sigma_amb (1 - e^(-t/tau)))^2 + (sigma_P rise)^2. What this costs a health
monitor is k sigma_T of mu's scale (model.TemperatureLaw): the price of no sensor.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from worm_model.effects import oil
from worm_model.health.settings import Thermal


@dataclass
class ThermalEstimate:
    """The running estimate (module docstring). Start it with :meth:`start`, feed it with :meth:`step`."""

    settings: Thermal
    offset: float = 0.0  # [K] start's distance from ambient, decaying
    rise: float = 0.0  # [K] self-heating
    decay: float = 1.0  # e^(-t/tau) since the start
    time: float = 0.0  # [s] since the start
    initial_sigma: float = math.nan  # [K] s_0 of a known start (NaN: a cold start)

    @classmethod
    def start(cls, settings: Thermal, temperature: float | None = None,
              sigma: float | None = None) -> "ThermalEstimate":
        """An estimate from now: the oil at ``temperature`` [degC] known to ``sigma`` [K]; None: a cold start (the
        oil at the assumed ambient)."""
        if temperature is None:
            return cls(settings)
        return cls(settings, offset=temperature - settings.ambient, initial_sigma=0.0 if sigma is None else sigma)

    def step(self, dt: float, power: float) -> None:
        """Advance by dt [s] with ``power`` [W] of heat held (NaN or < 0 counts as 0)."""
        if not dt > 0.0:
            return
        s = self.settings
        e = oil.decay(dt, s.time_constant)
        steady = oil.steady_temperature(0.0, power if power > 0.0 else 0.0, s.thermal_resistance)
        self.offset *= e
        self.rise = oil.relax(self.rise, steady, e)
        self.decay *= e
        self.time += dt

    def settle(self, power: float, duration: float) -> None:
        """Advance by ``duration`` [s] at a constant ``power`` [W] in one exact step."""
        self.step(duration, power)

    @property
    def temperature(self) -> float:
        """The estimated oil temperature [degC]."""
        return self.settings.ambient + self.offset + self.rise

    @property
    def sigma(self) -> float:
        """Its standard uncertainty [K] (module docstring)."""
        s = self.settings
        if math.isnan(self.initial_sigma):  # cold start: the hall's error throughout, the night's decaying
            return math.sqrt(s.ambient_sigma ** 2 + (s.initial_sigma * self.decay) ** 2
                             + (s.power_sigma * self.rise) ** 2)
        return math.sqrt((self.initial_sigma * self.decay) ** 2 + (s.ambient_sigma * (1.0 - self.decay)) ** 2
                         + (s.power_sigma * self.rise) ** 2)


__all__ = ["ThermalEstimate"]
