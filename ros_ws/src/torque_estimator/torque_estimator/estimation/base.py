"""The interface every τ_d estimator implements: its inputs, outputs and quality flags.

Inputs are the drive motor's measured worm speed ω_w [rad/s] and armature
current i [A]; the output is the load torque τ_d on the gear shaft [N·m],
positive when it opposes positive worm rotation (the sign convention of
:mod:`torque_estimator.calibration.database`).

Estimators are plugins: a class satisfying :class:`TorqueEstimator` plus a
row in :data:`torque_estimator.estimation.registry.ESTIMATORS`, so the
benchmark and the node treat them alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntFlag
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray



class EstimateFlags(IntFlag):
    """Per-sample quality bits of an estimate (stored as ints in arrays)."""

    NONE = 0
    #: The query lies outside the calibrated region; the value is extrapolated.
    OUT_OF_CALIBRATION = 1
    #: The (ω, i) map is not one-to-one here (self-locking V, physics.md §8);
    #: the value is one of two branches and the uncertainty covers both.
    AMBIGUOUS = 2
    #: ω or i was NaN/inf; the torque is NaN.
    INVALID_INPUT = 4
    #: The motor was accelerating; a quasi-static map reads inertia as load.
    TRANSIENT = 8


@dataclass(frozen=True, eq=False)
class TorqueEstimates:
    """Estimates for a batch of samples; all arrays share the inputs' broadcast shape.

    Attributes:
        torque: estimated τ_d [N·m], NaN for invalid input.
        uncertainty: 1-sigma-like spread of the estimate [N·m].
        flags: :class:`EstimateFlags` bits per sample (integer array).
    """

    torque: NDArray[np.float64]
    uncertainty: NDArray[np.float64]
    flags: NDArray[np.int64]


@runtime_checkable
class TorqueEstimator(Protocol):
    """A τ_d estimator built from a calibration database."""

    name: str

    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """Estimate τ_d [N·m] from ω_w [rad/s] and i [A].

        The inputs broadcast against each other; the outputs have the
        broadcast shape (scalars give 0-d arrays: use ``float(est.torque)``).
        Never raises for NaN/inf samples: they are flagged INVALID_INPUT.
        """
        ...


__all__ = ["EstimateFlags", "TorqueEstimates", "TorqueEstimator"]
