"""The observer's stream, corrected: for a model file's identified sensor errors, and for a calibration's bias;
and any estimator's streams fed no encoder angle.

The stream wrappers wrap a stream (a :class:`~torque_estimator.estimation.observer.kalman.LoadObserver`, or another
wrapper) and are streams themselves (:class:`~torque_estimator.estimation.base.EstimateStream`:
``update`` and ``skip``); other attributes (``load``, ``jumps``, ``restarts``, ...) are the wrapped
observer's. ObserverEstimator.stream stacks them. Units SI; τ_d [N·m] on the gear shaft. No ROS.
"""
from __future__ import annotations

import math
from typing import Any

from worm_model.rig_data.estimate import Estimate

from torque_estimator.estimation.base import EstimateStream
from torque_estimator.estimation.calibration_bias import CalibrationBias
from torque_estimator.estimation.extended_model import SensorCorrection


class CorrectedStream:
    """A stream fed the drive current corrected for the identified sensor errors, its estimate taken back
    to the true load (ObserverEstimator's ``model_file``, extended_model.SensorCorrection)."""

    def __init__(self, stream: EstimateStream, correction: SensorCorrection) -> None:
        self.stream = stream
        self.correction = correction
        self._gain = 1.0 / (1.0 + correction.drive_gain)

    def update(self, *, omega_worm: float, current_drive: float, voltage_drive: float = math.nan,
               theta_worm: float | None = None) -> Estimate:
        c = self.correction
        est = self.stream.update(omega_worm=omega_worm, current_drive=(current_drive - c.drive_offset) * self._gain,
                                 voltage_drive=voltage_drive, theta_worm=theta_worm)
        torque = est.torque - (c.load_gain * est.torque + c.load_offset)
        return est.with_torque(torque)

    def skip(self, samples: int) -> None:
        self.stream.skip(samples)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


class BiasedStream:
    """A stream whose estimate gets the calibration's bias at its own speed and torque (ObserverEstimator)."""

    def __init__(self, stream: EstimateStream, bias: CalibrationBias) -> None:
        self.stream = stream
        self.bias = bias

    def update(self, *, omega_worm: float, current_drive: float, voltage_drive: float = math.nan,
               theta_worm: float | None = None) -> Estimate:
        est = self.stream.update(omega_worm=omega_worm, current_drive=current_drive, voltage_drive=voltage_drive,
                                 theta_worm=theta_worm)
        if not math.isfinite(est.torque):
            return est
        return est.with_torque(est.torque + self.bias(est.omega_worm, est.torque))

    def skip(self, samples: int) -> None:
        self.stream.skip(samples)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


class EncoderlessStream:
    """A stream fed no encoder angle, whatever its samples carry: a drive that reports current and speed alone."""

    def __init__(self, stream: EstimateStream) -> None:
        self.stream = stream

    def update(self, *, omega_worm: float, current_drive: float, voltage_drive: float = math.nan,
               theta_worm: float | None = None) -> Estimate:
        return self.stream.update(omega_worm=omega_worm, current_drive=current_drive, voltage_drive=voltage_drive)

    def skip(self, samples: int) -> None:
        self.stream.skip(samples)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


class WithoutEncoder:
    """An estimator whose streams are fed no encoder angle (:class:`EncoderlessStream`): what the estimator
    does on a drive without an angle, measured on samples that have one."""

    def __init__(self, estimator: Any) -> None:
        self.estimator = estimator

    def stream(self, sample_period: float) -> EncoderlessStream:
        return EncoderlessStream(self.estimator.stream(sample_period))


__all__ = ["BiasedStream", "CorrectedStream", "EncoderlessStream", "WithoutEncoder"]
