"""How an estimator follows a changing load and speed, streamed as estimator_node runs it (no ROS).

Every method goes through :class:`~torque_estimator.estimation.live.LiveEstimator`
(the k-NN and the extended model behind its matched filters and change-gated
smoothing; the observer as a streaming estimator fed voltage and encoder angle, the
momentum observer as one fed the encoder angle and NaN for the voltage it does not read),
on n simulated rigs side by side (one per seed, each with its own sensor noise),
each held at its speed set-point by the rig's PI (worm_rig_driver.drive, no
feedforward). Three experiments, the figures of ``make evaluate``'s ``transient:``
lines:

* step: 150 rad/s, the load steps 0 -> 0.2 N m as a true step (the simulator's
  load loop made instantaneous, so the figure is the estimator's, not the load
  motors'). ``step90_ms``: time from the step until the seeds' mean estimate has
  covered 90 % of it; ``overshoot_pct``: how far the mean goes beyond the new load,
  % of the step (0 if never);
* ramp: 50 -> 300 rad/s in 1 s at 0.1 N m: mean |estimate - load| over the ramp;
* reversal: +150 -> -150 rad/s at 0.1 N m: mean |estimate - load| over the 0.6 s
  from the reversal on (flagged samples included: a user of the stream sees them).

Errors in % of ``torque_range`` (the calibrated range). Torques [N m] on the gear
shaft, positive opposing positive worm rotation.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from worm_model.physics.parameters import Rig
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.estimation.registry import METHODS
from torque_estimator.estimation.settings import BuiltEstimator

#: the simulator's load-loop time constant [s] that makes its load a true step
TRUE_STEP = 1e-7
STEP_AT, STEP_SIZE, STEP_SPEED = 0.5, 0.2, 150.0  # [s], [N m], [rad/s]
RAMP = (0.5, 1.0, 50.0, 300.0, 0.1)  # start [s], duration [s], from, to [rad/s], load [N m]
REVERSAL = (0.6, 0.6, 150.0, 0.1)  # at [s], judged over [s], speed +-[rad/s], load [N m]


@dataclass(frozen=True)
class TransientFigures:
    """One method's figures (see module docstring)."""

    method: str
    step90_ms: float
    overshoot_pct: float
    ramp_err_pct: float
    reversal_err_pct: float
    steady_std: float  #: [N m] noise of the estimate at a constant load (before the step), mean over seeds

    def line(self) -> str:
        """The ``transient:`` line of ``make evaluate``."""
        return (f"transient: method={self.method} step90_ms={self.step90_ms:g} overshoot_pct={self.overshoot_pct:.1f} "
                f"ramp_err_pct={self.ramp_err_pct:.2f} reversal_err_pct={self.reversal_err_pct:.2f}")


def stream(rig: Rig, estimator: BuiltEstimator, speed: Callable[[float], float], load: Callable[[float], float],
           duration: float, *, seeds: int = 4, seed: int = 0, true_step: bool = False) -> dict[str, np.ndarray]:
    """Run ``seeds`` rigs under speed(t) [rad/s] and load(t) [N m] set-points, one LiveEstimator each as
    ``estimator`` (estimation.settings.build_estimator's) makes it; fed the drive voltage only when its method reads
    it, NaN otherwise, as from a drive that reports none.

    Returns arrays (samples, seeds): ``t`` [s], ``tau_true`` (the load applied in the sample's
    period) and ``tau_est`` [N m], and ``flags``.
    """
    voltage = METHODS[estimator.settings.method].reads_voltage
    sim = SimulatedRig(rig, n=seeds, seed=seed)
    if true_step:
        sim.plant.load_current_time_constant = TRUE_STEP
    dt = sim.sample_period
    controller = SpeedController(rig, DEFAULT_GAINS, n=seeds)
    live = [estimator.live(dt) for _ in range(seeds)]
    steps = int(round(duration / dt))
    out = {name: np.empty((steps, seeds)) for name in ("t", "tau_true", "tau_est", "flags")}
    for k in range(steps):
        t = k * dt
        sim.command(load_torque=load(t))
        m = sim.sample()
        sim.command(voltage_drive=controller.update(dt, speed(t), m.omega_worm).voltage)
        for i, estimator_i in enumerate(live):
            e = estimator_i.update(float(m.omega_worm[i]), float(m.current_drive[i]),
                                   voltage_drive=float(m.voltage_drive[i]) if voltage else math.nan,
                                   theta_worm=float(m.theta_worm[i]))
            out["tau_est"][k, i], out["flags"][k, i] = e.torque, e.flags
        out["t"][k] = t
        out["tau_true"][k] = sim.applied_load_torque
    return out


def step_figures(run: Mapping[str, np.ndarray]) -> tuple[float, float, float]:
    """(step90_ms, overshoot_pct, steady_std) of the seeds' estimates around the load step at STEP_AT."""
    t = run["t"][:, 0]
    mean = np.nanmean(run["tau_est"], axis=1)
    before = float(np.mean(mean[(t >= STEP_AT - 0.2) & (t < STEP_AT)]))
    after = t >= STEP_AT
    covered = (mean[after] - before) / STEP_SIZE
    reached = np.flatnonzero(covered >= 0.9)
    step90 = float((t[after][reached[0]] - STEP_AT) * 1e3) if reached.size else float("nan")
    overshoot = max(0.0, float(np.max(covered)) - 1.0) * 100.0
    steady = run["tau_est"][(t >= STEP_AT - 0.2) & (t < STEP_AT)]
    return round(step90, 3), overshoot, float(np.mean(np.nanstd(steady, axis=0)))


def transient_figures(rig: Rig, estimator: BuiltEstimator, torque_range: float, *, seeds: int = 12,
                      seed: int = 0) -> TransientFigures:
    """The three experiments of the module docstring for one estimator as build_estimator builds it."""
    step = stream(rig, estimator, lambda t: STEP_SPEED, lambda t: STEP_SIZE if t >= STEP_AT else 0.0, STEP_AT + 0.3,
                  seeds=seeds, seed=seed, true_step=True)
    step90, overshoot, steady_std = step_figures(step)
    start, length, low, high, ramp_load = RAMP
    ramp = stream(rig, estimator, lambda t: low + (high - low) * min(max(t - start, 0.0), length) / length,
                  lambda t: ramp_load, start + length, seeds=max(seeds // 3, 1), seed=seed + 1)
    on_ramp = ramp["t"][:, 0] >= start
    ramp_err = float(np.nanmean(np.abs(ramp["tau_est"] - ramp["tau_true"])[on_ramp]))
    at, judged, speed, rev_load = REVERSAL
    rev = stream(rig, estimator, lambda t: speed if t < at else -speed, lambda t: rev_load, at + judged,
                 seeds=max(seeds // 3, 1), seed=seed + 2)
    after = rev["t"][:, 0] >= at
    rev_err = float(np.nanmean(np.abs(rev["tau_est"] - rev["tau_true"])[after]))
    return TransientFigures(estimator.settings.method, step90, overshoot, 100 * ramp_err / torque_range,
                            100 * rev_err / torque_range, steady_std)


def ensemble_noise(rig: Rig, estimator: BuiltEstimator, *, seeds: int = 12, seed: int = 0,
                   settle: float = 1.0, duration: float = 1.0) -> float:
    """Std [N m] of the estimate on a constant load (0 N m at STEP_SPEED) across ``seeds`` rigs, averaged over
    ``duration`` after ``settle``: the noise of an estimator slower than step_figures' 0.2 s window
    (the momentum observer between steps), to compare with its predicted steady noise."""
    run = stream(rig, estimator, lambda t: STEP_SPEED, lambda t: 0.0, settle + duration, seeds=seeds, seed=seed)
    return float(np.mean(np.std(run["tau_est"][run["t"][:, 0] >= settle], axis=1)))


__all__ = ["TRUE_STEP", "TransientFigures", "ensemble_noise", "step_figures", "stream", "transient_figures"]
