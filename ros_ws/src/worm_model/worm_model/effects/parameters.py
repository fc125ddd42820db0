"""An effect's parameters: how each is declared (default, unit, meaning, range check), the units an effects
file may write them in, and the check of one value.

Every parameter has one unit (``Parameter.unit``, one of the right-hand units of :data:`UNITS`); a file may
give it in any unit of the same kind (``{value: 15, unit: arcmin}`` for a ``rad``), converted here.  A
value is refused when it fails its declared check (:data:`CHECKS`) or is far beyond any bench rig
(:data:`PLAUSIBLE`): the message names the file and the key (:class:`worm_model.errors.EffectsError`).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from worm_model.errors import EffectsError
from worm_model.physics.parameters import finite_number

#: unit accepted in an effects file -> (factor to the parameter's unit, that unit)
UNITS: dict[str, tuple[float, str]] = {
    "N m": (1.0, "N m"), "mN m": (1e-3, "N m"),
    "rad": (1.0, "rad"), "deg": (math.pi / 180.0, "rad"), "arcmin": (math.pi / 10800.0, "rad"),
    "rad/s": (1.0, "rad/s"), "rpm": (math.pi / 30.0, "rad/s"),
    "m/s": (1.0, "m/s"),
    "A": (1.0, "A"), "mA": (1e-3, "A"),
    "s": (1.0, "s"), "min": (60.0, "s"),
    "h": (1.0, "h"),  # a gearbox's age (hours run): the aging effects
    "Hz": (1.0, "Hz"), "kHz": (1e3, "Hz"),
    "degC": (1.0, "degC"),
    "K/W": (1.0, "K/W"),
    "1/K": (1.0, "1/K"),
    "1": (1.0, "1"), "%": (0.01, "1"),
}

#: largest magnitude an effect parameter of each unit may have: far beyond what a bench rig like this one
#: shows (its motors make ~1 N m, turn at ~400 rad/s, draw ~10 A), so only typos and overflows are refused
PLAUSIBLE: dict[str, float] = {
    "N m": 100.0, "rad": 2 * math.pi, "rad/s": 1e4, "m/s": 100.0, "A": 100.0, "s": 1e6, "Hz": 1e5,
    "degC": 300.0, "K/W": 1e3, "1/K": 1.0, "h": 1e6, "1": 1e6,  # "1" holds counts too (PWM levels, orders)
}

#: range check name -> (predicate, message)
CHECKS: dict[str, tuple[Any, str]] = {
    "any": (lambda x: True, ""),
    "nonnegative": (lambda x: x >= 0.0, "must be >= 0"),
    "positive": (lambda x: x > 0.0, "must be > 0"),
    # a relative change or error: above +1000 % is a slip (a percentage written as a fraction, a unit), not a gearbox
    "relative": (lambda x: -1.0 < x <= 10.0, "must be > -1 and <= 10 (a relative change, -100 % .. +1000 %)"),
    "count": (lambda x: x >= 1 and float(x).is_integer(), "must be an integer >= 1"),
    "count0": (lambda x: x >= 0 and float(x).is_integer(), "must be an integer >= 0"),
}


@dataclass(frozen=True)
class Parameter:
    """Declaration of one effect parameter: default (in ``unit``), unit, meaning, range check."""

    default: float
    unit: str
    doc: str
    check: str = "any"


def parameter_value(raw: Any, declared: Parameter, origin: str, where: str) -> float:
    """A plain number (in the declared unit) or {value, unit[, note|source|assumption]}, checked."""
    if isinstance(raw, Mapping):
        unknown = set(raw) - {"value", "unit", "note", "source", "assumption"}
        if unknown or "value" not in raw:
            raise EffectsError(origin, where, "expected a number or a mapping {value, unit}"
                               + (f"; unknown keys {sorted(unknown)}" if unknown else ""))
        number = finite_number(raw["value"], origin, where, EffectsError)
        unit = str(raw.get("unit", declared.unit))
        if unit not in UNITS:
            raise EffectsError(origin, where, f"unknown unit {unit!r} (known: {', '.join(UNITS)})")
        factor, base = UNITS[unit]
        if base != declared.unit:
            raise EffectsError(origin, where, f"unit {unit!r} is not a {declared.unit!r}")
        number *= factor
    else:
        number = finite_number(raw, origin, where, EffectsError)
    predicate, message = CHECKS[declared.check]
    if not predicate(number):
        raise EffectsError(origin, where, f"value {number:g} {declared.unit}: {message}")
    limit = PLAUSIBLE[declared.unit]
    if abs(number) > limit:
        raise EffectsError(origin, where, f"value {number:g} {declared.unit} is far beyond any bench rig "
                                          f"(|value| <= {limit:g} {declared.unit})")
    return number


__all__ = ["CHECKS", "PLAUSIBLE", "UNITS", "Parameter", "parameter_value"]
