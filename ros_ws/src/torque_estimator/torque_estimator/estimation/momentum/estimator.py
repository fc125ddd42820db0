"""MomentumEstimator: the momentum observer behind the estimator interface, the registry's "momentum".

The load observer's registry face (observer.estimator.ObserverEstimator) with another filter: the same
model (the rig file, or an identified model file's rig and sensor corrections), the same limits, the same
quasi-static ``estimate`` (the model's inverse of a steady speed and current, so the held-out table
scores it as the others) and the same calibration bias; ``stream`` makes a MomentumObserver, which reads
the current, the speed and the encoder angle only, never the voltage.

Units SI; τ_d [N·m] on the gear shaft, positive opposing positive worm rotation. No ROS.
"""
from __future__ import annotations

from torque_estimator.estimation.base import EstimateStream
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.momentum.observer import DEFAULT_BANDWIDTH, MomentumObserver
from torque_estimator.estimation.observer.estimator import ObserverEstimator
from torque_estimator.estimation.observer.noise import LoadProcess

#: the step detector's default false-alarm probability per sample (the load observer's)
DEFAULT_FALSE_ALARM = LoadProcess().false_alarm


class MomentumEstimator(ObserverEstimator):
    """The momentum observer as a registry estimator (registry.METHODS["momentum"]); see the module docstring.

    Args:
        database, rig_file, model_file, rig, calibration_bias: as ObserverEstimator's.
        bandwidth [Hz]: the load estimate's bandwidth between detected steps (MomentumObserver).
        false_alarm: the step detector's false-alarm probability per sample; 0: no step detection (the
            residual alone, at ``bandwidth``).
        load_min, load_max: the load prior [N m] (estimation.branches.LoadPrior; both 0: none declared).
    """

    name = "momentum"
    #: current and speed suffice (the voltage, where a stream has it, is not read)
    needs_voltage = False

    def __init__(self, database: CalibrationDatabase | None = None, rig_file: str | None = None,
                 model_file: str | None = None, *, bandwidth: float = DEFAULT_BANDWIDTH,
                 false_alarm: float = DEFAULT_FALSE_ALARM, load_min: float = 0.0, load_max: float = 0.0,
                 **options) -> None:
        if not bandwidth > 0 or not 0 <= false_alarm < 1:
            raise ValueError(f"need bandwidth > 0 Hz and 0 <= false_alarm < 1, got {bandwidth}, {false_alarm}")
        super().__init__(database, rig_file, model_file, load=LoadProcess(false_alarm=float(false_alarm)),
                         load_min=load_min, load_max=load_max, **options)
        self.bandwidth = float(bandwidth)

    def _filter(self, sample_period: float | None) -> EstimateStream:
        return MomentumObserver(self.rig, sample_period, bandwidth=self.bandwidth, load=self.load,
                                torque_limit=self.torque_limit, speed_limit=self.speed_limit, prior=self.prior)


__all__ = ["DEFAULT_FALSE_ALARM", "MomentumEstimator"]
