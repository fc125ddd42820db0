"""The observer's state, and the exact discretisation of its linear part over one sample period.

State x = [θ, ω, i, τ_d, a, b, δ]: worm angle [rad], speed [rad/s], armature current [A], load
torque [N·m] (the four of the model), the tacho's commutator ripple (a, b [1]) and the back-EMF
constant's relative error δ [1] (:class:`~torque_estimator.estimation.observer.kalman.LoadObserver`).

With the drive motor rigidly on the worm (Eq. 30), the motor and the inertia are linear:

    dθ/dt = ω
    J_eff dω/dt = K_t i − b ω − T_dist(ω, τ_d)                           (Eq. 28 + 30)
    L di/dt     = V − R i − K_e ω                                         (Eq. 29)

They are discretised exactly (zero-order hold on V and on T_dist over the period, matrix
exponential) for one J_eff (worm_model.physics.dynamics.effective_worm_inertia, Eq. 28: the
gear's reflected inertia depends on the flank and friction the load map uses); LoadObserver
caches one discretisation per J_eff bin. τ_d enters the period as the held torque −slope·τ_d
(slope = ∂T_dist/∂τ_d, static_map).

Units SI. No ROS; numpy + scipy.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from worm_model.physics.parameters import Rig

#: Index of each state in LoadObserver.x.
THETA, OMEGA, CURRENT, TAU, RIPPLE_SIN, RIPPLE_COS, BACK_EMF_ERROR = range(7)
N_STATES = 7

#: Measurement Jacobian of the 4-state model (θ, ω, i measured; τ_d not): the steady analysis (bounds).
H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0]])


@dataclass(frozen=True)
class Discretisation:
    """Exact ZOH discretisation of the linear part for one J_eff."""

    phi: np.ndarray  # (3, 3) on (θ, ω, i)
    gamma_v: np.ndarray  # (3,) per volt
    gamma_t: np.ndarray  # (3,) per N m of accelerating torque on the worm


def discretise(rig: Rig, inertia: float, period: float) -> Discretisation:
    """The motor (Eq. 29) and the worm's inertia J_eff = ``inertia`` [kg m²] over ``period`` [s]."""
    m = rig.drive_motor
    a = np.zeros((5, 5))
    a[0, 1] = 1.0
    a[1, 1], a[1, 2], a[1, 4] = -m.viscous_drag / inertia, m.torque_constant / inertia, 1.0 / inertia
    a[2, 1], a[2, 2], a[2, 3] = -m.back_emf_constant / m.inductance, -m.resistance / m.inductance, 1.0 / m.inductance
    e = scipy.linalg.expm(a * period)
    return Discretisation(e[:3, :3].copy(), e[:3, 3].copy(), e[:3, 4].copy())


def transition(d: Discretisation, slope: float) -> np.ndarray:
    """The 4×4 Jacobian of one period: τ_d enters as the torque −slope·τ_d held over the period."""
    phi = np.eye(4)
    phi[:3, :3] = d.phi
    phi[:3, 3] = -slope * d.gamma_t
    return phi


class Step:
    """One cached :class:`Discretisation` in the forms LoadObserver.update uses every sample.

    phi, gamma_v, gamma_t as nested lists of floats: the mean is propagated in float math
    (numpy's fixed cost per call is larger than this 3×3 arithmetic); ``transition``: the
    7×7 Jacobian of the period with the two columns that change every sample (τ_d: −slope·Γ_t,
    δ: −K_e ω̂·Γ_v) left at zero, copied and completed by LoadObserver._predict.
    """

    __slots__ = ("phi", "gamma_v", "gamma_t", "transition")

    def __init__(self, d: Discretisation) -> None:
        self.phi = d.phi.tolist()
        self.gamma_v = d.gamma_v.tolist()
        self.gamma_t = d.gamma_t.tolist()
        self.transition = np.eye(N_STATES)
        self.transition[:3, :3] = d.phi

    def mean(self, x: list[float], drive: float, torque: float) -> list[float]:
        """(θ, ω, i) after the step from x[:3]: Φ x + Γ_v·drive − Γ_t·torque (drive [V], torque [N m])."""
        x0, x1, x2 = x[0], x[1], x[2]
        return [p[0] * x0 + p[1] * x1 + p[2] * x2 + gv * drive - gt * torque
                for p, gv, gt in zip(self.phi, self.gamma_v, self.gamma_t)]


__all__ = ["BACK_EMF_ERROR", "CURRENT", "H", "N_STATES", "OMEGA", "RIPPLE_COS", "RIPPLE_SIN", "TAU", "THETA",
           "Discretisation", "Step", "discretise", "transition"]
