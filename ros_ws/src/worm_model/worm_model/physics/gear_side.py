"""What the gear shaft carries besides the external load: the load motors' own drag.

The paper's rig has two PMDC load motors directly on the gear shaft; their
brushes and bearings drag (Coulomb + viscous, Eq. 29's b and friction), and
the mesh must carry that drag too. It is also why the rig has a non-zero
switching torque (physics.md section 5): with the drive motor's drags taken
out of the input torque, the normal force passes through zero where the
external load just cancels this drag.

Signs: fixed frame, positive opposing positive rotation (physics.md section 2);
omega_worm [rad/s] is the worm speed, the gear turns at ratio * omega_worm.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from worm_model.physics.motor import coulomb_friction, make_coulomb_friction_float
from worm_model.physics.parameters import Rig


def gear_side_drag(rig: Rig, omega_worm) -> np.ndarray:
    """Drag torque of the load motors on the gear shaft [N m], opposing the gear's motion: each one's viscous
    drag and its Coulomb drag with the low-speed rise (worm_model.physics.motor.coulomb_friction)."""
    load = rig.load_motor
    omega_gear = rig.gearbox.ratio * np.asarray(omega_worm, dtype=float)
    return rig.load_motor_count * (load.viscous_drag * omega_gear + coulomb_friction(load, omega_gear))


def make_gear_side_drag_float(rig: Rig) -> Callable[[float], float]:
    """:func:`gear_side_drag` at one float worm speed [rad/s], in plain math (per-sample loops): the same
    operations in the same order, so the same number (the rise's exp to round-off)."""
    count, ratio = rig.load_motor_count, rig.gearbox.ratio
    viscous = rig.load_motor.viscous_drag
    coulomb = make_coulomb_friction_float(rig.load_motor)

    def drag(omega_worm: float) -> float:
        omega_gear = ratio * omega_worm
        return count * (viscous * omega_gear + coulomb(omega_gear))

    return drag


def gear_side_load(rig: Rig, tau_load, omega_worm) -> np.ndarray:
    """Everything the mesh carries on the gear side [N m]: external load tau_load plus drag."""
    return np.asarray(tau_load, dtype=float) + gear_side_drag(rig, omega_worm)


def no_load_switching_torque(rig: Rig, omega_worm) -> np.ndarray:
    """Switching torque tau_sw >= 0 [N m] at this speed: the aiding load at which N = 0.

    Quasi-statically N = 0 means the mesh transmits nothing (Eqs 19-20 with
    N = F_f = 0 give T = 0 and D_mesh = 0), i.e. the external load exactly
    cancels the gear-side drag: tau_sw = |gear_side_drag|. It grows with speed
    through the viscous part, as the paper's Fig. 8 shows.
    """
    return np.abs(gear_side_drag(rig, omega_worm))
