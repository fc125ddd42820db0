"""The momentum observer's state, and its motion over one sample period with the measured current as the input.

State x = [θ, ω, τ_d, a, b]: worm angle [rad], worm speed [rad/s] (the generalised momentum is
p = J_eff·ω), load torque on the gear shaft [N·m] (positive opposing positive worm rotation), and the
tacho's commutator ripple (a, b [1]; tacho = ω·(1 + a·sin pθ + b·cos pθ), identified when there is
an encoder angle to phase it by, as the load observer does).

With the drive motor rigidly on the worm (physics.md §7, Eq. 30) and the current measured, the
momentum balance of Eq. 28 is linear in ω once the mesh term is held over the period:

    dθ/dt = ω
    J_eff dω/dt = K_t i − b ω − T_dist(ω, τ_d)        (Eqs 28 + 30; T_dist: static_map, per flank)

The current enters as its mean over the period (the trapezoid of the two samples that bound it: no
voltage, so nothing says how it moved between them) and T_dist at the filtered state at the period's
start. Exactly integrated with u = (K_t ī − T_dist)/J_eff held and β = b/J_eff:

    ω⁺ = e·ω + a₁·u,   θ⁺ = θ + a₁·ω + a₂·u,   e = exp(−β T),  a₁ = (1 − e)/β,  a₂ = (T − a₁)/β

(a₁ → T, a₂ → T²/2 without viscous drag). τ_d enters through u with the slope ∂T_dist/∂τ_d = (r_w/r_g)·K_s.
Closed form: no matrix exponential, so no cache of discretisations.

Units SI. No ROS; numpy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from torque_estimator.estimation.observer.noise import NoiseFigures

#: Index of each state in MomentumObserver.x.
THETA, OMEGA, TAU, RIPPLE_SIN, RIPPLE_COS = range(5)
N_STATES = 5

#: below this β·T [1] the series of a₁, a₂ replaces the closed form (its cancellation costs digits)
_SERIES = 1e-6


@dataclass(frozen=True)
class Period:
    """The closed-form motion of the module docstring over ``period`` [s] for one inertia [kg m²].

    Attributes:
        decay: e [1]; a1 [s]: ω's and θ's gain on u per unit held acceleration; a2 [s²]: θ's.
        inertia: J_eff [kg m²] it was made for.
    """

    decay: float
    a1: float
    a2: float
    inertia: float

    @classmethod
    def of(cls, inertia: float, viscous: float, period: float) -> "Period":
        """The period for J_eff = ``inertia`` [kg m²] and viscous drag b = ``viscous`` [N m s/rad]."""
        beta = viscous / inertia
        if beta * period < _SERIES:
            return cls(1.0 - beta * period, period, 0.5 * period * period, inertia)
        a1 = -math.expm1(-beta * period) / beta
        return cls(math.exp(-beta * period), a1, (period - a1) / beta, inertia)

    def mean(self, theta: float, omega: float, torque: float) -> tuple[float, float]:
        """(θ⁺, ω⁺) from (θ, ω) with the net worm torque K_t ī − T_dist = ``torque`` [N m] held."""
        u = torque / self.inertia
        return theta + self.a1 * omega + self.a2 * u, self.decay * omega + self.a1 * u

    def transition(self, slope: float) -> np.ndarray:
        """The period's Jacobian over the state (5×5): τ_d acts as the torque −slope·τ_d."""
        phi = np.eye(N_STATES)
        phi[THETA, OMEGA] = self.a1
        phi[OMEGA, OMEGA] = self.decay
        phi[THETA, TAU] = -slope * self.a2 / self.inertia
        phi[OMEGA, TAU] = -slope * self.a1 / self.inertia
        return phi

    def current_gain(self, torque_constant: float) -> np.ndarray:
        """(5,) the state's change per ampere of mean current over the period."""
        g = np.zeros(N_STATES)
        g[THETA] = torque_constant * self.a2 / self.inertia
        g[OMEGA] = torque_constant * self.a1 / self.inertia
        return g


def load_variance(bandwidth: float, noise: "NoiseFigures", torque_constant: float, inertia: float, slope: float,
                  ratio: float, period: float) -> float:
    """Variance [(N m)²] of τ_d's random walk over one period that puts the steady filter's slowest pole at
    λ = 2π·``bandwidth`` [Hz] (the momentum observer's ``bandwidth`` option).

    The continuous filter of the momentum p = J_eff ω and the worm-side disturbance d (ṗ = K_t i − d, the
    current's noise a torque noise of intensity Q = K_t² σ_i² T; ḋ a random walk of intensity q; p measured
    by the tacho with R = J_eff² σ_t² T) has the error poles s² + B s + ω₀² with ω₀² = √(q/R) and
    B = √(c + 2ω₀²), c = Q/R = (K_t σ_i / J_eff σ_t)² (solving its Riccati equation by hand). Without the
    current's noise it is the Butterworth ω₀ = (q/R)^(1/4); with it (c = 2.2e4 s⁻² on the bundled rig) a
    small q gives two real poles, the slow one far below ω₀. So:

    * λ² <= c/2: the poles λ and √(c − λ²) >= λ, for q = λ²(c − λ²)·R;
    * above: ω₀ = λ (q = λ⁴ R), damping >= 1/√2.

    On the gear side τ_d = d / slope: the variance per period is q·T / slope², with |slope| floored at a tenth
    of the frictionless mesh's (the ratio i) so a flank that barely carries the load (K_− near 0 at the
    self-locking limit) does not let τ_d run. The encoder, when there is one, adds information the
    relation leaves out: the filter is then somewhat faster.
    """
    lam = 2.0 * math.pi * bandwidth
    r = inertia * inertia * noise.tacho_var * period
    c = (torque_constant * torque_constant * noise.current_var) / (inertia * inertia * noise.tacho_var)
    q = lam * lam * (c - lam * lam) * r if lam * lam <= 0.5 * c else lam ** 4 * r
    floor = 0.1 * ratio
    return q * period / max(slope * slope, floor * floor)


__all__ = ["N_STATES", "OMEGA", "Period", "RIPPLE_COS", "RIPPLE_SIN", "TAU", "THETA", "load_variance"]
