"""LoadObserver: the streaming load-torque observer, an extended Kalman filter on Eqs 28-30 with step detection.

Units SI, angles in rad, fixed frame: positive worm rotation is the reference; τ_d [N·m] is the
load torque on the GEAR shaft, positive when it opposes positive worm rotation (the sign of
:mod:`torque_estimator.estimation.database`).

What the rig gives every sample k (RigSample / worm_rig_driver.sim.sensors.Measurement): the drive
voltage V_k [V] actually applied (held over the period that starts at the sample's tick), the
armature current i_k [A] (Hall sensor, ADC), the tacho speed ω_k [rad/s] (ADC) and the encoder
angle θ_k [rad] (latched at the tick). The current and the tacho are each sampled at their own
instant after the tick t_k (the rig file's ADC timing, rig.sensors.sample_times(): 12 us and
116 us on the bundled rig); V_k then acts over [t_k, t_k+1].

The model's only nonlinearity is the static mesh/friction map T_dist(ω, τ_d) (static_map), and the
observer is an extended Kalman filter whose linear part is exact (discrete): the mean is propagated
with the nonlinear T_dist, the covariance with its Jacobian ∂T_dist/∂τ_d = (r_w/r_g)·K_s.
Estimating τ_d directly rather than the lumped T_dist and inverting afterwards makes a speed
reversal at constant load a non-event (T_dist jumps at ω = 0 by the model, not by the state). The
static inverse (StaticLoadMap.invert, per flank, both branches in the V) is still used: for the
initial state and for the other branch of an AMBIGUOUS estimate. The gains follow from the noise
figures and the load process (noise); load steps are found by the step detector (glr).

Flags (EstimateFlags): INVALID_INPUT when V, i, ω or θ is NaN/inf: no measurement update (the
model still propagates with the last valid voltage, the missing-data Kalman step), τ̂ held; never
raises. AMBIGUOUS in the self-locking V (μ(ω̂) > cos φ_n tan λ): the filter stays on the branch it
is on (continuity), the uncertainty reaches the other branch. OUT_OF_CALIBRATION when |τ̂| − 2u
exceeds what the load motors can apply (Rig.max_load_torque, or the calibration's range if
larger) or |ω̂| exceeds the calibrated speeds by 10 %. TRANSIENT while the τ_d variance is still
converging after the filter's start or a detected jump (convergence: back within twice its value before
the jump, or no longer falling).

Cost: one :meth:`LoadObserver.update` takes ~50 us of CPU (bench/observer_bench.py,
observer_update_cpu; ~200 us with numpy throughout). On a 7-state filter numpy's fixed cost per
call (~1 us) outweighs the arithmetic, so the per-sample scalar work (μ(ω), K_s, J_eff, the mean
propagation, the measurement Jacobian) runs in float math, once per state (StaticLoadMap.mesh on
worm_model's float twins), and numpy does only the matrix algebra. test_observer's
test_numbers_pinned holds the results to a run recorded with the all-numpy implementation. A J_eff
bin met for the first time costs matrix exponentials (~0.4 ms single-threaded; 3-40 ms measured on
a busy 2-core machine with OpenBLAS's default threads: OPENBLAS_NUM_THREADS=1).

No ROS; numpy + scipy.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg.lapack

from worm_model.physics.dynamics import inertia_at_flank_factor
from worm_model.physics.parameters import Rig
from worm_model.physics.resolution import standstill_speed
from worm_model.rig_data.estimate import Estimate

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.branches import BranchTracker, Choice, Hold, LoadPrior, hold_drift
from torque_estimator.estimation.observer.convergence import Convergence
from torque_estimator.estimation.observer.discrete import (BACK_EMF_ERROR, CURRENT, N_STATES, OMEGA, RIPPLE_COS,
                                                           RIPPLE_SIN, TAU, THETA, Step, discretise)
from torque_estimator.estimation.observer.glr import StepDetector
from torque_estimator.estimation.observer.noise import LoadProcess, NoiseFigures
from torque_estimator.estimation.observer.static_map import StaticLoadMap

#: Below this |ω̂| [rad/s] the worm counts as standing (no mode, no AMBIGUOUS).
STANDSTILL = 1e-3

#: Normalised innovation squared (ν' S⁻¹ ν, 3 degrees of freedom) above which a sample is taken for
#: a discontinuity, not a continuation of the rig's motion (a restarted rig or encoder, lost
#: samples at speed), and the filter starts again from it. Measured on the pinned reference run
#: (load steps, a reversal at 30000 rad/s², the self-locking V, a 1000 rad/s² ramp): at most 28
#: (white encoder), 95 (interval), 324 with a 20 % light, constant-μ model; one lost sample at
#: 150 rad/s: ~2e4; a restarted rig: ~3e9. Without the restart such a sample drives the filter
#: to ±1e5 N m and then NaN, for good.
RESTART_NIS = 1e4
#: Lost samples (:meth:`LoadObserver.skip`) predicted over; more, and the filter starts again.
MAX_SKIP = 100


_SQRT2 = math.sqrt(2.0)
#: rows of the identity over the state (the encoder's Jacobian is the θ row)
_UNIT = [[1.0 if j == i else 0.0 for j in range(N_STATES)] for i in range(N_STATES)]


def _normal_pdf(z: float) -> float:
    return math.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)


def _normal_cdf(z: float) -> float:
    return 0.5 * math.erfc(-z / _SQRT2)


_IDENTITY = {n: np.eye(n) for n in (2, 3)}


def _inverse(S: np.ndarray) -> np.ndarray:
    """S⁻¹ of the 2×2 or 3×3 innovation covariance by LAPACK's dgesv (LU with partial pivoting,
    solved for the identity), what np.linalg.inv computes (bit for bit on every S of the pinned
    run) without its ~3 us of argument checks and error-state handling."""
    _lu, _piv, inverse, info = scipy.linalg.lapack.dgesv(S, _IDENTITY[len(S)])
    if info > 0:
        raise np.linalg.LinAlgError("Singular matrix")
    return inverse


def interval_measurement(mean: float, var: float, low: float, high: float, uniform_var: float
                         ) -> tuple[float, float]:
    """The Gaussian pseudo-measurement (z, r) equivalent to learning θ ∈ [low, high).

    Prior θ ~ N(mean, var). The exact posterior is that normal truncated to the
    interval; its mean m⁺ and variance v⁺ (moment matching) are what a Kalman update
    with measurement z and variance r gives when 1/v⁺ = 1/var + 1/r and
    m⁺ = mean + var/(var + r)·(z − mean). If the interval holds almost all the prior
    mass (the encoder says nothing new), r is huge; if it holds almost none (the
    prior is off by many σ, e.g. after an undetected load step), the plain uniform
    model is used: z = the interval's centre, r = ``uniform_var``.
    """
    sd = math.sqrt(var)
    lo, hi = (low - mean) / sd, (high - mean) / sd
    mass = _normal_cdf(hi) - _normal_cdf(lo)
    if mass < 1e-6:
        return 0.5 * (low + high), uniform_var
    p_lo, p_hi = _normal_pdf(lo), _normal_pdf(hi)
    shift = (p_lo - p_hi) / mass
    ratio = 1.0 + (lo * p_lo - hi * p_hi) / mass - shift * shift  # v⁺ / var
    if not 1e-9 < ratio < 1.0 - 1e-9:
        if ratio >= 1.0 - 1e-9:
            return mean, 1e9 * var  # no information
        return 0.5 * (low + high), uniform_var
    r = var * ratio / (1.0 - ratio)
    return mean + sd * shift * (var + r) / var, r


def judged(omega: float, tau: float, variance: float, limits: tuple[float, float], flags: int = 0,
           choice: Choice | None = None) -> tuple[int, float]:
    """(flags, 1σ [N m]) of an estimate τ_d [N m] of ``variance`` [(N m)²] at ω [rad/s] (the module docstring's
    flags): AMBIGUOUS where the branch tracker's ``choice`` could not tell the V's two arms apart, the uncertainty
    then reaching the other; OUT_OF_CALIBRATION where no candidate lay in the prior, or beyond the (torque [N m],
    speed [rad/s]) ``limits``. ``flags``: bits already set (TRANSIENT is each observer's own test). The momentum
    observer's too."""
    u = math.sqrt(max(variance, 0.0))
    if choice is not None and choice.ambiguous:
        flags |= EstimateFlags.AMBIGUOUS
        u = max(u, abs(choice.other - tau))
    if choice is not None and choice.outside:
        flags |= EstimateFlags.OUT_OF_CALIBRATION
    if abs(tau) - 2.0 * u > limits[0] or abs(omega) > limits[1]:
        flags |= EstimateFlags.OUT_OF_CALIBRATION
    return int(flags), u


class Branches:
    """What an observer reports of its state's load (branches module docstring): on a moving worm the candidate the
    :class:`~torque_estimator.estimation.branches.BranchTracker` takes (the state moved onto it, ``flip``), on a
    standing one (``standing``) of a drive that self-locks at rest the last moving estimate held, flagged
    STANDSTILL, its uncertainty growing (its friction holds the load, the current says nothing of it)."""

    def __init__(self, smap: StaticLoadMap, prior: LoadPrior, scale: float, period: float) -> None:
        self.map = smap
        self.tracker = BranchTracker(prior)
        self.hold = Hold(hold_drift(prior, scale), period)
        self.holds = smap.self_locks_at_rest  # a drive that does not self-lock at rest shows its load standing
        #: [rad/s] a sample tells the tracker something only this far from standing (twice the standstill band)
        self.clear = 2.0 * standstill_speed(smap.rig)

    def reset(self) -> None:
        self.tracker.reset()
        self.hold.end()

    def report(self, omega: float, tau: float, variance: float, mesh: tuple, limits: tuple[float, float],
               flags: int, standing: bool, observer) -> tuple[float, float, int]:
        """(τ_d [N m], 1σ [N m], flags) of the state at ω [rad/s] with load τ, its ``variance``, mesh
        (StaticLoadMap.mesh there). ``observer``: its ``_flip(load) -> (variance, mesh)`` moves the state onto
        another arm, ``_resumed()`` says it moves again after a stop (branches.Hold.stopped: the load may have
        changed unseen, it has to find it anew, TRANSIENT)."""
        if standing and self.holds:
            self.tracker.stand()
            self.hold.start(tau, math.sqrt(max(variance, 0.0)))
            load, u = self.hold.step()
            flags, _u = judged(0.0, load, u * u, limits, flags | EstimateFlags.STANDSTILL)
            return load, u, flags
        if self.hold.keeps():  # after a stop, motion that has not lasted yet (branches.Hold.keeps)
            load, u = self.hold.step()
            flags, _u = judged(0.0, load, u * u, limits, flags | EstimateFlags.STANDSTILL)
            return load, u, flags
        if self.hold.held is not None:
            if self.hold.stopped:  # the load may have changed while it stood: found anew
                observer._resumed()
            self.hold.end()
        flip = observer._flip
        other = self.map.other_branch(omega, tau, mesh[0], mesh[4], STANDSTILL)
        driving, coast = (tau, other) if mesh[2] > 0 else (other, tau)  # the state's flank: mesh's s
        settled = not flags & (EstimateFlags.TRANSIENT | EstimateFlags.INVALID_INPUT) and abs(omega) > self.clear
        choice = self.tracker.choose(omega, driving, coast, math.sqrt(max(variance, 0.0)), settled)
        if choice.ambiguous:  # nothing told them apart: the state stays on the arm it is on
            choice = Choice(tau, driving if tau == coast else coast, True, choice.outside)
        elif choice.load != tau and math.isfinite(choice.load):
            variance, mesh = flip(choice.load)
            tau = choice.load
        flags, u = judged(omega, tau, variance, limits, flags, choice)
        return tau, u, flags


class LoadObserver:
    """Streaming τ_d observer (module docstring); one :meth:`update` per rig sample.

    State x = [θ, ω, i, τ_d, a, b, δ]: the four of the model, the tacho's commutator
    ripple (a, b, below) and the back-EMF constant's relative error δ (LoadProcess.back_emf_std:
    with K_e taken as exact, a 5 % error biases τ̂_d by ~0.19 N m at 150 rad/s, the filter
    reading the back-EMF error as load; as a relative error it follows a reversal). The
    ripple is tacho = ω·(1 + a·sin(pθ) + b·cos(pθ)), p = the tacho's ripple periods per turn
    (the rig file's sensors.tacho_ripple_order). The ripple is deterministic in the
    worm angle, so it is identified (a, b constant, prior variance r²/2 each from the
    rig file's tacho_ripple r; the tacho's white variance is then σ_t² + lsb_t²/12
    only) instead of being treated as noise: left as noise, its 6 ms period at
    150 rad/s looks like a load step to a test over a few samples, and the GLR's jump
    estimates were 3-5 of their own σ off.

    ``encoder``: "white" (default) takes the encoder as θ + white noise of variance
    lsb²/12; "interval" as what it is, θ ∈ [count·lsb, (count+1)·lsb), through the
    moment-matched pseudo-measurement of :func:`interval_measurement`. The interval
    model detects steps about a sample earlier but overshoots more and re-detects
    more often; on the closed loop (bench/observer_bench.py) "white" gave the lower
    IAE, hence the default.

    Args:
        rig: the observer's model of the rig (the simulator may run another).
        sample_period [s]: None → 1 / rig.sensors.sample_rate_hz.
        noise: measurement noise figures; None → NoiseFigures.from_rig(rig).
        load: the load process; None → LoadProcess().
        torque_limit [N m]: |τ_d| the rig can apply (OUT_OF_CALIBRATION above it + 2u);
            None → rig.max_load_torque.
        speed_limit [rad/s]: |ω| above which OUT_OF_CALIBRATION; None → the no-load speed
            supply / K_e.
        ripple_order: tacho ripple periods per worm turn; None → rig.sensors.tacho_ripple_order.
        encoder: "white" or "interval" (see above).
        sample_delays: channel → [s] from the tick to its ADC sampling instant
            ("current_drive", "tacho_drive"); None → the rig file's ADC timing,
            rig.sensors.sample_times() (12 us and 116 us on the bundled rig): at a reversal the
            current slews ~20 A/ms and the worm ~30000 rad/s², so the instant matters (the
            measurement is predicted with the exact discretisation over that delay).
    """

    def __init__(self, rig: Rig, sample_period: float | None = None, *, noise: NoiseFigures | None = None,
                 load: LoadProcess | None = None, torque_limit: float | None = None,
                 speed_limit: float | None = None, ripple_order: int | None = None,
                 encoder: str = "white", sample_delays: dict[str, float] | None = None,
                 prior: LoadPrior | None = None) -> None:
        if encoder not in ("white", "interval"):
            raise ValueError(f"encoder must be 'white' or 'interval', got {encoder!r}")
        self.encoder = encoder
        self.rig = rig
        self.period = float(sample_period) if sample_period else 1.0 / rig.sensors.sample_rate_hz
        if not self.period > 0:
            raise ValueError(f"sample_period must be > 0, got {sample_period}")
        self.noise = noise or NoiseFigures.from_rig(rig)
        self.load = load or LoadProcess()
        self.map = StaticLoadMap(rig)
        self.torque_limit = rig.max_load_torque if torque_limit is None else float(torque_limit)
        self.speed_limit = (rig.supply_voltage / rig.drive_motor.back_emf_constant if speed_limit is None
                            else float(speed_limit))
        self.ripple_order = rig.sensors.tacho_ripple_order if ripple_order is None else int(ripple_order)
        #: [s] from the tick to each analogue channel's sampling instant (the firmware's ADC sequence)
        self.delays = rig.sensors.sample_times() if sample_delays is None else dict(sample_delays)
        self.theta_lsb = 2.0 * self.noise.theta_offset
        self.q = self.load.intensity(rig) * self.period
        self.detector = StepDetector(self.load.threshold(), self.load.window)
        self._steps: dict[tuple[float, float], Step] = {}  # by (J_eff / J_w to 4 decimals, period)
        self._inertia = (rig.total_worm_inertia, rig.total_gear_inertia)  # [kg m²] on the worm, on the gear
        self._back_emf = rig.drive_motor.back_emf_constant
        self._emf_drift = self.load.back_emf_drift ** 2 * self.period  # δ's random walk over a period
        # measurement covariances that do not change from sample to sample
        self._r_white = np.diag([self.noise.theta_var, self.noise.tacho_var, self.noise.current_var])
        self._r_no_encoder = np.diag([self.noise.tacho_var, self.noise.current_var])
        self.x = np.zeros(N_STATES)  # prior for the next sample
        self.P = np.eye(N_STATES)
        self.initialised = False
        self.voltage = 0.0  # last valid voltage [V]
        self._phi_prev: np.ndarray | None = None  # the last period's transition: onsets of the step detector
        self.convergence = Convergence()  # of the τ_d variance, after the start or a jump (TRANSIENT)
        self.jumps = 0  # detections so far
        self.samples = 0
        self.restarts = 0  # samples the filter was restarted from (RESTART_NIS, restart())
        #: the load prior, the branch tracker and the standstill hold (Branches)
        self.branches = Branches(self.map, prior or LoadPrior(), self.torque_limit, self.period)
        self.standstill = standstill_speed(rig)  # [rad/s] below which the worm stands
        self._measured_speed = math.inf  # [rad/s] the last valid sample's tacho (standing: Branches)
        self._flipped = False

    # --- internals --------------------------------------------------------------------------
    def _step(self, factor: float, period: float) -> Step:
        """The discretisation over ``period`` [s] for the inertia of flank factor K_s (Eq. 28), cached:
        J_eff rounded to 4 decimals of the rigid inertia, and the bin's own value discretised, so the
        result is a function of the state alone, not of which J_eff the filter met first (a replay
        that starts later than the live node must reproduce it to the bit)."""
        rigid, geared = self._inertia
        ratio = round(inertia_at_flank_factor(self.rig.gearbox, factor, rigid, geared) / rigid, 4)  # J_eff, binned
        key = (ratio, period)
        step = self._steps.get(key)
        if step is None:
            step = self._steps[key] = Step(discretise(self.rig, ratio * rigid, period))
        return step

    def _initialise(self, current: float, omega: float, theta: float | None) -> None:
        motor = self.rig.drive_motor
        t_dist = motor.torque_constant * current - motor.viscous_drag * omega
        tau = float(self.map.invert(omega, t_dist)[3])
        theta0 = 0.0 if theta is None else theta + self.noise.theta_offset
        self.x = np.array([theta0, omega, current, tau, 0.0, 0.0, 0.0])
        ripple_var = 0.5 * self.noise.tacho_ripple ** 2
        self.P = np.diag([self.noise.theta_var if theta is not None else 1.0, self.noise.tacho_total(omega),
                          self.noise.current_var, self.torque_limit ** 2, ripple_var, ripple_var,
                          self.load.back_emf_std ** 2])
        self.initialised = True
        self.convergence.start()

    def _predict(self, voltage: float, mesh: tuple | None = None) -> None:
        """Propagate the filtered state over one period with V held (mean: nonlinear T_dist).

        mesh: StaticLoadMap.mesh at the filtered state if the caller has it."""
        x = self.x.tolist()
        t_dist, slope, _flank, factor, _mu = self.map.mesh(x[OMEGA], x[TAU]) if mesh is None else mesh
        step = self._step(factor, self.period)
        emf = self._back_emf * x[OMEGA]
        self.x = np.array(step.mean(x, voltage - emf * x[BACK_EMF_ERROR], t_dist) + x[3:])
        phi = step.transition.copy()
        phi[:3, TAU] = [-slope * g for g in step.gamma_t]  # transition(): τ_d acts as the torque −slope·τ_d
        phi[:3, BACK_EMF_ERROR] = [-emf * g for g in step.gamma_v]
        P = phi @ self.P @ phi.T
        P[TAU, TAU] += self.q
        P[BACK_EMF_ERROR, BACK_EMF_ERROR] += self._emf_drift
        self.P = P
        self._phi_prev = phi

    def _at(self, delay: float, voltage: float, x: list[float], mesh: tuple) -> tuple[list[float], list[list[float]]]:
        """(θ, ω, i) predicted ``delay`` [s] after the tick from the prior x with V applied, and its
        Jacobian rows (3 × 7) over the state; floats. mesh: StaticLoadMap.mesh at the prior."""
        if delay <= 0:
            return x[:3], _UNIT[:3]
        t_dist, slope, _flank, factor, _mu = mesh
        step = self._step(factor, delay)
        emf = self._back_emf * x[OMEGA]
        state = step.mean(x, voltage - emf * x[BACK_EMF_ERROR], t_dist)
        # columns θ, ω, i | τ_d | a, b (the ripple does not move the motor) | δ
        jac = [[*p, -slope * gt, 0.0, 0.0, -emf * gv] for p, gt, gv in zip(step.phi, step.gamma_t, step.gamma_v)]
        return state, jac

    def _measurement(self, current: float, omega: float, theta: float | None, voltage: float):
        """(ν, Jacobian H, R): innovations of tacho and current, each predicted at its own ADC instant
        after the tick (the encoder is latched at the tick), plus the encoder's (pseudo-)measurement."""
        x = self.x.tolist()
        mesh = self.map.mesh(x[OMEGA], x[TAU])  # the prior's, for both instants
        p = self.ripple_order
        state_t, jac_t = self._at(self.delays["tacho_drive"], voltage, x, mesh)
        state_i, jac_i = self._at(self.delays["current_drive"], voltage, x, mesh)
        w, th = state_t[OMEGA], state_t[THETA]
        s, c = math.sin(p * th), math.cos(p * th)
        ripple = x[RIPPLE_SIN] * s + x[RIPPLE_COS] * c
        d_theta = w * p * (x[RIPPLE_SIN] * c - x[RIPPLE_COS] * s)
        gain = 1.0 + ripple
        jac_tacho = [gain * dw + d_theta * dth for dw, dth in zip(jac_t[OMEGA], jac_t[THETA])]
        jac_tacho[RIPPLE_SIN], jac_tacho[RIPPLE_COS] = w * s, w * c
        nu = [omega - w * gain, current - state_i[CURRENT]]
        rows = [jac_tacho, jac_i[CURRENT]]
        if theta is None:
            return np.array(nu), np.array(rows), self._r_no_encoder
        if self.encoder == "interval":
            z, r = interval_measurement(x[THETA], float(self.P[THETA, THETA]), theta, theta + self.theta_lsb,
                                        self.noise.theta_var)
            R = np.diag([r, self.noise.tacho_var, self.noise.current_var])
        else:
            z, R = theta + self.noise.theta_offset, self._r_white
        return np.array([z - x[THETA]] + nu), np.array([_UNIT[THETA]] + rows), R

    # --- public -----------------------------------------------------------------------------
    def update(self, *, omega_worm: float, current_drive: float, voltage_drive: float = math.nan,
               theta_worm: float | None = None) -> Estimate:
        """Feed one sample by name: ``voltage_drive`` V [V] applied from this tick on, ``current_drive`` i [A],
        ``omega_worm`` tacho ω [rad/s], ``theta_worm`` encoder θ [rad] (the floored count × lsb, as
        RigSample.theta_worm; None: no encoder). Returns the estimate at this sample; never raises for NaN/inf
        (flagged INVALID_INPUT)."""
        self.samples += 1
        inputs = (voltage_drive, current_drive, omega_worm)
        for v in inputs if theta_worm is None else (*inputs, theta_worm):
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                return self._invalid(voltage_drive)
        voltage_drive, current_drive, omega_worm = float(voltage_drive), float(current_drive), float(omega_worm)
        theta_worm = None if theta_worm is None else float(theta_worm)
        self._measured_speed = omega_worm
        if not self.initialised:
            self._initialise(current_drive, omega_worm, theta_worm)
        for restarted in (False, True):
            nu, h, R = self._measurement(current_drive, omega_worm, theta_worm, voltage_drive)
            x, P = self.x, self.P
            PhT = P @ h.T
            S = h @ PhT + R
            s_inv = _inverse(S)
            if restarted or float(nu @ s_inv @ nu) <= RESTART_NIS:
                break
            # (also NaN) not this rig's continuation: start again from this sample
            self.restarts += 1
            self.detector.clear()
            self._phi_prev = None
            self._initialise(current_drive, omega_worm, theta_worm)
        K = PhT @ s_inv
        xf = x + K @ nu
        Pf = P - K @ PhT.T  # K S K' = P H' S⁻¹ H P (P symmetric)
        jump = None if self._phi_prev is None else self.detector.test(self._phi_prev, h, nu, s_inv, K)
        if jump is not None:  # corrected at once (glr): x̂ += F·Δ̂, P += F F'/C
            self.convergence.start(float(Pf[TAU, TAU]))
            self.jumps += 1
            f = jump.signature
            xf, Pf = xf + f * jump.size, Pf + np.outer(f, f) / jump.information
        self.x, self.P = xf, 0.5 * (Pf + Pf.T)
        mesh = self.map.mesh(float(xf[OMEGA]), float(xf[TAU]))  # for both the estimate and the prediction
        estimate = self._estimate(jump is not None, 0, mesh)
        self.voltage = voltage_drive
        self._predict(voltage_drive, None if self._flipped else mesh)
        return estimate

    def _estimate(self, jump: bool, extra_flags: int, mesh: tuple | None = None) -> Estimate:
        """The estimate at the filtered state; mesh: StaticLoadMap.mesh there if the caller has it."""
        x = self.x
        omega, tau = float(x[OMEGA]), float(x[TAU])
        mesh = self.map.mesh(omega, tau) if mesh is None else mesh
        variance = float(self.P[TAU, TAU])
        if self.convergence.transient(variance):
            extra_flags |= EstimateFlags.TRANSIENT
        self._flipped = False
        # standing: the measured speed within the standstill band and the filtered one near it (the model has no
        # static friction: a current that holds a standing worm drifts the filtered speed off 0)
        standing = abs(self._measured_speed) <= self.standstill and abs(omega) <= 2.0 * self.standstill
        tau, u, flags = self.branches.report(omega, tau, variance, mesh, (self.torque_limit, self.speed_limit),
                                             extra_flags, standing, self)
        return Estimate(tau, u, flags, omega, float(x[CURRENT]), disturbance=mesh[0], jump=jump)

    def _resumed(self) -> None:
        """Moving again after a stop (Branches): the load as unknown as at the start (its variance the torque
        limit's square), converging anew (TRANSIENT)."""
        self.P[TAU, :] = 0.0
        self.P[:, TAU] = 0.0
        self.P[TAU, TAU] = self.torque_limit ** 2
        self.convergence.start()

    def _flip(self, load: float) -> tuple[float, tuple]:
        """Move the state's load onto the V's other arm, ``load`` [N m] (Branches): its variance and covariances
        scaled by the two arms' slopes (the same T_dist uncertainty); returns (variance, mesh there)."""
        omega = float(self.x[OMEGA])
        before = self.map.mesh(omega, float(self.x[TAU]))[1]
        mesh = self.map.mesh(omega, load)
        ratio = before / mesh[1] if mesh[1] else 1.0
        self.x[TAU] = load
        self.P[TAU, :] *= ratio
        self.P[:, TAU] *= ratio
        self._flipped = True
        return float(self.P[TAU, TAU]), mesh

    def skip(self, samples: int) -> None:
        """``samples`` rig samples were lost: predict over them with the last voltage, no
        measurement (what the rig did meanwhile is unknown; the covariance grows accordingly).
        More than MAX_SKIP: :meth:`restart` instead (the state would be a guess)."""
        if samples <= 0 or not self.initialised:
            return
        if samples > MAX_SKIP:
            self.restart()
            return
        self.detector.clear()
        self._phi_prev = None  # no step onset across the gap
        for _ in range(samples):
            self._predict(self.voltage)

    def restart(self) -> None:
        """Forget the state: the next sample initialises the filter (a new rig session)."""
        self.initialised = False
        self.detector.clear()
        self._phi_prev = None
        self.convergence.start()
        self.branches.reset()

    def _invalid(self, voltage) -> Estimate:
        bad = int(EstimateFlags.INVALID_INPUT)
        if not self.initialised:
            return Estimate(math.nan, math.nan, bad, math.nan, math.nan)
        self.detector.clear()
        est = self._estimate(False, bad)
        v = float(voltage) if isinstance(voltage, (int, float)) and math.isfinite(voltage) else self.voltage
        self._predict(v)
        self._phi_prev = None  # no step onset across a missing sample
        return est


__all__ = ["MAX_SKIP", "RESTART_NIS", "STANDSTILL", "Branches", "LoadObserver",
           "interval_measurement", "judged"]
