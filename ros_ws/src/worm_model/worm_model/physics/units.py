"""Units: the unit table of the rig parameter file, and the core's array type aliases.

Unit table: unit string -> (SI factor, dimension).

Every numeric leaf of a parameter file carries a ``unit``; the loader multiplies
the value by the factor below and checks that the dimension matches the one the
field declares (``worm_model.physics.parameters``).  Adding a unit is adding a row.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

_RPM = 2.0 * math.pi / 60.0  # rad/s per rev/min

#: unit -> (factor to SI, dimension name)
UNITS: dict[str, tuple[float, str]] = {
    # length
    "m": (1.0, "length"),
    "mm": (1e-3, "length"),
    # angle
    "rad": (1.0, "angle"),
    "deg": (math.pi / 180.0, "angle"),
    # moment of inertia
    "kg m^2": (1.0, "inertia"),
    "g cm^2": (1e-7, "inertia"),
    "kg cm^2": (1e-4, "inertia"),
    # electrical
    "ohm": (1.0, "resistance"),
    "H": (1.0, "inductance"),
    "mH": (1e-3, "inductance"),
    "A": (1.0, "current"),
    "mA": (1e-3, "current"),
    "V": (1.0, "voltage"),
    # torque and motor constants
    "N m": (1.0, "torque"),
    "mN m": (1e-3, "torque"),
    "N m/A": (1.0, "torque_constant"),
    "mN m/A": (1e-3, "torque_constant"),
    "V s/rad": (1.0, "back_emf_constant"),
    "V/krpm": (1.0 / (1000.0 * _RPM), "back_emf_constant"),
    "N m s/rad": (1.0, "viscous"),
    "mN m/krpm": (1e-3 / (1000.0 * _RPM), "viscous"),
    # speed and frequency
    "rad/s": (1.0, "angular_velocity"),
    "m/s": (1.0, "velocity"),
    "mm/s": (1e-3, "velocity"),
    "rpm": (_RPM, "angular_velocity"),
    "Hz": (1.0, "frequency"),
    # dimensionless
    "1": (1.0, "dimensionless"),
}

_ALIASES = {"·": " ", "*": " ", "Ω": "ohm", "²": "^2", "Ohm": "ohm"}


def normalize_unit(unit: str) -> str:
    """Canonical spelling of a unit string ('N·m' -> 'N m', 'kg·m²' -> 'kg m^2')."""
    text = str(unit)
    for old, new in _ALIASES.items():
        text = text.replace(old, new)
    return " ".join(text.split())


def to_si(value: float, unit: str) -> tuple[float, str]:
    """Convert ``value`` given in ``unit`` to SI.

    Returns:
        (value in SI, dimension name).

    Raises:
        KeyError: the unit is not in :data:`UNITS`.
    """
    factor, dimension = UNITS[normalize_unit(unit)]
    return value * factor, dimension


# Array aliases shared by the numpy core: every function takes scalars or arrays
# (broadcast together) and returns arrays (0-d for scalar input).
FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int8]
BoolArray = NDArray[np.bool_]
