"""The registry of τ_d estimators: name -> factory, and which node parameters each takes.

Adding an estimator is adding a row here (and its module beside this one);
estimator_node, replay, evaluate and the benchmarks find it by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Callable

from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.base import TorqueEstimator
from torque_estimator.estimation.extended_model import ExtendedModelEstimator
from torque_estimator.estimation.knn import KnnEstimator
from torque_estimator.estimation.observer import ObserverEstimator


#: Estimator name → factory ``(database, **options) -> TorqueEstimator``.
#: "observer" is also a streaming estimator: it has ``stream(sample_period)``, which
#: LiveEstimator uses (fed voltage and encoder angle per sample) instead of its own filters.
ESTIMATORS: dict[str, Callable[..., TorqueEstimator]] = {
    "knn": KnnEstimator,
    "extended_model": ExtendedModelEstimator,
    "observer": ObserverEstimator,
}

#: Estimator name → the estimator_node parameters passed to its factory as options.
NODE_OPTIONS: dict[str, tuple[str, ...]] = {
    "knn": ("k", "weighting"),
    "extended_model": ("model_file", "rig_file"),
    "observer": ("rig_file", "model_file"),
}


#: Estimators that work without a calibration database (their ranges come from the rig file, or from the
#: ``identification:`` section of a model file written by ``identify``).
CALIBRATION_OPTIONAL: frozenset[str] = frozenset({"observer", "extended_model"})


def live_rig_file(method: str, rig_file: str, model_file: str) -> str:
    """The rig file of LiveEstimator's inertia compensation (K_t, inertias): ``rig_file`` when set, else the
    ``model_file`` of a method that takes one (its identified values), else "" (the bundled rig).
    estimator_node, replay and ``estimate`` all use this rule."""
    if rig_file:
        return rig_file
    return model_file if model_file and "model_file" in NODE_OPTIONS.get(method, ()) else ""


def node_options(name: str, parameters: Mapping[str, Any]) -> dict[str, Any]:
    """The options of estimator ``name`` taken from estimator_node's parameters (node and replay alike)."""
    return {option: parameters[option] for option in NODE_OPTIONS.get(name, ())}


def make_estimator(name: str, database: CalibrationDatabase | None, **options: Any) -> TorqueEstimator:
    """Build the estimator registered as ``name`` over ``database`` (None: only for CALIBRATION_OPTIONAL ones).

    Raises:
        ValueError: no estimator of that name (the message lists the known ones).
        TypeError, ValueError: bad options, from the estimator's constructor.
    """
    try:
        factory = ESTIMATORS[name]
    except KeyError:
        raise ValueError(f"unknown estimator {name!r}; known: {sorted(ESTIMATORS)}") from None
    if database is None and name not in CALIBRATION_OPTIONAL:
        raise ValueError(f"estimator {name!r} needs a calibration database")
    return factory(database, **options)


__all__ = [
    "CALIBRATION_OPTIONAL",
    "ESTIMATORS",
    "live_rig_file",
    "make_estimator",
    "NODE_OPTIONS",
    "node_options",
]
