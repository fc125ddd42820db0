"""What an estimator is built from, and the one builder: estimator_node, replay, ``estimate`` and the rig
feedforward all go through :func:`build_estimator`.

:class:`EstimatorSettings` holds the method (a name of registry.METHODS), the rig file, the
calibration file, the model file and the method's options (worm_model.cli.node_options.Option rows: the parameters
estimator_node declares for that method). :data:`SETTINGS_OPTIONS` are the four files' and the
method's own parameters, declared for every method.

The builder's rules (the same for every caller):

* the calibration database is read when ``calibration_file`` is set (checked against the rig: a
  point far outside what it can do is refused); a method that needs one (knn) fails without it;
* the rig of LiveEstimator's inertia compensation (K_t, the inertias): ``rig_file`` when set, else
  the ``model_file`` of a method that reads one (its identified values), else the bundled rig;
* the estimator gets ``model_file`` and ``rig_file`` when it reads a model file (extended_model
  inverts the model file, else the rig file with no effects; the observer runs the model file's
  rig, else the rig file's), the method's own options, and the database;
* a caller that holds a Rig instead of a file (the rig feedforward: the rig its node runs) passes
  it as ``rig``: it is the estimator's model and LiveEstimator's rig alike.

Errors name what was wrong (the caller says which of its options set it): CalibrationError (the
calibration file, or none for a method that needs one), worm_model's ParameterError (the rig or
model file), ValueError (an unknown method or option). No ROS.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from worm_model.physics.parameters import Rig, load_rig

from torque_estimator.estimation.base import TorqueEstimator
from torque_estimator.estimation.database import CalibrationDatabase, load_database
from torque_estimator.errors import CalibrationError
from torque_estimator.estimation.live import LiveEstimator
from worm_model.cli.node_options import RIG_FILE, Option

from torque_estimator.estimation.registry import MAP_OPTIONS, METHODS, method

#: estimator_node's parameters for the settings themselves, declared whatever the method.
SETTINGS_OPTIONS: tuple[Option, ...] = (
    Option("method", "knn", "Estimator: knn (the paper's k-NN map over a calibration), extended_model (inverts the "
           "identified model), observer (Kalman filter on the model, Eqs 28-30, fed the voltage too), momentum "
           "(momentum observer on the model: current and speed only, no voltage).", choices=tuple(METHODS)),
    RIG_FILE,
    Option("calibration_file", "",
           "Calibration database (JSON written by `calibrate`); knn needs one; the observer, momentum and "
           "extended_model can do without one (their ranges then come from the rig file), and with one the observer "
           "and momentum add the model's error measured at its points."),
    Option("model_file", "",
           "Extended model parameter file (rig + effects, written by `identify` or `residuals`): inverted by the "
           "extended_model estimator, its identified parameters are the observer's and momentum's model, and its "
           "identification: "
           "ranges replace a calibration's; empty = rig_file (or the bundled rig) with no effects, the paper's "
           "model."),
)

#: What estimator_node reads.
INPUTS: tuple[str, ...] = ("rig_samples", "joint_state")

#: estimator_node's input and its rate, whatever the method (worm_model.cli.node_options rows).
INPUT_OPTIONS: tuple[Option, ...] = (
    Option("input", "rig_samples", "What the estimates are computed from: rig_samples (rig/samples, a rig's batches) "
           "or joint_state (a robot's sensor_msgs/JointState on joint_state_topic).", choices=INPUTS),
    Option("sample_rate", 1000.0, "Sample rate [Hz] of the input: the rig's, or the JointState publisher's (its "
           "messages' stamps are numbered at this rate).", low=1.0, high=100000.0),
)

#: The rig_samples input's own: the standard outputs' joint and frame (the joint_state input's are
#: joints.settings.JOINT_STATE_ESTIMATOR_OPTIONS).
RIG_SAMPLES_OPTIONS: tuple[Option, ...] = (
    Option("joint_name", "gear", "Name of the joint in torque_estimate/joint_states."),
    Option("wrench_frame", "gear_output", "frame_id of torque_estimate/wrench: its z axis is the output shaft, "
           "positive rotation about +z."),
)

#: Every estimator parameter of estimator_node, whatever the method, by name (replay fills in their defaults).
ALL_OPTIONS: dict[str, Option] = {o.name: o for o in SETTINGS_OPTIONS
                                  + tuple(opt for row in METHODS.values() for opt in row.options)}

_LIVE = frozenset(o.name for o in MAP_OPTIONS)  # passed to LiveEstimator, the others to the estimator


@dataclass(frozen=True)
class EstimatorSettings:
    """Everything an estimator is built from (module docstring).

    Attributes:
        method: a name of registry.METHODS.
        rig_file, calibration_file, model_file: paths, "" for none.
        options: the method's options by name (its Option rows' names; missing ones take their default).

    Raises:
        ValueError: an unknown method, or an option the method does not read.
    """

    method: str = "knn"
    rig_file: str = ""
    calibration_file: str = ""
    model_file: str = ""
    options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        row = method(self.method)
        known = {o.name for o in row.options}
        if unknown := sorted(set(self.options) - known):
            raise ValueError(f"estimator {self.method!r} does not read {', '.join(unknown)} "
                             f"(it reads: {', '.join(sorted(known)) or 'no options'})")
        object.__setattr__(self, "options", {**{o.name: o.default for o in row.options}, **self.options})

    @classmethod
    def from_parameters(cls, parameters: Mapping[str, Any], method_name: str | None = None) -> "EstimatorSettings":
        """The settings in estimator_node's parameters (name -> value: what the node declared, or replay's
        defaults < file < overrides): the files, and the options of ``method_name`` (None: ``parameters
        ["method"]``); parameters the method does not read are left out, missing ones take their default."""
        name = str(parameters.get("method", "knn")) if method_name is None else method_name
        options = {o.name: parameters[o.name] for o in method(name).options if o.name in parameters}
        return cls(name, *(str(parameters.get(key) or "") for key in ("rig_file", "calibration_file", "model_file")),
                   options=options)

    @property
    def live_options(self) -> dict[str, Any]:
        """The options LiveEstimator takes (its filters; none for a streaming method)."""
        return {k: v for k, v in self.options.items() if k in _LIVE}

    @property
    def estimator_options(self) -> dict[str, Any]:
        """The options the estimator's factory takes."""
        return {k: v for k, v in self.options.items() if k not in _LIVE}

    @property
    def live_rig_file(self) -> str:
        """The rig file of LiveEstimator's inertia compensation (module docstring); "" for the bundled rig."""
        if self.rig_file:
            return self.rig_file
        return self.model_file if self.model_file and METHODS[self.method].reads_model_file else ""


@dataclass(frozen=True)
class BuiltEstimator:
    """What :func:`build_estimator` made: the estimator, the database it reads (None without one), the rig
    of LiveEstimator, and the settings; :meth:`live` makes the per-sample front end."""

    settings: EstimatorSettings
    estimator: TorqueEstimator
    database: CalibrationDatabase | None
    rig: Rig

    def live(self, sample_period: float) -> LiveEstimator:
        """A fresh LiveEstimator (all its state new) for samples ``sample_period`` [s] apart."""
        return LiveEstimator(self.rig, self.estimator, sample_period, **self.settings.live_options)


def build_estimator(settings: EstimatorSettings, *, rig: Rig | None = None,
                    database: CalibrationDatabase | None = None,
                    estimator_options: Mapping[str, Any] | None = None) -> BuiltEstimator:
    """Build the estimator of ``settings`` by the module docstring's rules.

    Args:
        rig: a Rig instead of the settings' files (the rig feedforward); then ``model_file`` must be empty.
        database: a database already read instead of ``calibration_file`` (the benchmarks, studies).
        estimator_options: keyword arguments for the estimator's constructor that are no node parameter
            (the rig feedforward's LoadProcess for the observer).

    Raises:
        CalibrationError, ParameterError, ValueError: see the module docstring.
    """
    row = METHODS[settings.method]
    if rig is not None and settings.model_file:
        raise ValueError("a rig and a model_file: the estimator's model is one or the other")
    live_rig = rig if rig is not None else load_rig(settings.live_rig_file or None)
    if database is None and settings.calibration_file:
        database = load_database(settings.calibration_file, live_rig)
    if database is None and row.needs_calibration:
        raise CalibrationError(f"estimator {settings.method!r} needs a calibration file (the database `calibrate` "
                               "writes)")
    options = {**settings.estimator_options, **(estimator_options or {})}
    if row.reads_model_file:
        options.update({"model_file": settings.model_file or None, "rig_file": settings.rig_file or None}
                       if rig is None else {"rig": rig})
    return BuiltEstimator(settings, row.factory(database, **options), database, live_rig)


__all__ = ["ALL_OPTIONS", "SETTINGS_OPTIONS", "BuiltEstimator", "EstimatorSettings", "build_estimator"]
