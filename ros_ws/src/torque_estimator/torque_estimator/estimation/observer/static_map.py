"""The observer's one nonlinearity: the worm-side disturbance T_dist(ω, τ_d) of Eq. 28 and its inverse.

T_dist is the lumped worm-side disturbance: everything K_t i − J_eff α − b ω does not explain.
From Eq. 28 in the frame of motion (σ = sign ω, +1 at 0):

    T_dist(ω, τ_d) = c·sign ω + σ·(r_w/r_g)·K_s(μ(ω))·D,   D = σ·(τ_d + τ_drag,g(ω)),
    s = +1 (driving flank) for D >= 0, −1 (coast) for D < 0,

with c the drive motor's Coulomb drag (with its low-speed rise, worm_model.physics.motor.coulomb_friction),
τ_drag,g the load motors' drag the gear shaft also
carries (worm_model.physics.gear_side: it sets the switching torque, so the pseudo-resistive
mode is D >= 0 with τ_d < 0), μ(ω) the rig's friction model (worm_model.physics.friction, AGMA,
speed dependent) and K_s the flank factor (worm_model.physics.efficiency: K_+ = tan(λ+ρ'),
K_− = tan(λ−ρ')). The second term is worm_model's quasi-static input torque of Eq. 28
(dynamics.reflected_input_torque) for the gear-side load τ_d + τ_drag,g; the inverse per flank is
dynamics.load_per_flank. T_dist is piecewise linear in τ_d with slope (r_w/r_g)·K_s; in a
self-locking box (K_− < 0, |ω| below ~5 rad/s on the NMRV030) it is V-shaped: two loads give the
same T_dist (AMBIGUOUS).

Units SI, fixed frame; τ_d [N·m] on the gear shaft, positive opposing positive worm rotation.
No ROS; numpy.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.dynamics import load_per_flank, make_reflected_input_torque_float
from worm_model.physics.efficiency import flank_factor
from worm_model.physics.friction import friction_coefficient, make_friction_coefficient_float
from worm_model.physics.gear_side import gear_side_drag, make_gear_side_drag_float
from worm_model.physics.motor import coulomb_friction, make_coulomb_friction_float
from worm_model.physics.parameters import Rig

from torque_estimator.estimation.base import EstimateFlags


class StaticLoadMap:
    """T_dist(ω, τ_d) of the module docstring and its inverse, from the rig's model (worm_model).

    The array methods take any shape; :meth:`mesh` and :meth:`worm_torque` take one (ω, τ_d)
    and run in float math on worm_model's float twins of μ(ω), the gear-side drag and Eq. 28's
    input torque: the streaming observer calls them per sample, where numpy on one value costs
    ~5 us a call.
    """

    def __init__(self, rig: Rig) -> None:
        self.rig = rig
        gb = rig.gearbox
        self.k = gb.radius_ratio
        self._coulomb_float = make_coulomb_friction_float(rig.drive_motor)  # c(ω) sign ω, one float
        self.self_locking_mu = gb.self_locking_mu
        self._mu_float = make_friction_coefficient_float(rig.friction, gb)  # μ(ω), one float
        self._drag_float = make_gear_side_drag_float(rig)  # τ_drag,g(ω), one float
        self._input_torque_float = make_reflected_input_torque_float(gb)  # Eq. 28 at α = 0, one float

    @property
    def self_locks_at_rest(self) -> bool:
        """Whether the mesh's friction at zero sliding speed exceeds the self-locking limit: then a standing worm
        holds the load by friction alone and its current says nothing of it (the observers' STANDSTILL hold)."""
        return float(self.mu(0.0)) > self.self_locking_mu

    def mu(self, omega: ArrayLike) -> np.ndarray:
        return np.asarray(friction_coefficient(self.rig.friction, self.rig.gearbox, omega), dtype=float)

    def gear_drag(self, omega: ArrayLike) -> np.ndarray:
        """Load motors' drag on the gear shaft [N m] (worm_model.physics.gear_side.gear_side_drag)."""
        return gear_side_drag(self.rig, omega)

    def factors(self, omega: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(K_+, K_−) at ω."""
        mu = self.mu(omega)
        return (np.asarray(flank_factor(self.rig.gearbox, mu, 1.0)),
                np.asarray(flank_factor(self.rig.gearbox, mu, -1.0)))

    def mesh(self, omega: float, tau_d: float) -> tuple[float, float, int, float, float]:
        """(T_dist [N m], ∂T_dist/∂τ_d [1], flank s, K_s [1], μ [1]) at one (ω, τ_d), in float math.

        worm_model's float twins do the operations of the array functions in the same order, so
        the same numbers up to the friction law's last bit (make_friction_coefficient_float).
        """
        mu = self._mu_float(omega)
        torque, factor, flank = self._input_torque_float(mu, tau_d + self._drag_float(omega), omega)
        return self._coulomb_float(omega) + torque, self.k * factor, flank, factor, mu

    def worm_torque(self, omega: float, tau_d: float) -> tuple[float, float, int]:
        """(T_dist [N m], ∂T_dist/∂τ_d [1], flank s) at one (ω, τ_d)."""
        return self.mesh(omega, tau_d)[:3]

    def other_branch(self, omega: float, tau_d: float, t_dist: float, mu: float, standstill: float) -> float:
        """In the self-locking V (a worm moving faster than ``standstill`` [rad/s] with μ above the self-locking
        limit, and both flanks explaining T_dist [N m] at ω): the load [N m] on the other flank than τ_d's; NaN
        where the load is not ambiguous (the observers' candidates, branches.BranchTracker)."""
        if abs(omega) <= standstill or mu <= self.self_locking_mu:
            return math.nan
        driving, coast, _flags, _chosen = self.invert(omega, t_dist)
        branches = [float(b) for b in (driving, coast) if math.isfinite(float(b))]
        if len(branches) != 2:
            return math.nan
        return max(branches, key=lambda b: abs(b - tau_d))

    def invert(self, omega: ArrayLike, t_dist: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """τ_d explaining a worm-side disturbance T_dist [N m] at ω [rad/s], per flank.

        Returns (driving, coast, flags, chosen): τ_d on the driving-flank branch (NaN where
        none), on the coast branch (NaN where none), flags (AMBIGUOUS: both branches exist,
        the self-locking V; OUT_OF_CALIBRATION: neither), and the branch chosen when one must
        be: the driving flank (the load that opposes the motion most, as the extended-model
        estimator), else the coast flank, else the V's vertex (D = 0).
        """
        w, t = np.broadcast_arrays(np.asarray(omega, dtype=float), np.asarray(t_dist, dtype=float))
        drag = self.gear_drag(w)
        driving, coast = load_per_flank(self.rig.gearbox, self.mu(w), t - coulomb_friction(self.rig.drive_motor, w), w)
        driving, coast = driving - drag, coast - drag
        ok_plus, ok_minus = ~np.isnan(driving), ~np.isnan(coast)
        flags = np.where(ok_plus & ok_minus, int(EstimateFlags.AMBIGUOUS), 0)
        flags = np.where(~ok_plus & ~ok_minus, int(EstimateFlags.OUT_OF_CALIBRATION), flags)
        chosen = np.where(ok_plus, driving, np.where(ok_minus, coast, -drag))
        return driving, coast, flags.astype(np.int64), chosen


__all__ = ["StaticLoadMap"]
