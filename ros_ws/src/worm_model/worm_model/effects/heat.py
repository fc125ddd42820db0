"""The mesh heat the model owns: the power the worm mesh turns into heat.

    P_mesh = max(T_w omega_w - D omega_g, 0)                                               [W]

T_w [N m] the torque the worm delivers into the mesh (the motor's torque less what accelerates the worm,
+ along + worm rotation), omega_w [rad/s] the worm speed, D [N m] the torque the mesh delivers to the gear
side (load, gear-side drags and what accelerates the gear, + opposing + gear rotation), omega_g [rad/s] the
gear speed, worm-referenced (ratio x omega_w in contact). Power in at the worm less power out at the gear:
the friction force times the sliding speed, F_f V_s >= 0 (physics.md, Eqs 21-22); the clip keeps the
round-off of a loss-free instant from turning into cooling.

Who computes it: the simulator's plants (the truth: the oil's heat while the teeth touch), the residual
analysis (the heating proxy of its ``oil_temperature`` regressor) and the health model (the loss at a
steady point), each with its own torques; the float twin serves the simulator's scalar path.
"""
from __future__ import annotations

import numpy as np

from worm_model.physics.units import FloatArray


def mesh_heat(worm_torque: FloatArray, worm_speed: FloatArray, gear_torque: FloatArray,
              gear_speed: FloatArray) -> FloatArray:
    """P_mesh [W] >= 0 (module docstring), element by element."""
    return np.maximum(worm_torque * worm_speed - gear_torque * gear_speed, 0.0)


def mesh_heat_float(worm_torque: float, worm_speed: float, gear_torque: float, gear_speed: float) -> float:
    """:func:`mesh_heat` of plain floats, with the same floating-point operations."""
    return max(worm_torque * worm_speed - gear_torque * gear_speed, 0.0)  # (NaN kept, as np.maximum)


__all__ = ["mesh_heat", "mesh_heat_float"]
