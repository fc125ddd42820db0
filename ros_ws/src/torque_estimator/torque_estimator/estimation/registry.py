"""The registry of τ_d estimators: name -> factory, and what each method reads besides the rig and its files.

Adding an estimator is adding a row to :data:`METHODS` (and its module beside this one):
estimator_node declares the row's options as its parameters, and the node, replay,
``estimate``, the rig feedforward, evaluate and the benchmarks find it by name
(settings.py builds it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from worm_model.cli.node_options import Option

from torque_estimator.estimation.base import TorqueEstimator
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.extended_model import ExtendedModelEstimator
from torque_estimator.estimation.knn import WEIGHTINGS, KnnEstimator
from torque_estimator.estimation.momentum import DEFAULT_BANDWIDTH, DEFAULT_FALSE_ALARM, MomentumEstimator
from torque_estimator.estimation.observer import ObserverEstimator


#: LiveEstimator's matched filters, change detector and inertia compensation in front of a quasi-static map
#: (live.py): read by the methods that are such a map, not by one that follows the rig itself (a stream).
MAP_OPTIONS: tuple[Option, ...] = (
    Option("input_filter", 0.003,
           "Time constant [s] of each of the 3 low-pass stages speed and current pass alike (quasi-static maps: "
           "knn, extended_model).", low=0.0, high=5.0),
    Option("inertia_compensation", True,
           "Remove the current that accelerates the rig's inertia (Eq. 28) before the quasi-static lookup (knn, "
           "extended_model)."),
    Option("estimate_filter", 0.05,
           "Time constant [s] of the smoothing of the compensated current, 0: none (knn, extended_model).",
           low=0.0, high=5.0),
    Option("change_threshold", 4.0,
           "Departure of the compensated current from its smoothed value, in running noise sigma, taken for a "
           "change and followed at once, 0: never (knn, extended_model).", low=0.0, high=100.0),
    Option("transient_acceleration", 200.0,
           "Worm acceleration [rad/s^2] above which an estimate is flagged TRANSIENT (knn, extended_model).",
           low=0.0, high=1e6),
)

#: The k-NN map's own options (KnnEstimator).
KNN_OPTIONS: tuple[Option, ...] = (
    Option("k", 4, "Neighbours averaged by the k-NN estimator (knn).", low=1, high=64),
    Option("weighting", "inverse_distance", "k-NN weighting of the neighbours (knn).", choices=tuple(WEIGHTINGS)),
)

#: The load prior of the model-based estimators (branches.LoadPrior): what tells a self-locking drive's two
#: candidate loads apart besides the motion.
PRIOR_OPTIONS: tuple[Option, ...] = (
    Option("load_min", 0.0,
           "Least load [N m] the drive carries (gear frame, + opposing + rotation: a hanging mass lifted by + "
           "rotation is positive); with load_max, a candidate load outside [load_min, load_max] is not the load "
           "(a self-locking drive's two candidates); both 0: none declared, the identification's or calibration's "
           "range stands in (extended_model, observer, momentum).", low=-1e4, high=1e4),
    Option("load_max", 0.0, "Largest load [N m] the drive carries (see load_min).", low=-1e4, high=1e4),
)

#: The momentum observer's own options (MomentumEstimator).
MOMENTUM_OPTIONS: tuple[Option, ...] = (
    Option("bandwidth", DEFAULT_BANDWIDTH,
           "Bandwidth [Hz] of the load estimate between detected load steps (momentum): higher follows a slow "
           "load change sooner and is noisier.", low=0.01, high=200.0),
    Option("false_alarm", DEFAULT_FALSE_ALARM,
           "False-alarm probability per sample of the load-step detector (momentum); 0: no step detection, the "
           "residual alone at its bandwidth.", low=0.0, high=0.01),
)


@dataclass(frozen=True)
class Method:
    """One estimator: its factory ``(database, **options) -> TorqueEstimator``, the options it reads
    (estimator_node declares them for this method only), whether it needs a calibration database,
    whether it reads a model file (``model_file``: extended_model inverts it, the observer runs it), and
    whether it reads the drive voltage (the observer: without it every sample is INVALID_INPUT; the others
    never read it, so an input without a voltage serves them)."""

    factory: Callable[..., TorqueEstimator]
    options: tuple[Option, ...]
    needs_calibration: bool
    reads_model_file: bool
    reads_voltage: bool = False


#: Estimator name -> Method. "observer" and "momentum" are streaming estimators (base.StreamingEstimator):
#: LiveEstimator feeds their streams every sample as it is instead of running its own filters, so they read no
#: MAP_OPTIONS. The observer reads the voltage too; the momentum observer only current, speed and encoder angle.
METHODS: dict[str, Method] = {
    "knn": Method(KnnEstimator, KNN_OPTIONS + MAP_OPTIONS, needs_calibration=True, reads_model_file=False),
    "extended_model": Method(ExtendedModelEstimator, MAP_OPTIONS + PRIOR_OPTIONS, needs_calibration=False,
                             reads_model_file=True),
    "observer": Method(ObserverEstimator, PRIOR_OPTIONS, needs_calibration=False, reads_model_file=True,
                       reads_voltage=True),
    "momentum": Method(MomentumEstimator, MOMENTUM_OPTIONS + PRIOR_OPTIONS, needs_calibration=False,
                       reads_model_file=True),
}

#: Estimator name -> factory (evaluate, the benchmarks and the tests iterate over it).
ESTIMATORS: dict[str, Callable[..., TorqueEstimator]] = {name: m.factory for name, m in METHODS.items()}


def method(name: str) -> Method:
    """The registry's row of estimator ``name``.

    Raises:
        ValueError: no estimator of that name (the message lists the known ones).
    """
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown estimator {name!r}; known: {sorted(METHODS)}") from None


def make_estimator(name: str, database: CalibrationDatabase | None, **options: Any) -> TorqueEstimator:
    """Build the estimator registered as ``name`` over ``database`` (None: only for one that needs none).

    Raises:
        ValueError: no estimator of that name, or it needs a calibration database and got none.
        TypeError, ValueError: bad options, from the estimator's constructor.
    """
    row = method(name)
    if database is None and row.needs_calibration:
        raise ValueError(f"estimator {name!r} needs a calibration database")
    return row.factory(database, **options)


__all__ = ["ESTIMATORS", "KNN_OPTIONS", "MAP_OPTIONS", "METHODS", "MOMENTUM_OPTIONS", "Method", "PRIOR_OPTIONS",
           "make_estimator", "method"]
