"""Experiments on the load observer (estimation/observer/) on the simulated rig: shared by its tests and
bench/observer_bench.py. Plain numpy; no ROS.

Every experiment runs n rigs side by side in one SimulatedRig (one per seed or operating
point, each with its own sensor noise), each held by the PI speed controller
(speed_controller.DEFAULT_GAINS, no feedforward unless said), and one stream of the estimator
per rig (the shipped observer as estimator_node builds it, unless another is given) fed what
the rig measures each sample (voltage_drive, current_drive, omega_worm, theta_worm). The
simulator runs the rig file's true parameters; the observer may run a perturbed copy
(:func:`perturbed_rig`). Torques in N m on the gear shaft, positive opposing positive worm
rotation; times in s unless named _ms.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from worm_model.physics.parameters import Rig
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.estimation.observer import ObserverEstimator
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController

#: Load-loop time constant [s] that makes the simulator's load a true step (its default is the
#: load motors' 2 ms current loop, which delays the applied torque itself by ~4.6 ms to 90 %).
IDEAL_STEP = 1e-7


def perturbed_rig(rig: Rig, mu: float = 1.0, kt: float = 1.0, inertia: float = 1.0) -> Rig:
    """The rig with its friction coefficient, motor constant (K_t and K_e: one constant in SI)
    and every inertia (worm, gear, rotors) scaled: the observer's model error in a robustness study."""
    friction = rig.friction
    friction = (replace(friction, scale=friction.scale * mu) if friction.model == "agma"
                else replace(friction, mu_constant=friction.mu_constant * mu))
    motor = replace(rig.drive_motor, torque_constant=rig.drive_motor.torque_constant * kt,
                    back_emf_constant=rig.drive_motor.back_emf_constant * kt,
                    rotor_inertia=rig.drive_motor.rotor_inertia * inertia)
    load = replace(rig.load_motor, rotor_inertia=rig.load_motor.rotor_inertia * inertia)
    gearbox = replace(rig.gearbox, worm_inertia=rig.gearbox.worm_inertia * inertia,
                      gear_inertia=rig.gearbox.gear_inertia * inertia)
    return replace(rig, friction=friction, drive_motor=motor, load_motor=load, gearbox=gearbox)


def run_observers(rig: Rig, speed: Callable[[float], np.ndarray], load: Callable[[float], np.ndarray], n: int,
                  duration: float, *, seed: int = 0, observer_rig: Rig | None = None,
                  load_time_constant: float | None = None, substeps: int = 2,
                  estimator: ObserverEstimator | None = None) -> dict[str, np.ndarray]:
    """Run n rigs for ``duration`` under speed(t) and load(t) set-points (each -> shape (n,)).

    substeps: the simulator's integration steps per sample (its default 2 is coarse in a
    reversal, where the worm accelerates at ~30000 rad/s²).
    estimator: streams from ``estimator.stream`` (its model, sensor correction and calibration
    bias) instead of the shipped observer's (ObserverEstimator, as estimator_node builds it) on
    ``observer_rig`` (default ``rig``: the observer's model is the plant's).
    Returns arrays (samples, n): t [s] (the sample's tick), tau_true (applied load over the
    period starting at that tick), tau_est, uncertainty, flags, omega_true, jump (bool).
    """
    sim = SimulatedRig(rig, n=n, seed=seed, substeps=substeps)
    if load_time_constant is not None:
        sim.plant.load_current_time_constant = load_time_constant
    dt = sim.sample_period
    controller = SpeedController(rig, DEFAULT_GAINS, n=n)
    estimator = estimator if estimator is not None else ObserverEstimator(rig=observer_rig or rig)
    observers = [estimator.stream(dt) for _ in range(n)]
    steps = int(round(duration / dt))
    out = {name: np.zeros((steps, n)) for name in ("t", "tau_true", "tau_est", "uncertainty", "omega_true")}
    out["flags"] = np.zeros((steps, n), dtype=np.int64)
    out["jump"] = np.zeros((steps, n), dtype=bool)
    for k in range(steps):
        t = k * dt
        sim.command(load_torque=load(t))
        omega_true = sim.plant.state.omega_worm.copy()  # at the tick the sensors latch
        m = sim.sample()
        for j, obs in enumerate(observers):
            est = obs.update(omega_worm=float(m.omega_worm[j]), current_drive=float(m.current_drive[j]),
                             voltage_drive=float(m.voltage_drive[j]), theta_worm=float(m.theta_worm[j]))
            out["tau_est"][k, j], out["uncertainty"][k, j] = est.torque, est.uncertainty
            out["flags"][k, j], out["jump"][k, j] = est.flags, est.jump
        out["t"][k] = t
        out["tau_true"][k] = sim.applied_load_torque
        out["omega_true"][k] = omega_true
        sim.command(voltage_drive=controller.update(dt, speed(t + dt), m.omega_worm).voltage)
    return out


@dataclass
class StepResponse:
    """The observer's response to a load step at constant speed, over n seeds.

    step90_ms: when the ensemble-mean estimate first reaches 90 % of the step [ms after the
    step]; per_seed90_ms: the same per seed; overshoot_pct: the ensemble mean's largest
    excursion beyond the step within 50 ms, % of the step; spread_5ms: 10th and 90th
    percentile over seeds of the estimate 5 ms after the step (fraction of the step);
    steady_std: std of the estimate over the 0.3 s before the step [N m], mean over seeds;
    steady_bias: mean error over the last 0.1 s [N m]; mean_response: ensemble mean
    (fraction of the step) from the step on, one value per ms.
    """

    step90_ms: float
    per_seed90_ms: np.ndarray
    overshoot_pct: float
    spread_5ms: tuple[float, float]
    steady_std: float
    steady_bias: float
    mean_response: np.ndarray
    truth90_ms: float


def _first(fraction: np.ndarray, level: float = 0.9) -> float:
    above = np.flatnonzero(fraction >= level)
    return float(above[0]) if above.size else float("nan")


def step_response(rig: Rig, *, seeds: int = 12, seed: int = 0, speed: float = 150.0, before: float = 0.0,
                  after: float = 0.2, settle: float = 0.6, observe: float = 0.2, ideal_step: bool = True,
                  observer_rig: Rig | None = None) -> StepResponse:
    """Step the load from ``before`` to ``after`` at ``settle`` s, speed held at ``speed``."""
    k_step = int(round(settle * rig.sensors.sample_rate_hz))
    run = run_observers(rig, lambda t: np.full(seeds, speed),
                        lambda t: np.full(seeds, after if t >= settle - 1e-9 else before), seeds, settle + observe,
                        seed=seed, observer_rig=observer_rig, load_time_constant=IDEAL_STEP if ideal_step else None)
    change = after - before
    fraction = (run["tau_est"][k_step:] - before) / change
    mean = fraction.mean(axis=1)
    per_seed = np.array([_first(fraction[:, j]) for j in range(seeds)])
    truth = (run["tau_true"][k_step:, 0] - before) / change
    ms = int(round(0.05 * rig.sensors.sample_rate_hz))
    return StepResponse(
        step90_ms=_first(mean), per_seed90_ms=per_seed, overshoot_pct=float(100 * max(mean[:ms].max() - 1, 0.0)),
        spread_5ms=(float(np.percentile(fraction[5], 10)), float(np.percentile(fraction[5], 90))),
        steady_std=float(run["tau_est"][k_step - 300:k_step].std(axis=0).mean()),
        steady_bias=float((run["tau_est"][-100:] - run["tau_true"][-100:]).mean()),
        mean_response=mean, truth90_ms=_first(truth))


def held_out_streaming(rig: Rig, speeds: np.ndarray, torques: np.ndarray, *, seed: int = 1001,
                       duration: float = 1.5, window: float = 0.5, observer_rig: Rig | None = None,
                       estimator: ObserverEstimator | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Stream the observer at each (speed, torque) point held by the PI (one rig per point, the
    rig's own 2 ms load loop); returns (mean estimate, mean applied load) over the last ``window``.
    ``estimator``: its streams (e.g. with a calibration's bias) instead of ``observer_rig``'s."""
    speeds, torques = np.asarray(speeds, float), np.asarray(torques, float)
    run = run_observers(rig, lambda t: speeds, lambda t: torques, len(speeds), duration, seed=seed,
                        observer_rig=observer_rig, estimator=estimator)
    last = int(round(window * rig.sensors.sample_rate_hz))
    return run["tau_est"][-last:].mean(axis=0), run["tau_true"][-last:].mean(axis=0)


def profile_error(rig: Rig, speed: Callable[[float], float], load: float, duration: float, *, seeds: int = 4,
                  seed: int = 0, start: float = 0.0, observer_rig: Rig | None = None,
                  substeps: int = 2) -> tuple[float, float]:
    """(mean, max) |estimate − applied load| [N m] from ``start`` to the end, the speed set-point
    following ``speed(t)`` (a ramp, a reversal), the load held; over ``seeds`` rigs."""
    run = run_observers(rig, lambda t: np.full(seeds, speed(t)), lambda t: np.full(seeds, load), seeds, duration,
                        seed=seed, observer_rig=observer_rig, substeps=substeps)
    first = int(round(start * rig.sensors.sample_rate_hz))
    err = np.abs(run["tau_est"][first:] - run["tau_true"][first:])
    return float(err.mean()), float(err.max())


__all__ = ["IDEAL_STEP", "perturbed_rig", "run_observers", "StepResponse", "step_response", "held_out_streaming",
           "profile_error"]
