"""MomentumObserver: the load torque τ_d from the drive current and the worm speed (and the encoder angle when there
is one). It never reads the voltage.

The generalised-momentum observer of robotics (De Luca & Mattone 2003; Haddadin, De Luca & Albu-Schäffer,
IEEE T-RO 33(6), 2017) compares the measured momentum p = J_eff·ω with the momentum the motor torque and
the model predict; De Luca's residual

    r = K·( p − p(0) − ∫ (τ_m − b ω − T_dist + r) dt ),     τ_m = K_t i,

is the external torque through a first-order low-pass of bandwidth K. Here the model term is this
project's (physics.md §6-7, Eq. 28 with the drive motor on the worm): T_dist(ω, τ_d) of
observer.static_map — the load on the gear shaft reflected through the mesh's efficiency on the engaged
flank (K_+ = tan(λ+ρ') driving, K_− = tan(λ−ρ') coast), μ(ω), the drive's Coulomb drag and the load
side's drags, self-locking included — so the residual is τ_d itself, on the gear shaft, and a speed
reversal at a constant load is no event (T_dist's jump at ω = 0 is the model's, not the residual's).

Two things the fixed-gain residual cannot do on these sensors, and what is done instead:

* **Its gains.** The residual is run in its Kalman form (the generalised momentum and τ_d as states,
  Wahrburg et al., IEEE T-ASE 15(3), 2018): state x = [θ, ω, τ_d, a, b] (discrete), the current the
  input (its noise, the rig file's, enters as the input's), the tacho (and the encoder, when given)
  measured. Between load steps τ_d is a random walk whose intensity makes the filter's bandwidth
  ``bandwidth`` [Hz] (discrete.load_variance): the one tuning knob, as K is De Luca's.
* **Steps.** A residual fast enough to follow a load step in 5 ms is a noisy one: any linear estimator
  whose mean reaches 90 % of a step 5 samples after it has a noise of at least 0.9 × the Cramér–Rao
  bound on the step's size after 5 samples (bounds.linear_noise_bound). So the filter stays slow and
  a load step is found by the load observer's step detector (observer.glr: the generalised
  likelihood ratio test on the innovations, at ``false_alarm`` per sample), which corrects the state
  at once by the step's estimated size.

Where the model does not hold, the step detector is off for HOLD_OFF (10 ms; the filter runs on):

* the worm's speed changes sign (a reversal: Eq. 28 holds in motion; through ω = 0 the friction
  changes sign, the worm may stick, the teeth cross the backlash);
* the worm stands (below);
* the current jumped (a voltage step: at the simulated rig's ±150 rad/s reversal the current moves up
  to 9.9 A between two samples, against 0.08 A at a steady speed). The current's mean over a period is
  taken as the trapezoid of its two samples; without the voltage nothing says how it moved between
  them. A voltage-driven motor's current moves exponentially (τ_e = L/R) and its mean differs from the
  trapezoid by f·Δi, f = 1/(1 − e^(−T/τ_e)) − τ_e/T − 1/2 (0.10 at 1 kHz on the bundled rig): that is
  added to the current's noise every period, and a period where it exceeds 3 σ_i of the current's own
  noise is one the detector does not trust.

On the simulated rig's ±150 rad/s reversal at 0.1 N m (evaluation.transient) the mean error over the
next 0.6 s is 0.53, 0.33, 0.32 % of the range for a hold-off of 5, 10, 25 ms, and 4.43 % with none:
the detector reads the reversal as load steps.

A standing worm (its filtered speed within STILL_SIGMAS of its own uncertainty of 0 and the measured
speed within STILL_SIGMAS of the tacho's noise) stays where it is: static friction holds it whatever
the load and the current, so the period says nothing of the load and the estimate is held. Without
this the model would read a stopped worm as the load that balances its current: on the T-RO drive's
start-stop runs (evaluation.real_drive: a self-locked drive, at rest with no current), the estimate
over a standstill would fall to the load that balances no current, near 0, and the next move would
start from it on the wrong flank.

The tacho's commutator ripple is periodic in the worm angle: with an encoder it is identified (two
states, phased by θ), without one it is taken as noise. The tacho is sampled ``tacho_delay`` after
the tick (the rig file's ADC timing); the encoder at the tick.

Inputs per sample: current i [A], tacho speed ω [rad/s] and, optionally, the encoder angle θ [rad];
the voltage argument of :meth:`MomentumObserver.update` (base.EstimateStream's signature) is ignored.
A non-finite i or ω is an invalid sample (flagged INVALID_INPUT, the state predicted over it with the
last current); a missing or non-finite θ is a sample without the encoder.

Flags as the load observer's (observer.kalman): AMBIGUOUS in the self-locking V, OUT_OF_CALIBRATION
beyond the limits, TRANSIENT while τ_d's variance is above twice its steady value (after a step, at
the start). Units SI, fixed frame; τ_d [N·m] on the gear shaft, positive opposing positive worm
rotation. No ROS; numpy + scipy.
"""
from __future__ import annotations

import math

import numpy as np

from worm_model.physics.dynamics import inertia_at_flank_factor
from worm_model.physics.parameters import Rig
from worm_model.rig_data.estimate import Estimate

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.momentum.bounds import steady_variance
from torque_estimator.estimation.momentum.discrete import (N_STATES, OMEGA, RIPPLE_COS, RIPPLE_SIN, TAU, THETA,
                                                           Period, load_variance)
from torque_estimator.estimation.observer.glr import StepDetector
from torque_estimator.estimation.branches import LoadPrior
from torque_estimator.estimation.observer.kalman import MAX_SKIP, RESTART_NIS, Branches
from torque_estimator.estimation.observer.noise import LoadProcess, NoiseFigures
from torque_estimator.estimation.observer.static_map import StaticLoadMap

#: [Hz] the default bandwidth between load steps, about the load observer's (its load process' 1 %/s drift is a
#: slowest pole at ~0.56 Hz by discrete.load_variance's relation on the bundled rig). On the simulated rig
#: (evaluation.transient, 12 seeds) 0.5, 1, 2, 4 Hz give a steady noise of 4.9e-4, 7.5e-4, 1.3e-3, 2.3e-3 N m
#: and reversal errors of 0.33, 0.57, 0.92, 1.40 % of the range; the step detector's 4 ms to 90 % of a step
#: is the same at each.
DEFAULT_BANDWIDTH = 0.5
#: [s] the step detector is off this long (at least a sample) after a period where the model does not hold
#: (module docstring)
HOLD_OFF = 0.010
#: the worm counts as standing when its filtered speed is within this many σ of the filter's own speed
#: uncertainty of 0 and the measured speed within this many σ of the tacho's noise
STILL_SIGMAS = 2.0
#: a current step larger than this many σ of the current's noise (through the interpolation factor f) is a
#: period the step detector does not trust
SLEW_SIGMAS = 3.0


def interpolation_error(rig: Rig, period: float) -> float:
    """f [1]: how far a voltage-driven motor's mean current over ``period`` [s] can be from the trapezoid of its
    end samples, per ampere of their difference (module docstring)."""
    motor = rig.drive_motor
    tau_e = motor.inductance / motor.resistance
    return 1.0 / -math.expm1(-period / tau_e) - tau_e / period - 0.5


class MomentumObserver:
    """The streaming momentum observer of the module docstring; one :meth:`update` per sample.

    Args:
        rig: the observer's model of the rig (K_t, inertias, drags, the mesh; L/R; the sensors' noise).
        sample_period [s]: None → 1 / rig.sensors.sample_rate_hz.
        bandwidth [Hz]: of the load estimate between detected steps (discrete.load_variance).
        load: the step detector's settings (LoadProcess: false_alarm per sample, 0 = no detection, and
            window); its drift is not read (``bandwidth`` replaces it).
        noise: the sensors' noise figures; None → NoiseFigures.from_rig(rig).
        torque_limit [N m], speed_limit [rad/s]: OUT_OF_CALIBRATION beyond them (None: the load motors'
            torque, rig.max_load_torque; the no-load speed, supply / K_e).
        ripple_order: tacho ripple periods per worm turn; None → the rig file's.
        tacho_delay [s]: from the tick to the tacho's sampling; None → the rig file's ADC timing.
    """

    def __init__(self, rig: Rig, sample_period: float | None = None, *, bandwidth: float = DEFAULT_BANDWIDTH,
                 load: LoadProcess | None = None, noise: NoiseFigures | None = None,
                 torque_limit: float | None = None, speed_limit: float | None = None,
                 ripple_order: int | None = None, tacho_delay: float | None = None,
                 prior: LoadPrior | None = None) -> None:
        self.rig = rig
        self.period = float(sample_period) if sample_period else 1.0 / rig.sensors.sample_rate_hz
        if not self.period > 0 or not bandwidth > 0:
            raise ValueError(f"need sample_period > 0 and bandwidth > 0, got {sample_period}, {bandwidth}")
        self.bandwidth = float(bandwidth)
        self.noise = noise or NoiseFigures.from_rig(rig)
        self.load = load or LoadProcess()
        self.map = StaticLoadMap(rig)
        motor = rig.drive_motor
        self._kt, self._viscous = motor.torque_constant, motor.viscous_drag
        self._inertia = (rig.total_worm_inertia, rig.total_gear_inertia)
        self.torque_limit = rig.max_load_torque if torque_limit is None else float(torque_limit)
        self.speed_limit = rig.supply_voltage / motor.back_emf_constant if speed_limit is None else float(speed_limit)
        self.ripple_order = rig.sensors.tacho_ripple_order if ripple_order is None else int(ripple_order)
        self.tacho_delay = rig.sensors.sample_times()["tacho_drive"] if tacho_delay is None else float(tacho_delay)
        self.detector = (StepDetector(self.load.threshold(), self.load.window, N_STATES, TAU)
                         if self.load.false_alarm > 0 else None)
        self.interpolation = interpolation_error(rig, self.period)  # f of the module docstring
        self._slew_limit = SLEW_SIGMAS * math.sqrt(self.noise.current_var)
        self._hold_samples = max(1, math.ceil(HOLD_OFF / self.period - 1e-9))
        self._still = STILL_SIGMAS * math.sqrt(self.noise.tacho_var)
        self._r_encoder = np.diag([self.noise.theta_var, self.noise.tacho_var])
        self.x = np.zeros(N_STATES)  # the filtered state of the last sample
        self.P = np.eye(N_STATES)
        self.current = 0.0  # [A] the last valid current
        self.initialised = False
        self.hold_off = 0  # samples the step detector stays off
        self.still = False  # the worm stood through the last period (standing)
        self._at_x: tuple | None = None  # StaticLoadMap.mesh at the filtered state, while it is x
        self._phi_prev: np.ndarray | None = None  # the last period's transition (None: no step onset in it)
        self.p_reference = math.inf  # τ_d variance before the last step (TRANSIENT)
        self.jumps = 0  # steps detected
        self.samples = 0
        self.restarts = 0  # samples the filter started again from (RESTART_NIS, restart())
        #: the load prior, the branch tracker and the standstill hold (observer.kalman.Branches)
        self.branches = Branches(self.map, prior or LoadPrior(), self.torque_limit, self.period)

    # --- the model ----------------------------------------------------------------------------
    def _period(self, mesh: tuple) -> Period:
        """The period's motion at J_eff of the engaged flank; mesh: StaticLoadMap.mesh there."""
        inertia = inertia_at_flank_factor(self.rig.gearbox, mesh[3], *self._inertia)
        return Period.of(inertia, self._viscous, self.period)

    def standing(self, omega: float | None) -> bool:
        """Whether the worm stands (module docstring): the filtered speed within STILL_SIGMAS of its own
        uncertainty of 0, and the measured speed ``omega`` [rad/s] (None: not measured) within STILL_SIGMAS of
        the tacho's noise of 0."""
        spread = STILL_SIGMAS * math.sqrt(max(float(self.P[OMEGA, OMEGA]), 0.0))
        return abs(float(self.x[OMEGA])) <= spread and (omega is None or abs(omega) <= self._still)

    def _predict(self, current: float, omega: float | None = None) -> np.ndarray:
        """Move the filtered state over one period with the mean of the last and this current [A] (the current's
        noise, and the interpolation's error for the step between them, as process noise); returns the
        period's transition. A standing worm (``omega`` [rad/s] the speed measured at the period's end, None:
        none) stays: static friction holds it whatever the load, which the period then says nothing of."""
        x = self.x.tolist()
        mesh = self._at_x or self.map.mesh(x[OMEGA], x[TAU])
        t_dist, slope = mesh[0], mesh[1]
        step = self._period(mesh)
        self.still = self.standing(omega)
        if self.still:
            phi = np.eye(N_STATES)
            phi[OMEGA, OMEGA] = phi[THETA, OMEGA] = 0.0
            theta, omega, g = x[THETA], 0.0, np.zeros(N_STATES)
        else:
            theta, omega = step.mean(x[THETA], x[OMEGA], self._kt * 0.5 * (self.current + current) - t_dist)
            phi = step.transition(slope)
            g = step.current_gain(self._kt)
        slew = self.interpolation * (current - self.current)
        P = phi @ self.P @ phi.T + np.outer(g, g) * (self.noise.current_var + slew * slew)
        if self.still:  # it may start at any moment: its speed as uncertain as the tacho says
            P[OMEGA, OMEGA] += self.noise.tacho_var
        P[TAU, TAU] += load_variance(self.bandwidth, self.noise, self._kt, step.inertia, slope,
                                     self.rig.gearbox.ratio, self.period)
        self.x = np.array([theta, omega, x[TAU], x[RIPPLE_SIN], x[RIPPLE_COS]])
        self.P = P
        self.current = current
        self._at_x = None
        return phi

    def _measurement(self, current: float, omega: float, theta: float | None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ν, H, R) at the prior: the tacho predicted at its sampling instant (the worm accelerated by this
        sample's current over the delay), with the ripple when the encoder phases it; the encoder's angle."""
        x = self.x.tolist()
        mesh = self.map.mesh(x[OMEGA], x[TAU])
        j, d = self._period(mesh).inertia, 0.0 if self.still else self.tacho_delay
        w = x[OMEGA] + d * (self._kt * current - self._viscous * x[OMEGA] - mesh[0]) / j
        dw = [0.0, 1.0 - d * self._viscous / j, -d * mesh[1] / j, 0.0, 0.0]  # ∂w/∂x
        if theta is None:
            return np.array([omega - w]), np.array([dw]), np.array([[self.noise.tacho_total(w)]])
        p = self.ripple_order
        phase = p * (x[THETA] + d * x[OMEGA])
        s, c = math.sin(phase), math.cos(phase)
        gain = 1.0 + x[RIPPLE_SIN] * s + x[RIPPLE_COS] * c
        d_phase = w * p * (x[RIPPLE_SIN] * c - x[RIPPLE_COS] * s)  # ∂(tacho)/∂θ
        tacho = [gain * v for v in dw]
        tacho[THETA] += d_phase
        tacho[OMEGA] += d_phase * d
        tacho[RIPPLE_SIN], tacho[RIPPLE_COS] = w * s, w * c
        nu = [theta + self.noise.theta_offset - x[THETA], omega - w * gain]
        return np.array(nu), np.array([[1.0, 0.0, 0.0, 0.0, 0.0], tacho]), self._r_encoder

    def _model_holds(self, current_before: float, current: float, omega_before: float, omega_after: float) -> bool:
        """Whether the last period is one the step detector can trust (module docstring): no reversal, the worm
        not standing, no jump of the current beyond SLEW_SIGMAS of its noise."""
        reversal = (omega_before > 0.0) != (omega_after > 0.0)
        return not (reversal or self.still) and abs(self.interpolation * (current - current_before)) <= self._slew_limit

    def _initialise(self, current: float, omega: float, theta: float | None) -> None:
        """The state from one sample: τ_d the model's quasi-static inverse (α = 0) of its current and speed."""
        t_dist = self._kt * current - self._viscous * omega
        tau = float(self.map.invert(omega, t_dist)[3])
        ripple_var = 0.5 * self.noise.tacho_ripple ** 2
        self.x = np.array([0.0 if theta is None else theta + self.noise.theta_offset, omega, tau, 0.0, 0.0])
        self.P = np.diag([1.0 if theta is None else self.noise.theta_var, self.noise.tacho_total(omega),
                          self.torque_limit ** 2, ripple_var, ripple_var])
        self.current = current
        self.initialised = True
        self.hold_off = 0
        self.still = False
        self._at_x = None
        self._phi_prev = None
        self.p_reference = math.inf
        if self.detector is not None:
            self.detector.clear()

    # --- public ---------------------------------------------------------------------------------
    def update(self, *, omega_worm: float, current_drive: float, voltage_drive: float = math.nan,
               theta_worm: float | None = None) -> Estimate:
        """Feed one sample by name: ``voltage_drive`` is not read (any value, NaN included); ``current_drive`` i [A],
        ``omega_worm`` tacho ω [rad/s], ``theta_worm`` encoder θ [rad] (the floored count × lsb; None or
        non-finite: no encoder). Returns the estimate at this sample; never raises for NaN/inf (INVALID_INPUT)."""
        self.samples += 1
        if not (_finite(current_drive) and _finite(omega_worm)):
            return self._invalid()
        current_drive, omega_worm = float(current_drive), float(omega_worm)
        theta_worm = float(theta_worm) if _finite(theta_worm) else None
        if not self.initialised:
            self._initialise(current_drive, omega_worm, theta_worm)
            return self._estimate(False, with_encoder=theta_worm is not None)
        omega_before, current_before = float(self.x[OMEGA]), self.current
        phi = self._predict(current_drive, omega_worm)
        nu, h, R = self._measurement(current_drive, omega_worm, theta_worm)
        PhT = self.P @ h.T
        s_inv = _inverse(h @ PhT + R)
        if not float(nu @ s_inv @ nu) <= RESTART_NIS:  # (also NaN) not this rig's continuation: start again
            self.restarts += 1
            self._initialise(current_drive, omega_worm, theta_worm)
            return self._estimate(False, with_encoder=theta_worm is not None)
        K = PhT @ s_inv
        xf = self.x + K @ nu
        Pf = self.P - K @ PhT.T
        jump = None
        if not self._model_holds(current_before, current_drive, omega_before, float(xf[OMEGA])):
            self.hold_off = self._hold_samples
            if self.detector is not None:
                self.detector.clear()
        elif self.hold_off:
            self.hold_off -= 1
        elif self.detector is not None and self._phi_prev is not None:
            jump = self.detector.test(phi, h, nu, s_inv, K)
        if jump is not None:  # corrected at once (observer.glr): x̂ += F·Δ̂, P += F F'/C
            self.p_reference = float(Pf[TAU, TAU])
            self.jumps += 1
            xf, Pf = xf + jump.signature * jump.size, Pf + np.outer(jump.signature, jump.signature) / jump.information
        self.x, self.P = xf, 0.5 * (Pf + Pf.T)
        self._phi_prev = phi
        return self._estimate(jump is not None, with_encoder=theta_worm is not None)

    def _estimate(self, jump: bool, extra_flags: int = 0, with_encoder: bool = True) -> Estimate:
        """The estimate at the filtered state, with its flags (module docstring)."""
        omega, tau = float(self.x[OMEGA]), float(self.x[TAU])
        self._at_x = self._at_x or self.map.mesh(omega, tau)
        if self.p_reference == math.inf:
            self.p_reference = steady_variance(self.rig, omega, tau, self.bandwidth, period=self.period,
                                               noise=self.noise, with_encoder=with_encoder)
        variance = float(self.P[TAU, TAU])
        if variance > 2.0 * self.p_reference:
            extra_flags |= EstimateFlags.TRANSIENT
        tau, u, flags = self.branches.report(omega, tau, variance, self._at_x, (self.torque_limit, self.speed_limit),
                                             extra_flags, self.still, self)
        return Estimate(tau, u, flags, omega, self.current, disturbance=self._at_x[0], jump=jump)

    def _resumed(self) -> None:
        """Moving again after a stop (observer.kalman.Branches): the load as unknown as at the start, TRANSIENT
        against the steady variance of where it moves now."""
        self.P[TAU, :] = 0.0
        self.P[:, TAU] = 0.0
        self.P[TAU, TAU] = self.torque_limit ** 2
        self.p_reference = math.inf

    def _flip(self, load: float) -> tuple[float, tuple]:
        """Move the state's load onto the V's other arm, ``load`` [N m] (observer.kalman.Branches): its variance
        and covariances scaled by the two arms' slopes; returns (variance, mesh there)."""
        omega = float(self.x[OMEGA])
        before = self._at_x[1]
        self._at_x = mesh = self.map.mesh(omega, load)
        ratio = before / mesh[1] if mesh[1] else 1.0
        self.x[TAU] = load
        self.P[TAU, :] *= ratio
        self.P[:, TAU] *= ratio
        self.p_reference *= ratio * ratio  # the other arm's steady variance, by the same slopes
        return float(self.P[TAU, TAU]), mesh

    def _invalid(self) -> Estimate:
        bad = int(EstimateFlags.INVALID_INPUT)
        if not self.initialised:
            return Estimate(math.nan, math.nan, bad, math.nan, math.nan)
        self.skip(1)
        return self._estimate(False, bad)

    def skip(self, samples: int) -> None:
        """``samples`` samples were lost: predict over them with the last current (the covariance grows as it
        should); more than observer.kalman.MAX_SKIP: :meth:`restart` (the state would be a guess)."""
        if samples <= 0 or not self.initialised:
            return
        if samples > MAX_SKIP:
            self.restart()
            return
        if self.detector is not None:
            self.detector.clear()
        self._phi_prev = None  # no step onset across the gap
        for _ in range(samples):
            self._predict(self.current)

    def restart(self) -> None:
        """Forget the state: the next valid sample initialises the filter (a new session)."""
        self.initialised = False
        self._at_x = None
        self._phi_prev = None
        self.p_reference = math.inf
        if self.detector is not None:
            self.detector.clear()
        self.branches.reset()


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def _inverse(S: np.ndarray) -> np.ndarray:
    """S⁻¹ of the 1×1 or 2×2 innovation covariance, in closed form (np.linalg.inv's checks cost more than the
    arithmetic); a singular S gives inf/NaN, which the NIS test then refuses."""
    if len(S) == 1:
        return 1.0 / S
    a, b, c, d = S[0, 0], S[0, 1], S[1, 0], S[1, 1]
    det = a * d - b * c
    return np.array([[d, -b], [-c, a]]) / det


__all__ = ["DEFAULT_BANDWIDTH", "HOLD_OFF", "SLEW_SIGMAS", "MomentumObserver", "interpolation_error"]
