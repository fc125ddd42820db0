"""What any estimator can do from the current, the speed and the encoder angle (no voltage): the steady filter and
information bounds.

On the linear model of discrete (θ, ω, τ_d; the tacho's ripple identified when there is an encoder,
white noise otherwise) linearised at an operating point (ω, τ_d), with the sensors' noise figures
(observer.noise.NoiseFigures: the rig file's) and the current's noise entering as the input's:

* :func:`steady_filter`: the steady Kalman filter at a bandwidth (the momentum observer's, between steps);
* :func:`predicted_noise`: its noise on a constant load;
* :func:`jump_bound`: the Cramér–Rao bound on the size of a load step n samples after it (the
  information the sensors carry about it, whatever estimator reads them);
* :func:`linear_noise_bound`: what that bound costs a *linear* estimator (any fixed-gain momentum
  observer: De Luca's residual, a Kalman filter at a fixed bandwidth): if its mean response to a step
  reaches a fraction r of it n samples after the step, its estimate is an unbiased estimate of
  (load before) + r·(step) from those samples, so its noise on a constant load is at least r times the
  jump bound after n samples. A fast linear momentum observer is a noisy one; the momentum observer runs
  slow between steps and catches steps with the step detector instead.

Units SI; τ_d [N·m] on the gear shaft. No ROS; numpy + scipy.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from worm_model.physics.dynamics import inertia_at_flank_factor
from worm_model.physics.parameters import Rig

from torque_estimator.estimation.momentum.discrete import OMEGA, TAU, THETA, Period, load_variance
from torque_estimator.estimation.observer.bounds import step_information
from torque_estimator.estimation.observer.noise import NoiseFigures
from torque_estimator.estimation.observer.static_map import StaticLoadMap

#: [Hz] the bandwidth of the steady filter the jump bound whitens with: low enough that the load is as good as
#: constant between steps (the bound moves by < 1 % below it)
BOUND_BANDWIDTH = 0.1


def linearised(rig: Rig, omega: float, tau_d: float, period: float, noise: NoiseFigures, bandwidth: float,
               with_encoder: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Φ, G, Q, H, R) of the linear model at (ω, τ_d): transition, the state's change per ampere, the process
    noise (current noise through G, and τ_d's walk at ``bandwidth`` [Hz]), the measurement matrix and noise.
    States (θ, ω, τ_d) with an encoder (the tacho's ripple identified), (ω, τ_d) without (ripple as noise)."""
    smap = StaticLoadMap(rig)
    _t, slope, _flank, factor, _mu = smap.mesh(omega, tau_d)
    inertia = inertia_at_flank_factor(rig.gearbox, factor, rig.total_worm_inertia, rig.total_gear_inertia)
    step = Period.of(inertia, rig.drive_motor.viscous_drag, period)
    keep = [THETA, OMEGA, TAU] if with_encoder else [OMEGA, TAU]
    phi = step.transition(slope)[np.ix_(keep, keep)]
    g = step.current_gain(rig.drive_motor.torque_constant)[keep]
    q = np.outer(g, g) * noise.current_var
    q[-1, -1] += load_variance(bandwidth, noise, rig.drive_motor.torque_constant, inertia, slope,
                                      rig.gearbox.ratio, period)
    if with_encoder:
        h, r = np.eye(2, 3), np.diag([noise.theta_var, noise.tacho_var])
    else:
        h, r = np.array([[1.0, 0.0]]), np.array([[noise.tacho_total(omega)]])
    return phi, g, q, h, r


def steady_filter(rig: Rig, omega: float, tau_d: float, period: float, noise: NoiseFigures, bandwidth: float,
                  with_encoder: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Φ, K, P_filtered, P_prior) of the steady Kalman filter at (ω, τ_d); τ_d is the last state."""
    phi, _g, q, h, r = linearised(rig, omega, tau_d, period, noise, bandwidth, with_encoder)
    prior = scipy.linalg.solve_discrete_are(phi.T, h.T, q, r)
    s = h @ prior @ h.T + r
    k = prior @ h.T @ np.linalg.inv(s)
    return phi, k, prior - k @ s @ k.T, prior


def _defaults(rig: Rig, period: float | None, noise: NoiseFigures | None) -> tuple[float, NoiseFigures]:
    return period or 1.0 / rig.sensors.sample_rate_hz, noise or NoiseFigures.from_rig(rig)


def steady_variance(rig: Rig, omega: float, tau_d: float, bandwidth: float, *, period: float | None = None,
                    noise: NoiseFigures | None = None, with_encoder: bool = True) -> float:
    """The steady filter's τ_d variance [(N m)²] at (ω, τ_d) (the observer's TRANSIENT reference)."""
    period, noise = _defaults(rig, period, noise)
    return float(steady_filter(rig, omega, tau_d, period, noise, bandwidth, with_encoder)[2][-1, -1])


def predicted_noise(rig: Rig, omega: float, tau_d: float, bandwidth: float, *, period: float | None = None,
                    noise: NoiseFigures | None = None, with_encoder: bool = True) -> float:
    """Std [N m] of the steady filter's τ̂_d on a CONSTANT load: the filtered error e⁺ = (I − KH)(Φ e⁺ + w) − K v
    has the covariance X = F X F' + (I − KH) Q_i (I − KH)' + K R K' (F = (I − KH)Φ, Q_i the current's noise)."""
    period, noise = _defaults(rig, period, noise)
    phi, g, _q, h, r = linearised(rig, omega, tau_d, period, noise, bandwidth, with_encoder)
    _phi, k, _pf, _pp = steady_filter(rig, omega, tau_d, period, noise, bandwidth, with_encoder)
    gain = np.eye(len(phi)) - k @ h
    x = scipy.linalg.solve_discrete_lyapunov(gain @ phi, gain @ np.outer(g, g) @ gain.T * noise.current_var
                                             + k @ r @ k.T)
    return math.sqrt(x[-1, -1])


def jump_bound(rig: Rig, omega: float, tau_d: float, samples: int, *, period: float | None = None,
               noise: NoiseFigures | None = None, with_encoder: bool = True,
               bandwidth: float = BOUND_BANDWIDTH) -> np.ndarray:
    """Cramér–Rao bound [N m, 1σ] on the size of a load step after 1..``samples`` samples.

    The step Δ leaves a known signature g_j in the steady filter's white innovations (covariance S);
    the Fisher information about Δ after n samples is C_n = Σ g_j' S⁻¹ g_j, and no unbiased estimate of Δ
    from those samples is better than 1/√C_n (as observer.bounds.jump_bound, on this model: no voltage,
    the current an input).
    """
    period, noise = _defaults(rig, period, noise)
    phi, _g, _q, h, r = linearised(rig, omega, tau_d, period, noise, bandwidth, with_encoder)
    _phi, k, _pf, prior = steady_filter(rig, omega, tau_d, period, noise, bandwidth, with_encoder)
    s_inv = np.linalg.inv(h @ prior @ h.T + r)
    return step_information(phi, h, k, s_inv, phi[:, -1], samples)  # phi[:, -1]: the error a unit step leaves


def linear_noise_bound(rig: Rig, omega: float, tau_d: float, samples: int, fraction: float = 0.9, *,
                       period: float | None = None, noise: NoiseFigures | None = None,
                       with_encoder: bool = True) -> float:
    """The least noise [N m, 1σ on a constant load] of any linear estimator whose mean response to a load step
    reaches ``fraction`` of it ``samples`` samples after the step (module docstring): fraction × the jump
    bound after that many samples."""
    return fraction * float(jump_bound(rig, omega, tau_d, samples, period=period, noise=noise,
                                       with_encoder=with_encoder)[-1])


__all__ = ["BOUND_BANDWIDTH", "jump_bound", "linear_noise_bound", "linearised", "predicted_noise", "steady_filter",
           "steady_variance"]
