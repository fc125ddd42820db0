"""estimator_node's per-sample processing as a plain class: one rig sample in, one estimate out.

For every sample (ω_w [rad/s], i [A]): both are low-passed (the calibration
map is quasi-static, so is its input), the current that accelerates the
inertia is taken out (quasi_static.inertia_free_current, Eq. 28), the
configured estimator maps (ω, i) to τ_d [N·m] (positive opposing positive
worm rotation) with an uncertainty and flags, and a sample taken while the
worm accelerates faster than ``transient_acceleration`` is flagged TRANSIENT.
A NaN/inf input gives an INVALID_INPUT estimate and leaves the filters as
they were. Used by estimator_node and by the controller benchmark, so both
run the same code. No ROS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from worm_model.filters import FilteredDerivative
from worm_model.parameters import Rig

from .estimator import EstimateFlags, TorqueEstimator
from .quasi_static import inertia_free_current


@dataclass(frozen=True)
class LiveEstimate:
    """One sample's estimate.

    Attributes:
        torque: τ_d [N·m]; uncertainty [N·m]; flags: EstimateFlags bits;
        omega_worm [rad/s] and current_drive [A]: the filtered (and, for the
        current, inertia-compensated) inputs the estimate was computed from.
    """

    torque: float
    uncertainty: float
    flags: int
    omega_worm: float
    current_drive: float


class LiveEstimator:
    """Streaming τ_d estimation for one rig (see module docstring).

    Args:
        rig: rig parameters (inertia and motor constant for the compensation).
        estimator: the quasi-static map lookup (e.g. KnnEstimator).
        sample_period: time between samples [s].
        input_filter: time constant of the low-pass on speed and current [s] (0: none).
        inertia_compensation: remove J_eff·α/K_t from the current.
        transient_acceleration: |α| [rad/s²] above which an estimate is flagged TRANSIENT.
    """

    def __init__(self, rig: Rig, estimator: TorqueEstimator, sample_period: float, input_filter: float = 0.05,
                 inertia_compensation: bool = True, transient_acceleration: float = 200.0) -> None:
        self.rig = rig
        self.estimator = estimator
        self.inertia_compensation = inertia_compensation
        self.transient_acceleration = transient_acceleration
        self.speed = FilteredDerivative(input_filter, sample_period)
        self.current = FilteredDerivative(input_filter, sample_period)

    def update(self, omega_worm: float, current_drive: float) -> LiveEstimate:
        """Feed one sample: measured worm speed [rad/s] and drive current [A]."""
        omega, alpha = self.speed.update(omega_worm)
        current, _ = self.current.update(current_drive)
        if self.inertia_compensation:
            current = float(inertia_free_current(self.rig, current, omega, alpha))
        result = self.estimator.estimate(omega, current)
        flags = int(result.flags)
        if not (math.isfinite(omega_worm) and math.isfinite(current_drive)):
            flags |= EstimateFlags.INVALID_INPUT
        if abs(alpha) > self.transient_acceleration:
            flags |= EstimateFlags.TRANSIENT
        return LiveEstimate(float(result.torque), float(result.uncertainty), flags, float(omega), float(current))


__all__ = ["LiveEstimate", "LiveEstimator"]
