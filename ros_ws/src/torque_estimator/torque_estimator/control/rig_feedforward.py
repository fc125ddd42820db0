"""The feedforward a rig computes itself: a τ_d estimator beside its speed PI, on every sample.

Why: through the node graph an estimate reaches the rig's PI one /rig/samples
batch and a transit later (the shipped graph batches 10 samples; the benchmark's
graph timing, 5). Averaged over where a load step falls in its batch of 5, the
observer's feedforward takes ~22 % off the worst load-step dip there
(bench/controller_bench.py, graph timing), and even the true load through the
same path only 46 %. Run beside the PI (sim_node's clock thread,
driver_node's serial reader), the estimate of the sample just taken drives the
very next period: the observer then takes ~44 % off (rig timing), on the same
estimator, calibration and gains.

:class:`EstimatorFeedforward` is worm_rig_driver.drive.rig_loop's RigFeedforward:
LiveEstimator per sample (built as estimator_node builds it, estimation.settings, on
the rig of the node that runs the loop), the controller's rule for
which estimate may be used (control.feedforward.FeedforwardGate: not INVALID_INPUT
or OUT_OF_CALIBRATION, not beyond 1.5x the load motors' torque) and τ_d reflected
through the gearbox at the set-point (balancing_torque, as controller_node).
worm_rig_driver finds :func:`build` by its entry point (setup.py, group
``worm_rig_driver.feedforward``), so that package never imports this one.

The observer's step detector runs here at a false-alarm rate of 1e-3 per sample
(estimator_node's: 1e-4). A feedforward pays for every sample a step goes
unnoticed (0.45-0.6 rad/s of dip each on the bundled rig) and little for a false
alarm, whose jump estimate the next samples undo: over controller_bench's runs at
rig timing 1e-3 gave a worst dip of 2.77 against 2.91 rad/s at 1e-4, with the
steady estimate error (0.21 % of the range) and the steady speed error (0.103
rad/s RMS) no worse. A false alarm's jump is mostly small, but not always: a jump
declared from one sample has a large variance, and one tacho reading 3.5 rad/s
off (~6 of its sigma) has set off -1.36 N m at a held 0.2 N m in a demo run,
flagged (TRANSIENT | OUT_OF_CALIBRATION), so the gate refused it and the standard
outputs carried none of it. Plain Python; no ROS.
"""
from __future__ import annotations

from worm_model.physics.parameters import Rig
from worm_model.physics.steady_state import make_balancing_torque_float
from worm_model.rig_data.estimate import Estimate
from worm_model.rig_data.samples import RigSample

from torque_estimator.control.feedforward import FeedforwardGate
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.live import LiveEstimator
from torque_estimator.estimation.observer import LoadProcess
from torque_estimator.estimation.settings import BuiltEstimator, EstimatorSettings, build_estimator

#: Step detector's false-alarm rate per sample for a feedforward (module docstring).
FEEDFORWARD_FALSE_ALARM = 1e-3


class EstimatorFeedforward:
    """τ_d estimator + FeedforwardGate + balancing torque, one sample at a time (module docstring).

    Args:
        rig: rig parameters (the gearbox the load is reflected through, the load motors' limit).
        live: the per-sample estimator (LiveEstimator: a streaming one, such as the observer, is fed voltage
            and angle).
        sample_period: [s] between samples.
        method: the estimator's registry name (``method``).

    ``observe`` returns the sample's estimate: the rig publishes it as the graph's estimate, so what the
    graph sees is what is fed forward.
    """

    def __init__(self, rig: Rig, live: LiveEstimator, sample_period: float, method: str = "") -> None:
        self.live = live
        self.method = method
        self.gate = FeedforwardGate(timeout=0.0, max_load=1.5 * rig.max_load_torque)
        self.sample_period = sample_period
        self._balancing = make_balancing_torque_float(rig)
        self._stamp = 0.0

    def observe(self, sample: RigSample, seq: int) -> Estimate:
        """The rig's ``sample``, its loop's sample ``seq``; returns its estimate."""
        est = self.live.update(sample.omega_worm, sample.current_drive, voltage_drive=sample.voltage_drive,
                               theta_worm=sample.theta_worm, seq=seq)
        self._stamp = seq * self.sample_period
        self.gate.offer(est.torque, est.flags, self._stamp)
        return est

    def torque(self, setpoint: float) -> float:
        """Torque at the worm [N m] for the next period at set-point ``setpoint`` [rad/s]; 0 when unusable."""
        tau_d = self.gate.load(self._stamp)
        return 0.0 if tau_d is None else self._balancing(tau_d, setpoint)


def build(method: str, calibration_file: str, rig: Rig, sample_period: float) -> EstimatorFeedforward:
    """The rig feedforward of registry estimator ``method`` over ``calibration_file`` ("" for none: the
    observer and extended_model work from the rig alone), for ``rig``: the entry point worm_rig_driver calls.

    Raises:
        ValueError: unknown method; CalibrationError (a ValueError): a method that needs a calibration without
            one, or a bad calibration file.
    """
    built = _build(EstimatorSettings(method, calibration_file=calibration_file), rig, None)
    return EstimatorFeedforward(rig, built.live(sample_period), sample_period, method)


def feedforward_estimator(method: str, database: CalibrationDatabase | None, rig: Rig) -> BuiltEstimator:
    """Registry estimator ``method`` as a rig feedforward builds it: on ``rig``, the observer's step detector
    at FEEDFORWARD_FALSE_ALARM (the benchmark's rig timing and the closed-loop studies use this too)."""
    return _build(EstimatorSettings(method), rig, database)


def _build(settings: EstimatorSettings, rig: Rig, database: CalibrationDatabase | None) -> BuiltEstimator:
    options = {"load": LoadProcess(false_alarm=FEEDFORWARD_FALSE_ALARM)} if settings.method == "observer" else {}
    return build_estimator(settings, rig=rig, database=database, estimator_options=options)


__all__ = ["FEEDFORWARD_FALSE_ALARM", "EstimatorFeedforward", "build", "feedforward_estimator"]
