"""ObserverEstimator: the load observer behind the estimator interface, the registry's "observer".

Two faces: :meth:`ObserverEstimator.estimate` (the TorqueEstimator interface of
:mod:`torque_estimator.estimation.base`) is the quasi-static inverse of the observer's model
(static_map), so the held-out table and the sweeps score it as the other estimators; and
:meth:`ObserverEstimator.stream` makes the streaming observer (kalman.LoadObserver, wrapped by
streams for a model file's sensor errors and a calibration's bias), which LiveEstimator feeds
voltage and encoder angle per sample: what estimator_node, replay and the rig feedforward run.

Units SI; τ_d [N·m] on the gear shaft, positive opposing positive worm rotation. No ROS.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from worm_model.physics.parameters import Rig, load_rig
from worm_model.residuals.extended import ExtendedModel

from torque_estimator.estimation.base import EstimateFlags, EstimateStream, TorqueEstimates
from torque_estimator.estimation.calibration_bias import CalibrationBias
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.extended_model import SensorCorrection, checked_prior, identification_ranges
from torque_estimator.estimation.observer.kalman import LoadObserver
from torque_estimator.estimation.observer.noise import LoadProcess, NoiseFigures
from torque_estimator.estimation.observer.static_map import StaticLoadMap
from torque_estimator.estimation.observer.streams import BiasedStream, CorrectedStream


class ObserverEstimator:
    """The observer as a registry estimator (registry.ESTIMATORS["observer"]), and the factory of its streams.

    ``estimate(ω, i)`` is the quasi-static inverse of the model's map (α = 0: T_dist =
    K_t i − b ω, then StaticLoadMap.invert), so evaluate/score work as with the other
    estimators; ``stream(period)`` makes the streaming :class:`LoadObserver`, which
    LiveEstimator uses when it is given voltage and encoder angle per sample.

    With a calibration, the model's steady error at the calibration's points (its load
    minus the model's inverse of its speed and current) is added to every estimate,
    interpolated at the estimate's speed and torque (:class:`CalibrationBias`): a rig file
    with μ ×1.3 leaves ~0.02 N·m of steady bias without it. Its step response is the
    filter's: the correction follows τ̂ in the same sample.

    Args:
        database: calibration map, may be None: its torque and speed range set the limits
            for OUT_OF_CALIBRATION, and (``calibration_bias``) its points the bias correction.
        rig_file: rig YAML of the observer's model; empty/None → bundled rig.
        model_file: a rig file written by ``identify`` or ``residuals`` (identified parameters);
            when given it is the observer's model instead of ``rig_file``. Of its ``effects:``
            only the identified sensor errors are used (the observer's model is Eqs 28-30 with
            the drags): the drive current is corrected before the filter sees it, the estimate
            taken back from the load sensor's scale to the true load
            (extended_model.SensorCorrection); its ``identification:`` ranges, when present,
            set the speed and torque limits.
        rig: a Rig instead of a file (tests, robustness studies).
        load: the load process (LoadProcess); None → defaults.
        calibration_bias: add the calibration's measured model error (when a database is given).
    """

    #: its stream reads the drive voltage every sample (base.needs_voltage): no estimate from current and speed alone
    needs_voltage = True

    name = "observer"

    def __init__(self, database: CalibrationDatabase | None = None, rig_file: str | None = None,
                 model_file: str | None = None, *, rig: Rig | None = None, load: LoadProcess | None = None,
                 calibration_bias: bool = True, load_min: float = 0.0, load_max: float = 0.0) -> None:
        self.rig = rig if rig is not None else load_rig(model_file or rig_file or None)
        self.correction = SensorCorrection.of(ExtendedModel.load(model_file)) if model_file and rig is None \
            else SensorCorrection()
        self.load = load or LoadProcess()
        self.map = StaticLoadMap(self.rig)
        self.noise = NoiseFigures.from_rig(self.rig)
        limit, speed = self.rig.max_load_torque, None
        ranges = identification_ranges(model_file) if model_file and rig is None else None
        fallback = None  # the loads admitted when no prior is declared: the identification's or calibration's
        if ranges is not None:
            limit = max(limit, abs(ranges["torque_min"]), abs(ranges["torque_max"]))
            speed = 1.1 * ranges["speed_max"]
            fallback = (ranges["torque_min"], ranges["torque_max"])
        elif database is not None and len(database):
            limit = max(limit, float(np.max(np.abs(database.tau_load))))
            speed = 1.1 * float(np.max(np.abs(database.omega_worm)))
            fallback = (float(np.min(database.tau_load)), float(np.max(database.tau_load)))
        self.torque_limit = limit
        self.speed_limit = speed
        #: the loads the estimate may be (branches.LoadPrior): declared, else the identification's or
        #: calibration's range, else any
        self.prior = checked_prior(load_min, load_max, fallback, self.rig)
        self.bias = CalibrationBias(self._model_estimate, database) \
            if calibration_bias and database is not None and len(database) else None

    def stream(self, sample_period: float | None = None) -> EstimateStream:
        """A fresh streaming observer (LoadObserver) with this estimator's model and limits, corrected for
        the model file's sensor errors and the calibration's bias when there are any (streams)."""
        stream = self._filter(sample_period)
        if self.correction != SensorCorrection():
            stream = CorrectedStream(stream, self.correction)
        return stream if self.bias is None else BiasedStream(stream, self.bias)

    def _filter(self, sample_period: float | None) -> EstimateStream:
        """The bare streaming filter :meth:`stream` wraps (a subclass with another filter overrides this:
        the momentum observer, estimation/momentum/)."""
        return LoadObserver(self.rig, sample_period, load=self.load, torque_limit=self.torque_limit,
                            speed_limit=self.speed_limit, prior=self.prior)

    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """Quasi-static τ_d [N m] from ω [rad/s] and the inertia-free current i [A]; never raises."""
        out = self._model_estimate(omega_worm, current_drive)
        if self.bias is None:
            return out
        w = np.broadcast_to(np.asarray(omega_worm, dtype=float), out.torque.shape)
        other = out.other + self.bias.array(w, np.where(np.isfinite(out.other), out.other, out.torque))
        return TorqueEstimates(out.torque + self.bias.array(w, out.torque), out.uncertainty, out.flags, other)

    def _model_estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """The model's own quasi-static inverse (no calibration bias)."""
        w, i = np.broadcast_arrays(np.asarray(omega_worm, dtype=float), np.asarray(current_drive, dtype=float))
        valid = np.isfinite(w) & np.isfinite(i)
        ws, is_ = np.where(valid, w, 0.0), np.where(valid, self.correction.current(i), 0.0)
        motor = self.rig.drive_motor
        t_dist = motor.torque_constant * is_ - motor.viscous_drag * ws
        driving, coast, flags, chosen = self.map.invert(ws, t_dist)
        # the prior: a candidate outside it is none (both outside: the map's choice, OUT_OF_CALIBRATION)
        prior = self.prior
        drive_in = np.isfinite(driving) & (driving >= prior.low) & (driving <= prior.high)
        coast_in = np.isfinite(coast) & (coast >= prior.low) & (coast <= prior.high)
        chosen = np.where(drive_in, driving, np.where(coast_in, coast, chosen))
        both = drive_in & coast_in
        flags = np.where(both, int(EstimateFlags.AMBIGUOUS), 0) | np.where(
            ~drive_in & ~coast_in, int(EstimateFlags.OUT_OF_CALIBRATION), 0)
        k_plus, k_minus = self.map.factors(ws)
        slope = self.map.k * np.where(np.isfinite(driving) & (chosen == driving), k_plus, np.abs(k_minus))
        with np.errstate(divide="ignore", invalid="ignore"):
            u = motor.torque_constant * math.sqrt(self.noise.current_var) / slope
        other = np.where(both, np.where(chosen == driving, coast, driving), np.nan)
        out = (np.abs(chosen) > self.torque_limit) | (np.abs(ws) > (self.speed_limit or np.inf))
        flags = flags | np.where(out, int(EstimateFlags.OUT_OF_CALIBRATION), 0)
        torque = np.where(valid, self.correction.load(chosen), np.nan)
        u = np.where(valid, u, np.nan)
        flags = np.where(valid, flags, int(EstimateFlags.INVALID_INPUT)).astype(np.int64)
        return TorqueEstimates(torque, u, flags, np.where(valid, self.correction.load(other), np.nan))


__all__ = ["ObserverEstimator"]
