"""What any observer on these sensors can do: the steady Kalman filter, its noise, and information bounds.

All on the 4-state model (θ, ω, i, τ_d; ripple identified, back-EMF exact) linearised at an
operating point (ω, τ_d), with the sensors' noise figures (noise.NoiseFigures, ripple removed)
and the load model that sets the observer's bandwidth (noise.LoadProcess):

* :func:`steady_state_bound`: the steady Kalman covariance of τ_d, i.e. the posterior
  Cramér–Rao bound at that bandwidth;
* :func:`predicted_noise`: the observer's own steady noise on a constant load (steady gains,
  Lyapunov) and :func:`equivalent_window` its noise-equivalent averaging window;
* :func:`jump_bound`: the Cramér–Rao bound on the size of a load step n samples after it, the
  floor under any observer's reaction time on these sensors.

Units SI; τ_d [N·m] on the gear shaft. No ROS; numpy + scipy.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from worm_model.physics.dynamics import effective_worm_inertia
from worm_model.physics.parameters import Rig

from torque_estimator.estimation.observer.discrete import H, discretise, transition
from torque_estimator.estimation.observer.noise import LoadProcess, NoiseFigures
from torque_estimator.estimation.observer.static_map import StaticLoadMap


def linearised(rig: Rig, omega: float, tau_d: float, period: float) -> np.ndarray:
    """Φ (4×4) of the observer's model linearised at (ω, τ_d)."""
    smap = StaticLoadMap(rig)
    _t, slope, flank = smap.worm_torque(omega, tau_d)
    inertia = float(effective_worm_inertia(rig.gearbox, smap.mu(omega), flank, rig.total_worm_inertia,
                                           rig.total_gear_inertia))
    return transition(discretise(rig, inertia, period), slope)


def steady_filter(rig: Rig, omega: float, tau_d: float, period: float, noise: NoiseFigures, q: float,
                  with_encoder: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(Φ, K, P_filtered, P_prior) of the steady Kalman filter at an operating point."""
    phi = linearised(rig, omega, tau_d, period)
    h = H if with_encoder else H[1:]
    R = noise.measurement_covariance(omega)
    if not with_encoder:
        R = R[1:, 1:]
    Q = np.zeros((4, 4))
    Q[3, 3] = q
    prior = scipy.linalg.solve_discrete_are(phi.T, h.T, Q, R)
    S = h @ prior @ h.T + R
    K = prior @ h.T @ np.linalg.inv(S)
    filtered = prior - K @ S @ K.T
    return phi, K, filtered, prior


def _defaults(rig: Rig, period: float | None, noise: NoiseFigures | None, load: LoadProcess | None
              ) -> tuple[float, NoiseFigures, float]:
    """(period [s], noise figures, q per period [(N m)²]) with the rig's defaults for what is None."""
    period = period or 1.0 / rig.sensors.sample_rate_hz
    noise = noise or NoiseFigures.from_rig(rig).without_ripple()
    return period, noise, (load or LoadProcess()).intensity(rig) * period


def predicted_noise(rig: Rig, omega: float, tau_d: float, *, period: float | None = None,
                    noise: NoiseFigures | None = None, load: LoadProcess | None = None) -> float:
    """Std [N m] of the steady observer's τ̂_d for a CONSTANT load (measurement noise only).

    The filtered error obeys e⁺ = (I − K H) Φ e⁺ − K v; its covariance X solves the
    Lyapunov equation X = F X F' + K R K' with F = (I − K H) Φ.
    """
    period, noise, q = _defaults(rig, period, noise, load)
    phi, K, _pf, _pp = steady_filter(rig, omega, tau_d, period, noise, q)
    F = (np.eye(4) - K @ H) @ phi
    X = scipy.linalg.solve_discrete_lyapunov(F, K @ noise.measurement_covariance(omega) @ K.T)
    return math.sqrt(X[3, 3])


def equivalent_window(rig: Rig, omega: float, tau_d: float, *, period: float | None = None,
                      noise: NoiseFigures | None = None, load: LoadProcess | None = None,
                      samples: int = 20000) -> float:
    """Noise-equivalent averaging window [samples] of the steady observer's τ̂_d.

    From the τ̂_d response to a unit step of τ_d (steady gains, no noise, no GLR): the
    impulse response g_k = Δ(step); a uniform average of N samples has Σg² = 1/N, so
    N_eq = (Σ g)² / Σ g².
    """
    period, noise, q = _defaults(rig, period, noise, load)
    phi, K, _pf, _pp = steady_filter(rig, omega, tau_d, period, noise, q)
    gain = np.eye(4) - K @ H
    err = phi @ np.array([0, 0, 0, 1.0])  # prior error at the first sample after a unit jump of the truth
    response = []
    for _ in range(samples):
        filtered = gain @ err
        response.append(1.0 - filtered[3])
        err = phi @ filtered
    step = np.array(response)
    g = np.diff(np.concatenate(([0.0], step)))
    return float(np.sum(g) ** 2 / np.sum(g * g))


def steady_state_bound(rig: Rig, omega: float, tau_d: float, *, period: float | None = None,
                       noise: NoiseFigures | None = None, load: LoadProcess | None = None) -> float:
    """Bound [N m, 1σ] on the τ_d error at the observer's bandwidth: the steady Kalman τ_d covariance.

    For a load that follows the observer's load model (random walk of intensity q, which
    is what sets the bandwidth), linearised at (ω, τ_d), with the sensors' true noise
    figures (ripple identified, quantisation white), the filtered covariance of the
    steady Kalman filter is the posterior Cramér–Rao (van Trees) bound: no estimator
    using these sensors has a smaller mean-square error on such a load. (On a constant
    load the same filter's noise is :func:`predicted_noise`, smaller: the bound also
    pays for following the walk.)
    """
    period, noise, q = _defaults(rig, period, noise, load)
    return math.sqrt(steady_filter(rig, omega, tau_d, period, noise, q)[2][3, 3])


def jump_bound(rig: Rig, omega: float, tau_d: float, samples: int, *, period: float | None = None,
               noise: NoiseFigures | None = None, load: LoadProcess | None = None) -> np.ndarray:
    """Cramér–Rao bound [N m, 1σ] on the size of a load step after 1..``samples`` samples.

    A step Δ in τ_d leaves a known signature in the steady filter's innovations
    (white, covariance S); the Fisher information about Δ after n samples is
    C_n = Σ g_jᵀ S⁻¹ g_j, so no unbiased estimate of the step is better than 1/√C_n
    at n samples after it. This is what limits how fast any observer on these sensors
    can react (the GLR of LoadObserver reaches it for a correctly timed onset).
    """
    period, noise, q = _defaults(rig, period, noise, load)
    phi, K, _pf, prior = steady_filter(rig, omega, tau_d, period, noise, q)
    s_inv = np.linalg.inv(H @ prior @ H.T + noise.measurement_covariance(omega))
    return step_information(phi, H, K, s_inv, phi @ np.array([0, 0, 0, 1.0]), samples)


def step_information(phi: np.ndarray, h: np.ndarray, k: np.ndarray, s_inv: np.ndarray, first: np.ndarray,
                     samples: int) -> np.ndarray:
    """1/√C_n [N m] for n = 1..``samples``: the Cramér–Rao bound on a unit load step's size from the steady filter's
    innovations (transition Φ, measurement matrix H, gain K, innovation covariance S⁻¹), ``first`` the prior state
    error one period after the step; C_n = Σ g_j' S⁻¹ g_j over the signatures g_j = H e_j it leaves."""
    err, info, out = first.copy(), 0.0, []
    for _ in range(samples):
        g = h @ err
        info += float(g @ s_inv @ g)
        out.append(1.0 / math.sqrt(info))
        err = phi @ (err - k @ g)
    return np.array(out)


__all__ = ["equivalent_window", "jump_bound", "linearised", "predicted_noise", "steady_filter",
           "steady_state_bound", "step_information"]
