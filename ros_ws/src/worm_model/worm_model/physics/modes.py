"""Frame of motion and engagement modes (physics reference sections 2-3, paper section 2.2).

Frame of motion: sigma = sign(omega_w) (for a worm at rest, the sign of the applied
torque); T = sigma tau_in, D = sigma tau_d, a_w = sigma alpha_w, a_g = sigma alpha_g.
D > 0 means the load opposes the motion.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.units import FloatArray, IntArray


class Mode(IntEnum):
    """Engagement mode (paper section 2.2)."""

    STANDSTILL = 0  # worm not moving (or inputs not finite): no kinetic classification
    RESISTIVE = 1  # D > 0, driving flank
    PSEUDO_RESISTIVE = 2  # -tau_sw <= D <= 0, still the driving flank
    ASSISTIVE = 3  # D < -tau_sw, coast flank


class Flank(IntEnum):
    """Engaged flank s of Eqs 19-20."""

    COAST = -1
    NONE = 0
    DRIVING = 1


def motion_sign(omega_worm: ArrayLike, tau_in: ArrayLike = 0.0, eps: float = 1e-9) -> FloatArray:
    """sigma, the sign of the frame of motion (section 2).

    sign(omega_worm) where |omega_worm| >= eps [rad/s]; otherwise the sign of tau_in
    [N m]; +1 if both are zero.  NaN where the deciding input is NaN.

    Returns:
        float array of +1.0 / -1.0 (NaN for NaN input), broadcast shape.
    """
    w = np.asarray(omega_worm, dtype=float)
    t = np.asarray(tau_in, dtype=float)
    at_rest_sign = np.where(np.isnan(t), np.nan, np.where(t < 0.0, -1.0, 1.0))
    return np.where(np.isnan(w), np.nan, np.where(np.abs(w) >= eps, np.sign(w), at_rest_sign))


def classify_mode(D: ArrayLike, switching_torque: ArrayLike = 0.0) -> IntArray:
    """Mode from the load torque in the frame of motion (section 3).

    Args:
        D: sigma * tau_d [N m], > 0 opposes the motion.
        switching_torque: tau_sw >= 0 [N m] (section 5); 0 in the pure model.
    Returns:
        int8 array of :class:`Mode`: RESISTIVE for D > 0, PSEUDO_RESISTIVE for
        -tau_sw <= D <= 0, ASSISTIVE for D < -tau_sw, STANDSTILL for NaN D.
    """
    d = np.asarray(D, dtype=float)
    tsw = np.asarray(switching_torque, dtype=float)
    # nested where on plain ints: same first-match rule as np.select, several times faster
    # per live sample (np.select with IntEnum choices dominated model_node's callback)
    mode = np.where(d > 0.0, _RESISTIVE,
                    np.where(d >= -tsw, _PSEUDO_RESISTIVE, np.where(d < -tsw, _ASSISTIVE, _STANDSTILL)))
    return np.asarray(mode, dtype=np.int8)


_RESISTIVE, _PSEUDO_RESISTIVE = int(Mode.RESISTIVE), int(Mode.PSEUDO_RESISTIVE)
_ASSISTIVE, _STANDSTILL = int(Mode.ASSISTIVE), int(Mode.STANDSTILL)
