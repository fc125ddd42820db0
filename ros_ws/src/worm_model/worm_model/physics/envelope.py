"""What a rig can physically do, from its rig file: a measured value far outside it is named with its
place, not folded into a metric.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Final

#: a measured value beyond MARGIN times what the rig file says the rig can do is refused as implausible
MARGIN: Final = 2.0
#: largest unwrapped angle accepted [rad]
MAX_ANGLE: Final = 1e12


@dataclass(frozen=True)
class Envelope:
    """Largest magnitude of each rig-data channel the rig can produce, from its rig file, times MARGIN.

    ``omega_worm``: no-load speed at the supply voltage, V/K_e [rad/s]; ``current_drive``: stall current
    V/R [A]; ``tau_load``: what the load motors make at stall, count K_t V/R [N m]; ``current_load``:
    their summed stall current [A]; ``voltage_drive``: the supply [V]; ``temperature`` [degC]: -60..250;
    unwrapped angles [rad]: MAX_ANGLE (the no-load speed for some 80 years). Times are only required
    to be finite.
    """

    limits: dict[str, tuple[float, str]]
    rig_name: str = ""

    @classmethod
    def of(cls, rig: Any, margin: float = MARGIN) -> "Envelope":
        v, d, load = rig.supply_voltage, rig.drive_motor, rig.load_motor
        return cls({
            "omega_worm": (margin * v / d.back_emf_constant, "rad/s"),
            "omega_gear": (margin * v / d.back_emf_constant * rig.gearbox.ratio, "rad/s"),
            "current_drive": (margin * v / d.resistance, "A"),
            "tau_load": (margin * rig.load_motor_count * load.torque_constant * v / load.resistance, "N m"),
            "current_load": (margin * rig.load_motor_count * v / load.resistance, "A"),
            "voltage_drive": (margin * v, "V"),
            "temperature": (250.0, "degC"),
            "theta_worm": (MAX_ANGLE, "rad"),
            "theta_gear": (MAX_ANGLE, "rad"),
        }, getattr(rig, "name", ""))

    def problem(self, column: str, value: float) -> str | None:
        """Why ``value`` of ``column`` is implausible, or None (NaN passes: a missing optional value)."""
        if column not in self.limits or math.isnan(value):
            return None
        limit, unit = self.limits[column]
        if column == "temperature":
            if -60.0 <= value <= limit:
                return None
            return f"{value:g} {unit} is outside -60..{limit:g} {unit}"
        if math.isfinite(value) and abs(value) <= limit:
            return None
        rig = f"rig '{self.rig_name}'" if self.rig_name else "the rig"
        return (f"{value:g} {unit} is far outside what {rig} can do (|value| <= {limit:.4g} {unit}, "
                f"{MARGIN:g} x its rig-file limit)")

    def first_outside(self, column: str, values: Any) -> int | None:
        """Index of the first implausible value of a column (an array), or None."""
        import numpy as np

        if column not in self.limits:
            return None
        arr = np.asarray(values, dtype=float)
        limit = self.limits[column][0]
        if column == "temperature":
            bad = (arr < -60.0) | (arr > limit)
        else:
            with np.errstate(invalid="ignore"):
                bad = ~np.isnan(arr) & ~(np.abs(arr) <= limit)
        hits = np.flatnonzero(bad)
        return int(hits[0]) if hits.size else None
