"""The oil temperature law the model owns: a first-order thermal model of the gearbox's housing.

    C dT/dt = P - (T - T_amb) / R_th,     tau = R_th C                        (T [degC], P [W], R_th [K/W])

P is the heat made inside the gearbox (the mesh's friction power, worm_model.effects.heat, and the
shaft drags that heat the oil). For P held over a step dt [s] the law is integrated exactly:

    T <- T_ss + (T - T_ss) e^(-dt/tau),     T_ss = T_amb + R_th P

Its parameters and their defaults are the vocabulary's ``oil_temperature`` entry
(vocabulary.THERMAL_RESISTANCE: why 5 K/W). Who steps it: the simulator's ``oil_temperature`` effect
(the truth, sample by sample) and the health monitor's estimate of a drive without an oil sensor
(worm_model.health.thermal). The residual analysis fits its own closed form of the same law over a whole
run (worm_model.residuals.effects.thermal: a regressor, kept apart so that the analysis is judged on data
it did not make itself).
"""
from __future__ import annotations

import math

from worm_model.effects.vocabulary import THERMAL_RESISTANCE, THERMAL_TIME_CONSTANT
from worm_model.physics.units import FloatArray

#: one temperature or heat, or an array of them (one per rig or sample)
ArrayOrFloat = FloatArray | float


def decay(dt: float, time_constant: float) -> float:
    """e^(-dt/tau) [1]: what is left of a distance from the steady state after dt [s]."""
    return math.exp(-dt / time_constant)


def steady_temperature(ambient: ArrayOrFloat, heat: ArrayOrFloat,
                       thermal_resistance: float = THERMAL_RESISTANCE) -> ArrayOrFloat:
    """T_ss = T_amb + R_th P [degC]: where the oil settles under ``heat`` [W] held (ambient 0: the rise [K])."""
    return ambient + thermal_resistance * heat


def relax(temperature: ArrayOrFloat, steady: ArrayOrFloat, factor: float) -> ArrayOrFloat:
    """One exact step of the law: T_ss + (T - T_ss) x ``factor`` (:func:`decay` of the step) [degC or K]."""
    return steady + (temperature - steady) * factor


__all__ = ["THERMAL_RESISTANCE", "THERMAL_TIME_CONSTANT", "decay", "relax", "steady_temperature"]
