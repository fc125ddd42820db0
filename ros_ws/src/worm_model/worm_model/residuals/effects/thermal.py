"""The oil-temperature regressor: mu scaled by the oil's warming, measured or modelled (family "thermal")."""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from worm_model.effects import VOCABULARY
from worm_model.effects.heat import mesh_heat as heat_of_mesh
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects.base import Coefficient, GridParameter, _Base, regresses
from worm_model.residuals.model import ModelState, Signals, evaluate


def first_order_lag(t: FloatArray, x: FloatArray, run: np.ndarray, time_constant: float) -> FloatArray:
    """y' = (x - y) / time_constant with y = 0 at the start of every run: the oil law's closed form over a run.

    Discretised exactly for x held over each (median) sample period of the run, as one linear filter.
    The same law as worm_model.effects.oil, which the simulator steps sample by sample with the heat of
    its own plant; the analysis keeps this form of its own (a filter over a whole run, fed by the heat
    the *declared* model computes) so that what it fits is never the simulator's own arithmetic: a case
    passes because the analysis found the effect, not because both sides ran one function.
    """
    # imported at first use: scipy.signal takes ~0.4 s to import, paid at start by every executable
    from scipy.signal import lfilter

    y = np.zeros(len(x))
    for r in np.unique(run):
        idx = np.flatnonzero(run == r)
        period = float(np.median(np.diff(t[idx]))) if len(idx) > 1 else 0.0
        decay = math.exp(-period / time_constant) if time_constant > 0 else 0.0
        y[idx] = lfilter([1.0 - decay], [1.0, -decay], x[idx])
    return y


def mesh_heat(rig: Rig, signals: Signals, state: ModelState | None = None) -> FloatArray:
    """Friction power in the mesh [W] by the declared model (worm_model.effects.heat), >= 0.

    Power in from the worm, (r_w/r_g) K_s G at |omega|, less power out to the gear, G at i |omega|
    (frame of motion, inertia included in G).
    """
    st = state if state is not None else evaluate(rig, signals)
    gb = rig.gearbox
    speed = np.abs(signals.omega)
    return heat_of_mesh(st.mesh_demand * (gb.radius_ratio * st.flank_factor), speed, st.mesh_demand, gb.ratio * speed)


@regresses
class OilTemperature(_Base):
    """The oil law (worm_model.effects.oil: C dT/dt = P - (T - T_amb)/R_th) scaling mu: mu *= 1 + mu_per_kelvin dT.

    Two ways to the oil temperature rise dT over the reference (the temperature at which
    the declared mu holds, Signals.reference_temperature):

    * measured (a ``temperature`` column, e.g. a sump sensor): dT = T - T_ref, gaps in the
      column interpolated in time; grid {time_constant: 0};
    * not measured: the oil law in closed form (:func:`first_order_lag`), driven by the mesh
      friction power the declared model computes, R_th P lagged by the time constant (searched
      on a grid), starting at T_ref at every run.  Only the product mu_per_kelvin R_th is
      identifiable: R_th is fixed at the declared default.
    """

    name = "oil_temperature"
    family = "thermal"
    description = ("oil temperature (measured, or a first-order thermal model of the mesh's friction power) "
                   "scaling mu: mu *= 1 + mu_per_kelvin (T - T_ref)")
    #: [K/W] the declared default R_th: only the product mu_per_kelvin R_th is identifiable
    thermal_resistance: ClassVar[float] = VOCABULARY["oil_temperature"].default("thermal_resistance")
    #: [s] the declared default, written when the temperature was measured
    default_time_constant: ClassVar[float] = VOCABULARY["oil_temperature"].default("time_constant")
    #: [degC] the declared default ambient, the reference temperature where the data does not say it
    ambient: ClassVar[float] = VOCABULARY["oil_temperature"].default("ambient")
    parameters = (Coefficient.of("oil_temperature", "mu_per_kelvin"),)
    grid_parameters = (GridParameter("time_constant", "s", "thermal time constant (0: measured temperature)"),)

    def grid(self, rig, signals):
        ref = {"reference_temperature": float(signals.reference_temperature)}
        if signals.temperature is not None:
            return [{"time_constant": 0.0, **ref}]
        span = float(np.max(np.bincount(signals.run, weights=np.gradient(signals.t)))) \
            if len(signals) > 1 else 1.0  # the longest run [s]
        return [{"time_constant": float(tc), **ref}
                for tc in np.geomspace(max(span / 30.0, 0.5), 10.0 * span, 12)]

    def unavailable(self, rig, signals):
        if signals.temperature is not None and not np.any(np.isfinite(signals.temperature)):
            return "the temperature column holds no value"
        return None

    def warming(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> FloatArray:
        """Oil temperature rise over the reference [K]: measured, or the first-order model of the mesh heat."""
        if signals.temperature is not None:
            temp = signals.temperature
            finite = np.isfinite(temp)
            if not finite.any():
                return np.zeros(len(temp))
            if not finite.all():  # a slow quantity: interpolate the holes in time
                temp = np.interp(signals.t, signals.t[finite], temp[finite])
            return temp - float(grid.get("reference_temperature", signals.reference_temperature))
        heat = mesh_heat(rig, signals)
        return self.thermal_resistance * first_order_lag(signals.t, heat, signals.run, grid["time_constant"])

    def shapes(self, rig, signals, grid):
        return {"mu_relative": self.warming(rig, signals, grid)[:, None]}

    def signature(self, rig, signals, grid):
        label = "measured oil temperature - reference [K]" if signals.temperature is not None \
            else "modelled oil warming [K]"
        return label, self.warming(rig, signals, grid)

    def simulator_entry(self, values, grid):
        ref = float(grid.get("reference_temperature", self.ambient))
        tc = float(grid["time_constant"])
        return {"mu_per_kelvin": float(values["mu_per_kelvin"]),
                "time_constant": tc if tc > 0 else self.default_time_constant,
                "thermal_resistance": self.thermal_resistance, "ambient": ref, "initial": ref}

    def from_simulator_entry(self, entry, rig):
        r_th = float(entry.get("thermal_resistance", self.thermal_resistance))
        return ({"mu_per_kelvin": float(entry.get("mu_per_kelvin", 0.0)) * r_th / self.thermal_resistance},
                {"time_constant": float(entry.get("time_constant", self.default_time_constant)),
                 "reference_temperature": float(entry.get("ambient", self.ambient))})
