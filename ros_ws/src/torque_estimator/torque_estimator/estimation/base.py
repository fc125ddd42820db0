"""The interface every τ_d estimator implements: its inputs, outputs and quality flags, and the streaming contract.

Inputs are the drive motor's measured worm speed ω_w [rad/s] and armature
current i [A]; the output is the load torque τ_d on the gear shaft [N·m],
positive when it opposes positive worm rotation (the sign convention of
:mod:`torque_estimator.estimation.database`).

Estimators are plugins: a class satisfying :class:`TorqueEstimator` plus a
row in :data:`torque_estimator.estimation.registry.METHODS`, so the
benchmark and the node treat them alike. Two optional abilities, each a
protocol LiveEstimator (live.py) tests for:

* :class:`StreamingEstimator`: it follows the rig sample by sample itself
  (``stream(sample_period)`` gives an :class:`EstimateStream`, fed voltage,
  current, speed and encoder angle per sample), instead of LiveEstimator's
  filters in front of ``estimate`` (the observer; the momentum observer, which
  leaves the voltage unread);
* :class:`AngleEstimator`: ``estimate`` also takes the worm angle and removes
  a ripple periodic in it when ``uses_angle`` is True (extended_model with
  periodic effects).

An estimator that cannot estimate without the drive voltage says so with a
class attribute ``needs_voltage = True`` (the observer); :func:`needs_voltage`
reads it (absent: False). Input without a voltage (a robot's JointState: current
and speed only) runs only the others.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntFlag
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from worm_model.rig_data.estimate import Estimate


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
    #: The worm stands: static friction (a self-locked mesh) holds the load, so the current says nothing of it;
    #: the last estimate is held, its uncertainty growing.
    STANDSTILL = 16


@dataclass(frozen=True, eq=False)
class TorqueEstimates:
    """Estimates for a batch of samples; all arrays share the inputs' broadcast shape.

    Attributes:
        torque: estimated τ_d [N·m], NaN for invalid input.
        uncertainty: 1-sigma-like spread of the estimate [N·m] (where ``other`` is given: of this candidate alone).
        flags: :class:`EstimateFlags` bits per sample (integer array).
        other: where AMBIGUOUS, the other candidate load [N·m] (the V's other arm), NaN elsewhere; None from an
            estimator that never gives one. A caller that reports an estimate as ambiguous widens its
            uncertainty to reach the other candidate (estimation.live.LiveEstimator.judge).
    """

    torque: NDArray[np.float64]
    uncertainty: NDArray[np.float64]
    flags: NDArray[np.int64]
    other: NDArray[np.float64] | None = None


class EstimateStream(Protocol):
    """A streaming estimator's state for one rig: every sample in order, one estimate each."""

    def update(self, *, omega_worm: float, current_drive: float, voltage_drive: float = math.nan,
               theta_worm: float | None = None) -> Estimate:
        """One sample, by name (RigSample's fields): worm speed [rad/s], drive current [A], the drive voltage
        applied from its tick on [V] (NaN: not measured), encoder angle [rad] (None: no encoder). Never raises for
        NaN/inf (flagged INVALID_INPUT)."""
        ...

    def skip(self, samples: int) -> None:
        """``samples`` rig samples were lost before the next one (predict over them, or start again)."""
        ...


@runtime_checkable
class StreamingEstimator(Protocol):
    """An estimator that follows the rig itself: LiveEstimator feeds its stream every sample as it is."""

    def stream(self, sample_period: float) -> EstimateStream:
        """A fresh stream for samples ``sample_period`` [s] apart."""
        ...


@runtime_checkable
class AngleEstimator(Protocol):
    """An estimator whose ``estimate`` takes the worm angle θ [rad] too (``theta_worm=``), used when
    ``uses_angle`` is True."""

    @property
    def uses_angle(self) -> bool: ...

    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike, theta_worm: ArrayLike | None = None
                 ) -> TorqueEstimates: ...


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


def needs_voltage(estimator_class: object) -> bool:
    """Whether an estimator (its class, or a registry factory) reads the drive voltage (module docstring)."""
    return bool(getattr(estimator_class, "needs_voltage", False))


__all__ = ["AngleEstimator", "EstimateFlags", "EstimateStream", "StreamingEstimator",
           "TorqueEstimates", "TorqueEstimator", "needs_voltage"]
