"""observer: a model-based load-torque observer (Kalman filter + GLR step detection) on Eqs 28-30.

Units SI, angles in rad, fixed frame: positive worm rotation is the reference;
τ_d [N·m] is the load torque on the GEAR shaft, positive when it opposes positive
worm rotation (the sign of :mod:`torque_estimator.estimation.database`).

What the rig gives every sample k (RigSample / worm_rig_driver.sim.sensors.Measurement):
the drive voltage V_k [V] actually applied (held over the period that starts at the
sample's tick), the armature current i_k [A] (Hall sensor, 10-bit ADC), the tacho
speed ω_k [rad/s] (10-bit ADC) and the encoder angle θ_k [rad] (2000 counts/rev,
latched at the tick). All three measurements are taken (within 0.12 ms) at the tick
t_k; V_k then acts over [t_k, t_k+1].

Model (physics.md sections 6-7)
-------------------------------
State x = [θ, ω, i, τ_d]. With the drive motor rigidly on the worm (Eq. 30)

    dθ/dt = ω
    J_eff dω/dt = K_t i − b ω − T_dist(ω, τ_d)                           (Eq. 28 + 30)
    L di/dt     = V − R i − K_e ω                                         (Eq. 29)
    dτ_d/dt     = w(t)            (random walk, intensity q)  + steps     (load model)

where T_dist is the lumped worm-side disturbance: everything K_t i − J_eff α − b ω
does not explain. From Eq. 28 in the frame of motion (σ = sign ω, +1 at 0):

    T_dist(ω, τ_d) = c·sign ω + σ·(r_w/r_g)·K_s(μ(ω))·D,   D = σ·(τ_d + τ_drag,g(ω)),
    s = +1 (driving flank) for D >= 0, −1 (coast) for D < 0,

with c the drive motor's Coulomb drag, τ_drag,g the load motors' drag the gear shaft
also carries (worm_model.physics.gear_side: it sets the switching torque, so the
pseudo-resistive mode is D >= 0 with τ_d < 0), μ(ω) the rig's friction model
(worm_model.physics.friction, AGMA, speed dependent) and K_s the flank factor
(worm_model.physics.efficiency: K_+ = tan(λ+ρ'), K_− = tan(λ−ρ')). The inertia is the one of
Eq. 28, J_eff = J_w + J_m + J_g·i·(r_w/r_g)·K_s(μ, s), so the gear's reflected
inertia is consistent with the flank and friction the load map uses. T_dist is
piecewise linear in τ_d with slope (r_w/r_g)·K_s; in a self-locking box (K_− < 0,
|ω| below ~5 rad/s on the NMRV030) it is V-shaped: two loads give the same T_dist
(AMBIGUOUS, see below).

So the only nonlinearity is the static mesh/friction map, and the observer is an
extended Kalman filter whose linear part is exact: the motor and inertia are
discretised exactly (zero-order hold on V and on T_dist over the 1 ms period, matrix
exponential, cached per J_eff); the mean is propagated with the nonlinear T_dist;
the covariance with its Jacobian ∂T_dist/∂τ_d = (r_w/r_g)·K_s. Estimating τ_d
directly rather than the lumped T_dist and inverting afterwards makes a speed
reversal at constant load a non-event (T_dist jumps at ω = 0 by the model, not by
the state). The static inverse (:meth:`StaticLoadMap.invert`, per flank, both
branches in the V) is still used: for the initial state, for the quasi-static batch
estimate (:class:`ObserverEstimator.estimate`, the registry's TorqueEstimator
interface) and for the other branch of an AMBIGUOUS estimate.

Gains: from the noise figures, not tuned
----------------------------------------
The filter is a Kalman filter, so its gains follow from the covariances, all taken
from the rig file (:class:`NoiseFigures.from_rig`):

* current: σ_i² + lsb_i²/12 (Hall noise + the ADC step as uniform quantisation);
* tacho: σ_t² + lsb_t²/12 (noise, ADC step of worm_rig_driver.protocol.scaling's ±500 rad/s
  full scale); the commutator ripple (relative amplitude r, periodic in the worm
  angle) is not noise: the streaming observer identifies its phase (two extra
  states, prior variance r²/2 each; :class:`LoadObserver`). Left as noise it would
  add (r·ω)²/2 (:meth:`NoiseFigures.tacho_total`);
* encoder: lsb_θ²/12 with lsb_θ = 2π/(ppr·decoding), and the floor of the count
  corrected by +lsb_θ/2.

Quantisation is treated as white (true when the signal moves by many steps per
sample or is dithered by noise; at a few rad/s the encoder error is correlated).

Load process (:class:`LoadProcess`): the load is piecewise constant (the load motors
hold set-points for seconds and change them in steps) with a slow drift between
steps. The drift is a random walk whose rms change over one second is
``drift_fraction`` (default 1 %) of the load motors' maximum torque, q =
(0.01·τ_max)²/1 s; it sets the steady bandwidth (hence the steady noise). Steps are
not smeared into q (that would be a random walk fast enough to follow a step in a few
ms and ~20 % of the range of noise); they are detected by a generalised likelihood
ratio test on the innovations (Willsky & Jones 1976): for every onset within the last
``window`` samples the innovations' projection on the signature a unit jump in τ_d
would leave gives the maximum-likelihood jump Δ̂ = d/C and the statistic l = d²/C,
χ²(1) without a jump. A jump is declared when max l exceeds h = χ²₁ quantile at
``false_alarm``/``window`` (Bonferroni; default 1e-4 per sample: at most one false
alarm per 10 s at 1 kHz), and the filter is corrected at once: x̂ += F·Δ̂, P += F F'/C
(F the filtered error a unit jump at that onset leaves). The jump's size is
estimated, never assumed. With the bundled rig a 0.2 N·m step is detected after 3-4
samples with Δ̂ within ~15 % (1σ), then the enlarged covariance lets the next samples
finish the job.

Flags (EstimateFlags): INVALID_INPUT when V, i, ω or θ is NaN/inf: no measurement
update (the model still propagates with the last valid voltage, the missing-data
Kalman step), τ̂ held; never raises. AMBIGUOUS in the self-locking V (μ(ω̂) >
cos φ_n tan λ): the filter stays on the branch it is on (continuity), the
uncertainty reaches the other branch. OUT_OF_CALIBRATION when |τ̂| − 2u exceeds what
the load motors can apply (Rig.max_load_torque, or the calibration's range if
larger) or |ω̂| exceeds the calibrated speeds by 10 %. TRANSIENT while the τ_d
variance is above twice its value before the last detected jump (the estimate is
still converging), and during the initial convergence.

Noise bounds: :func:`steady_state_bound` is the steady Kalman covariance of τ_d with
the true noise figures for the load model that sets the observer's bandwidth, i.e.
the posterior Cramér–Rao bound at that bandwidth; :func:`predicted_noise` is the
observer's own steady noise on a constant load (steady gains, Lyapunov) and
:func:`equivalent_window` its noise-equivalent averaging window; :func:`jump_bound`
is the Cramér–Rao bound on the size of a load step n samples after it, the floor
under any observer's reaction time on these sensors.

Cost: one :meth:`LoadObserver.update` takes ~50 us of CPU (bench/observer_bench.py,
observer_update_cpu; ~200 us with numpy throughout). On a 7-state filter numpy's fixed cost
per call (~1 us) outweighs the arithmetic, so the per-sample scalar work (μ(ω), K_s, J_eff,
the mean propagation, the measurement Jacobian) runs in float math, once per state
(StaticLoadMap.mesh on worm_model's float twins), and numpy does only the matrix algebra. test_observer's
test_numbers_pinned holds the results to a run recorded with the all-numpy implementation.
A J_eff bin met for the first time costs matrix exponentials (~0.4 ms single-threaded; 3-40 ms
measured on a busy 2-core machine with OpenBLAS's default threads: OPENBLAS_NUM_THREADS=1).

No ROS; numpy + scipy.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
import scipy.linalg.lapack
from numpy.typing import ArrayLike
from scipy.stats import chi2

from worm_model.physics.efficiency import flank_factor, make_flank_factor_float
from worm_model.physics.friction import friction_coefficient, make_friction_coefficient_float
from worm_model.physics.parameters import Rig, load_rig
from worm_model.residuals.extended import ExtendedModel

from torque_estimator.estimation.calibration_bias import CalibrationBias
from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.base import EstimateFlags, TorqueEstimates
from torque_estimator.estimation.extended_model import SensorCorrection, identification_ranges

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


# ----------------------------------------------------------------------------------------------
# noise figures and load process

@dataclass(frozen=True)
class NoiseFigures:
    """Measurement noise variances of one drive channel, from the rig file (module docstring).

    Attributes:
        current_var [A²]: σ_i² + lsb_i²/12.
        tacho_var [(rad/s)²]: σ_t² + lsb_t²/12 (the speed-independent part).
        tacho_ripple [1]: relative ripple amplitude r; adds (r ω)²/2.
        theta_var [rad²]: lsb_θ²/12.
        theta_offset [rad]: lsb_θ/2, added to the floored encoder angle.
    """

    current_var: float
    tacho_var: float
    tacho_ripple: float
    theta_var: float
    theta_offset: float

    @classmethod
    def from_rig(cls, rig: Rig) -> "NoiseFigures":
        from worm_rig_driver.protocol.table import ADC_BITS
        from worm_rig_driver.protocol.scaling import TACHO_DRIVE_FULL_SCALE

        s = rig.sensors
        tacho_lsb = TACHO_DRIVE_FULL_SCALE / 2 ** (ADC_BITS - 1)
        theta_lsb = 2.0 * math.pi / (s.encoder_pulses_per_rev * s.encoder_decoding)
        return cls(current_var=s.current_noise_std ** 2 + s.current_lsb ** 2 / 12.0,
                   tacho_var=s.tacho_noise_std ** 2 + tacho_lsb ** 2 / 12.0,
                   tacho_ripple=s.tacho_ripple, theta_var=theta_lsb ** 2 / 12.0, theta_offset=theta_lsb / 2.0)

    def tacho_total(self, omega: float) -> float:
        """Tacho variance [(rad/s)²] at worm speed ω [rad/s], ripple included."""
        return self.tacho_var + 0.5 * (self.tacho_ripple * omega) ** 2

    def measurement_covariance(self, omega: float) -> np.ndarray:
        """R for the measurement vector (θ, ω, i) (ripple as noise unless tacho_ripple is 0)."""
        return np.diag([self.theta_var, self.tacho_total(omega), self.current_var])

    def without_ripple(self) -> "NoiseFigures":
        """The figures once the ripple is identified (what the streaming observer is left with)."""
        return replace(self, tacho_ripple=0.0)


@dataclass(frozen=True)
class LoadProcess:
    """The load model the gains follow from (module docstring).

    Attributes:
        drift_fraction: rms change of τ_d over ``drift_time`` between steps, as a fraction of
            Rig.max_load_torque (default 1 % per second).
        drift_time [s].
        false_alarm: probability per sample of a false jump detection (Bonferroni bound).
        window: onsets [samples] the GLR test looks back over.
        back_emf_std: prior relative std of the back-EMF constant, δ in L di/dt = V − R i −
            K_e(1 + δ) ω (δ is a state of the observer). Default 0.05: the ±5 % tolerance of a
            motor constant; 5 % of the 8 V back-EMF at 150 rad/s is 0.4 V, which, taken as
            exact, the filter would read as ~0.19 N m of load.
        back_emf_drift [1/√s]: random walk of δ (magnet temperature, −0.2 %/K); default 0.001.
    """

    drift_fraction: float = 0.01
    drift_time: float = 1.0
    false_alarm: float = 1e-4
    window: int = 25
    back_emf_std: float = 0.05
    back_emf_drift: float = 0.001

    def intensity(self, rig: Rig) -> float:
        """q [(N·m)²/s] of the random walk of τ_d."""
        return (self.drift_fraction * rig.max_load_torque) ** 2 / self.drift_time

    def threshold(self) -> float:
        """h: the GLR statistic above which a jump is declared."""
        return float(chi2.isf(self.false_alarm / max(self.window, 1), 1))


# ----------------------------------------------------------------------------------------------
# static part: the mesh/friction map and its inverse
class StaticLoadMap:
    """T_dist(ω, τ_d) of the module docstring and its inverse, from the rig's model (worm_model).

    The array methods take any shape; :meth:`mesh` and :meth:`worm_torque` take one (ω, τ_d)
    and run in float math on worm_model's float twins of μ(ω) and K_s(μ): the streaming
    observer calls them per sample, where numpy on one value costs ~5 us a call.
    """

    def __init__(self, rig: Rig) -> None:
        self.rig = rig
        gb = rig.gearbox
        self.k = gb.radius_ratio
        self.coulomb = rig.drive_motor.coulomb_drag
        load = rig.load_motor
        self.drag_viscous = rig.load_motor_count * load.viscous_drag * gb.ratio  # [N m s/rad] per worm rad/s
        self.drag_coulomb = rig.load_motor_count * load.coulomb_drag
        self.self_locking_mu = gb.self_locking_mu
        self._mu_float = make_friction_coefficient_float(rig.friction, gb)  # μ(ω), one float
        self._flank_factor_float = make_flank_factor_float(gb)  # K_s(μ, s), one float

    def mu(self, omega: ArrayLike) -> np.ndarray:
        return np.asarray(friction_coefficient(self.rig.friction, self.rig.gearbox, omega), dtype=float)

    def gear_drag(self, omega: ArrayLike) -> np.ndarray:
        """Load motors' drag on the gear shaft [N m] (worm_model.physics.gear_side.gear_side_drag)."""
        w = np.asarray(omega, dtype=float)
        return self.drag_viscous * w + self.drag_coulomb * np.sign(w)

    def factors(self, omega: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(K_+, K_−) at ω."""
        mu = self.mu(omega)
        return (np.asarray(flank_factor(self.rig.gearbox, mu, 1.0)),
                np.asarray(flank_factor(self.rig.gearbox, mu, -1.0)))

    def mesh(self, omega: float, tau_d: float) -> tuple[float, float, int, float, float]:
        """(T_dist [N m], ∂T_dist/∂τ_d [1], flank s, K_s [1], μ [1]) at one (ω, τ_d), in float math.

        The same operations as the array methods (gear_drag, factors), so the same numbers
        up to the friction law's last bit (worm_model.physics.friction.make_friction_coefficient_float).
        """
        mu = self._mu_float(omega)
        sigma = -1.0 if omega < 0 else 1.0
        sign = (omega > 0) - (omega < 0)
        D = sigma * (tau_d + (self.drag_viscous * omega + self.drag_coulomb * sign))  # gear_drag(ω)
        flank = 1 if D >= 0 else -1
        K = self._flank_factor_float(mu, float(flank))
        return self.coulomb * sign + sigma * self.k * K * D, self.k * K, flank, K, mu

    def worm_torque(self, omega: float, tau_d: float) -> tuple[float, float, int]:
        """(T_dist [N m], ∂T_dist/∂τ_d [1], flank s) at one (ω, τ_d)."""
        return self.mesh(omega, tau_d)[:3]

    def invert(self, omega: ArrayLike, t_dist: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """τ_d explaining a worm-side disturbance T_dist [N m] at ω [rad/s], per flank.

        Returns (driving, coast, flags, other): τ_d on the driving-flank branch (NaN where
        none), on the coast branch (NaN where none), flags (AMBIGUOUS: both branches exist,
        the self-locking V; OUT_OF_CALIBRATION: neither, the V's vertex τ_d is returned as
        driving), and the branch chosen when one must be: the driving flank (the load that
        opposes the motion most, as the extended-model estimator).
        """
        w, t = np.broadcast_arrays(np.asarray(omega, dtype=float), np.asarray(t_dist, dtype=float))
        sigma = np.where(w < 0, -1.0, 1.0)
        k_plus, k_minus = self.factors(w)
        X = sigma * (t - self.coulomb * np.sign(w)) / self.k  # = K_s D
        drag = self.gear_drag(w)
        with np.errstate(divide="ignore", invalid="ignore"):
            d_plus = X / k_plus
            d_minus = X / k_minus
        ok_plus = d_plus >= 0
        ok_minus = (d_minus < 0) & np.isfinite(d_minus)
        driving = np.where(ok_plus, sigma * d_plus - drag, np.nan)
        coast = np.where(ok_minus, sigma * d_minus - drag, np.nan)
        flags = np.where(ok_plus & ok_minus, int(EstimateFlags.AMBIGUOUS), 0)
        none = ~ok_plus & ~ok_minus
        flags = np.where(none, int(EstimateFlags.OUT_OF_CALIBRATION), flags)
        chosen = np.where(ok_plus, driving, np.where(ok_minus, coast, -drag))  # vertex: D = 0
        return driving, coast, flags.astype(np.int64), chosen


def inertia_terms(rig: Rig) -> tuple[float, float]:
    """(J_w + J_m, J_g i (r_w/r_g)) [kg m²]: J_eff = first + second · K_s (Eq. 28)."""
    gb = rig.gearbox
    return rig.total_worm_inertia, rig.total_gear_inertia * gb.ratio * gb.radius_ratio


def effective_inertia(rig: Rig, mu: float, flank: int) -> float:
    """J_eff of Eq. 28 [kg m²] on the worm: J_w + J_m + J_g i (r_w/r_g) K_s(μ)."""
    rigid, geared = inertia_terms(rig)
    return rigid + geared * float(flank_factor(rig.gearbox, mu, float(flank)))


# ----------------------------------------------------------------------------------------------
# discretisation
H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0]])


@dataclass(frozen=True)
class _Discrete:
    """Exact ZOH discretisation of the linear part for one J_eff."""

    phi: np.ndarray  # (3, 3) on (θ, ω, i)
    gamma_v: np.ndarray  # (3,) per volt
    gamma_t: np.ndarray  # (3,) per N m of accelerating torque on the worm


class _Step:
    """One cached :class:`_Discrete` in the forms LoadObserver.update uses every sample.

    phi, gamma_v, gamma_t as nested lists of floats: the mean is propagated in float math
    (numpy's fixed cost per call is larger than this 3×3 arithmetic); ``transition``: the
    7×7 Jacobian of the period with the two columns that change every sample (τ_d: −slope·Γ_t,
    δ: −K_e ω̂·Γ_v) left at zero, copied and completed by LoadObserver._predict.
    """

    __slots__ = ("phi", "gamma_v", "gamma_t", "transition")

    def __init__(self, d: _Discrete) -> None:
        self.phi = d.phi.tolist()
        self.gamma_v = d.gamma_v.tolist()
        self.gamma_t = d.gamma_t.tolist()
        self.transition = np.eye(N_STATES)
        self.transition[:3, :3] = d.phi

    def mean(self, x: list[float], drive: float, torque: float) -> list[float]:
        """(θ, ω, i) after the step from x[:3]: Φ x + Γ_v·drive − Γ_t·torque (drive [V], torque [N m])."""
        x0, x1, x2 = x[0], x[1], x[2]
        return [p[0] * x0 + p[1] * x1 + p[2] * x2 + gv * drive - gt * torque
                for p, gv, gt in zip(self.phi, self.gamma_v, self.gamma_t)]


def discretise(rig: Rig, inertia: float, period: float) -> _Discrete:
    m = rig.drive_motor
    a = np.zeros((5, 5))
    a[0, 1] = 1.0
    a[1, 1], a[1, 2], a[1, 4] = -m.viscous_drag / inertia, m.torque_constant / inertia, 1.0 / inertia
    a[2, 1], a[2, 2], a[2, 3] = -m.back_emf_constant / m.inductance, -m.resistance / m.inductance, 1.0 / m.inductance
    e = scipy.linalg.expm(a * period)
    return _Discrete(e[:3, :3].copy(), e[:3, 3].copy(), e[:3, 4].copy())


def transition(d: _Discrete, slope: float) -> np.ndarray:
    """The 4×4 Jacobian of one period: τ_d enters as the torque −slope·τ_d held over the period."""
    phi = np.eye(4)
    phi[:3, :3] = d.phi
    phi[:3, 3] = -slope * d.gamma_t
    return phi


# ----------------------------------------------------------------------------------------------
# the streaming observer
@dataclass(frozen=True)
class ObserverEstimate:
    """One sample's estimate.

    Attributes:
        torque: τ̂_d [N·m] on the gear shaft (positive opposing positive worm rotation).
        uncertainty: 1σ [N·m] (the filter's; in the V: reaches the other branch).
        flags: EstimateFlags bits.
        omega_worm [rad/s], current_drive [A]: the filtered speed and current.
        disturbance: T_dist(ω̂, τ̂_d) [N·m] on the worm (lumped motor-side disturbance).
        jump: True if a load step was detected at this sample.
    """

    torque: float
    uncertainty: float
    flags: int
    omega_worm: float
    current_drive: float
    disturbance: float
    jump: bool = False


#: Index of each state in LoadObserver.x.
THETA, OMEGA, CURRENT, TAU, RIPPLE_SIN, RIPPLE_COS, BACK_EMF_ERROR = range(7)
N_STATES = 7
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


class LoadObserver:
    """Streaming τ_d observer (module docstring); one :meth:`update` per rig sample.

    State x = [θ, ω, i, τ_d, a, b, δ]: the four of the model, the tacho's commutator
    ripple (a, b, below) and the back-EMF constant's relative error δ (LoadProcess.back_emf_std:
    with K_e taken as exact, a 5 % error biases τ̂_d by ~0.19 N m at 150 rad/s, the filter
    reading the back-EMF error as load; as a relative error it follows a reversal). The
    ripple is tacho = ω·(1 + a·sin(pθ) + b·cos(pθ)), p = the tacho's segment count
    (worm_rig_driver.sim.sensors.TACHO_RIPPLE_ORDER). The ripple is deterministic in the
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
        ripple_order: tacho ripple periods per worm turn; None → the simulator's sensor model's.
        encoder: "white" or "interval" (see above).
        sample_delays: channel → [s] from the tick to its ADC sampling instant
            ("current_drive", "tacho_drive"); None → worm_rig_driver.sim.sensors.AdcChain's
            (12 us and 116 us): at a reversal the current slews ~20 A/ms and the worm
            ~30000 rad/s², so the instant matters (the measurement is predicted with the
            exact discretisation over that delay).
    """

    def __init__(self, rig: Rig, sample_period: float | None = None, *, noise: NoiseFigures | None = None,
                 load: LoadProcess | None = None, torque_limit: float | None = None,
                 speed_limit: float | None = None, ripple_order: int | None = None,
                 encoder: str = "white", sample_delays: dict[str, float] | None = None) -> None:
        from worm_rig_driver.sim.sensors import TACHO_RIPPLE_ORDER, AdcChain

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
        self.ripple_order = TACHO_RIPPLE_ORDER if ripple_order is None else int(ripple_order)
        #: [s] from the tick to each analogue channel's sampling instant (the firmware's ADC sequence)
        self.delays = dict(AdcChain().sample_times()) if sample_delays is None else dict(sample_delays)
        self.theta_lsb = 2.0 * self.noise.theta_offset
        self.q = self.load.intensity(rig) * self.period
        self.threshold = self.load.threshold()
        self.window = int(self.load.window)
        self._steps: dict[tuple[float, float], _Step] = {}  # by (J_eff / J_w to 4 decimals, period)
        self._inertia = inertia_terms(rig)  # J_eff = first + second·K_s
        self._back_emf = rig.drive_motor.back_emf_constant
        self._emf_drift = self.load.back_emf_drift ** 2 * self.period  # δ's random walk over a period
        # measurement covariances that do not change from sample to sample
        self._r_white = np.diag([self.noise.theta_var, self.noise.tacho_var, self.noise.current_var])
        self._r_no_encoder = np.diag([self.noise.tacho_var, self.noise.current_var])
        self.x = np.zeros(N_STATES)  # prior for the next sample
        self.P = np.eye(N_STATES)
        self.initialised = False
        self.voltage = 0.0  # last valid voltage [V]
        self._phi_prev: np.ndarray | None = None
        self._clear_glr()
        self.p_reference = math.inf  # τ_d variance before the last jump (TRANSIENT test)
        self.jumps = 0  # detections so far
        self.samples = 0
        self.restarts = 0  # samples the filter was restarted from (RESTART_NIS, restart())

    # --- internals --------------------------------------------------------------------------
    def _clear_glr(self) -> None:
        self._sig = np.empty((0, N_STATES))
        self._d = np.empty(0)
        self._c = np.empty(0)

    def _step(self, factor: float, period: float) -> _Step:
        """The discretisation over ``period`` [s] for the inertia of flank factor K_s (Eq. 28), cached:
        J_eff rounded to 4 decimals of the rigid inertia, and the bin's own value discretised, so the
        result is a function of the state alone, not of which J_eff the filter met first (a replay
        that starts later than the live node must reproduce it to the bit)."""
        rigid, geared = self._inertia
        ratio = round((rigid + geared * factor) / rigid, 4)  # effective_inertia, binned
        key = (ratio, period)
        step = self._steps.get(key)
        if step is None:
            step = self._steps[key] = _Step(discretise(self.rig, ratio * rigid, period))
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
    def update(self, voltage: float, current: float, omega: float, theta: float | None = None) -> ObserverEstimate:
        """Feed one sample: V [V] applied from this tick on, i [A], tacho ω [rad/s], encoder θ [rad]
        (the floored count × lsb, as RigSample.theta_worm; None: no encoder). Returns the
        estimate at this sample; never raises for NaN/inf (flagged INVALID_INPUT)."""
        self.samples += 1
        for v in (voltage, current, omega) if theta is None else (voltage, current, omega, theta):
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                return self._invalid(voltage)
        voltage, current, omega = float(voltage), float(current), float(omega)
        theta = None if theta is None else float(theta)
        if not self.initialised:
            self._initialise(current, omega, theta)
        for restarted in (False, True):
            nu, h, R = self._measurement(current, omega, theta, voltage)
            x, P = self.x, self.P
            PhT = P @ h.T
            S = h @ PhT + R
            s_inv = _inverse(S)
            if restarted or float(nu @ s_inv @ nu) <= RESTART_NIS:
                break
            # (also NaN) not this rig's continuation: start again from this sample
            self.restarts += 1
            self._clear_glr()
            self._phi_prev = None
            self._initialise(current, omega, theta)
        K = PhT @ s_inv
        xf = x + K @ nu
        Pf = P - K @ PhT.T  # K S K' = P H' S⁻¹ H P (P symmetric)
        jump = self._glr(h, nu, s_inv, K, xf, Pf)
        if jump is not None:
            xf, Pf = jump
        self.x, self.P = xf, 0.5 * (Pf + Pf.T)
        mesh = self.map.mesh(float(xf[OMEGA]), float(xf[TAU]))  # for both the estimate and the prediction
        estimate = self._estimate(jump is not None, 0, mesh)
        self.voltage = voltage
        self._predict(voltage, mesh)
        return estimate

    def _glr(self, h, nu, s_inv, K, xf, Pf):
        """Willsky-Jones GLR over the last ``window`` onsets; returns corrected (x, P) on a jump."""
        if self._phi_prev is None or self.window < 1:
            return None
        phi = self._phi_prev
        # each stored onset's filtered signature through the last period, plus the newest onset
        # (a unit jump of τ_d during the last period): its prior error is phi's τ_d column.
        # The oldest onset leaves the window; oldest first, as argmax breaks ties by the first.
        keep = min(len(self._d), self.window - 1)
        sig = np.empty((keep + 1, N_STATES))
        np.matmul(self._sig[len(self._sig) - keep:], phi.T, out=sig[:keep])
        sig[keep] = phi[:, TAU]
        g = sig @ h.T  # innovation signatures (onsets, measurements)
        gs = g @ s_inv
        d = gs @ nu  # the newest onset starts from 0
        d[:keep] += self._d[len(self._d) - keep:]
        c = (gs * g).sum(axis=1)
        c[:keep] += self._c[len(self._c) - keep:]
        filtered = sig - g @ K.T  # filtered-state error signatures
        stat = np.zeros(keep + 1)
        np.divide(d * d, c, out=stat, where=c > 0)
        best = int(np.argmax(stat))
        if stat[best] > self.threshold:
            delta = d[best] / c[best]
            f = filtered[best]
            self.p_reference = float(Pf[TAU, TAU])
            self.jumps += 1
            self._clear_glr()
            return xf + f * delta, Pf + np.outer(f, f) / c[best]
        self._sig, self._d, self._c = filtered, d, c  # propagated through the next period's phi
        return None

    def _estimate(self, jump: bool, extra_flags: int, mesh: tuple | None = None) -> ObserverEstimate:
        """The estimate at the filtered state; mesh: StaticLoadMap.mesh there if the caller has it."""
        x, P = self.x, self.P
        omega, tau = float(x[OMEGA]), float(x[TAU])
        u = math.sqrt(max(float(P[TAU, TAU]), 0.0))
        t_dist, _slope, _flank, _factor, mu = self.map.mesh(omega, tau) if mesh is None else mesh
        flags = extra_flags
        if abs(omega) > STANDSTILL and mu > self.map.self_locking_mu:
            driving, coast, _f, _c = self.map.invert(omega, t_dist)
            branches = [float(b) for b in (driving, coast) if math.isfinite(float(b))]
            if len(branches) == 2:
                flags |= EstimateFlags.AMBIGUOUS
                u = max(u, max(abs(b - tau) for b in branches))
        if abs(tau) - 2.0 * u > self.torque_limit or abs(omega) > self.speed_limit:
            flags |= EstimateFlags.OUT_OF_CALIBRATION
        if self.p_reference == math.inf:
            self.p_reference = self.steady_variance(omega, tau)
        if float(P[TAU, TAU]) > 2.0 * self.p_reference:
            flags |= EstimateFlags.TRANSIENT
        return ObserverEstimate(tau, u, int(flags), omega, float(x[CURRENT]), t_dist, jump)

    def skip(self, samples: int) -> None:
        """``samples`` rig samples were lost: predict over them with the last voltage, no
        measurement (what the rig did meanwhile is unknown; the covariance grows accordingly).
        More than MAX_SKIP: :meth:`restart` instead (the state would be a guess)."""
        if samples <= 0 or not self.initialised:
            return
        if samples > MAX_SKIP:
            self.restart()
            return
        self._clear_glr()
        self._phi_prev = None  # no GLR onset across the gap
        for _ in range(samples):
            self._predict(self.voltage)

    def restart(self) -> None:
        """Forget the state: the next sample initialises the filter (a new rig session)."""
        self.initialised = False
        self._clear_glr()
        self._phi_prev = None
        self.p_reference = math.inf

    def _invalid(self, voltage) -> ObserverEstimate:
        bad = int(EstimateFlags.INVALID_INPUT)
        if not self.initialised:
            return ObserverEstimate(math.nan, math.nan, bad, math.nan, math.nan, math.nan)
        self._clear_glr()
        est = self._estimate(False, bad)
        v = float(voltage) if isinstance(voltage, (int, float)) and math.isfinite(voltage) else self.voltage
        self._predict(v)
        self._phi_prev = None  # no GLR onset across a missing sample
        return est

    # --- analysis ---------------------------------------------------------------------------
    def steady_variance(self, omega: float, tau_d: float) -> float:
        """Steady τ_d variance [(N m)²] of the filter (DARE, white-noise model) linearised at (ω, τ_d)."""
        noise = self.noise.without_ripple()
        return float(steady_filter(self.rig, omega, tau_d, self.period, noise, self.q)[2][3, 3])


# ----------------------------------------------------------------------------------------------
# steady-state analysis and the Cramér-Rao-type bound
def linearised(rig: Rig, omega: float, tau_d: float, period: float) -> np.ndarray:
    """Φ (4×4) of the observer's model linearised at (ω, τ_d)."""
    smap = StaticLoadMap(rig)
    _t, slope, flank = smap.worm_torque(omega, tau_d)
    inertia = effective_inertia(rig, float(smap.mu(omega)), flank)
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


def predicted_noise(rig: Rig, omega: float, tau_d: float, *, period: float | None = None,
                    noise: NoiseFigures | None = None, load: LoadProcess | None = None) -> float:
    """Std [N m] of the steady observer's τ̂_d for a CONSTANT load (measurement noise only).

    The filtered error obeys e⁺ = (I − K H) Φ e⁺ − K v; its covariance X solves the
    Lyapunov equation X = F X F' + K R K' with F = (I − K H) Φ.
    """
    period = period or 1.0 / rig.sensors.sample_rate_hz
    noise = noise or NoiseFigures.from_rig(rig).without_ripple()
    q = (load or LoadProcess()).intensity(rig) * period
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
    period = period or 1.0 / rig.sensors.sample_rate_hz
    noise = noise or NoiseFigures.from_rig(rig).without_ripple()
    q = (load or LoadProcess()).intensity(rig) * period
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
    period = period or 1.0 / rig.sensors.sample_rate_hz
    noise = noise or NoiseFigures.from_rig(rig).without_ripple()
    q = (load or LoadProcess()).intensity(rig) * period
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
    period = period or 1.0 / rig.sensors.sample_rate_hz
    noise = noise or NoiseFigures.from_rig(rig).without_ripple()
    q = (load or LoadProcess()).intensity(rig) * period
    phi, K, _pf, prior = steady_filter(rig, omega, tau_d, period, noise, q)
    s_inv = np.linalg.inv(H @ prior @ H.T + noise.measurement_covariance(omega))
    err = phi @ np.array([0, 0, 0, 1.0])
    info, out = 0.0, []
    for _ in range(samples):
        g = H @ err
        info += float(g @ s_inv @ g)
        out.append(1.0 / math.sqrt(info))
        err = phi @ (err - K @ g)
    return np.array(out)


# ----------------------------------------------------------------------------------------------
# registry front end
class ObserverEstimator:
    """The observer as a registry estimator (estimator.ESTIMATORS["observer"]).

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

    name = "observer"

    def __init__(self, database: CalibrationDatabase | None = None, rig_file: str | None = None,
                 model_file: str | None = None, *, rig: Rig | None = None, load: LoadProcess | None = None,
                 calibration_bias: bool = True) -> None:
        self.rig = rig if rig is not None else load_rig(model_file or rig_file or None)
        self.correction = SensorCorrection.of(ExtendedModel.load(model_file)) if model_file and rig is None \
            else SensorCorrection()
        self.load = load or LoadProcess()
        self.map = StaticLoadMap(self.rig)
        self.noise = NoiseFigures.from_rig(self.rig)
        limit, speed = self.rig.max_load_torque, None
        ranges = identification_ranges(model_file) if model_file and rig is None else None
        if ranges is not None:
            limit = max(limit, abs(ranges["torque_min"]), abs(ranges["torque_max"]))
            speed = 1.1 * ranges["speed_max"]
        elif database is not None and len(database):
            limit = max(limit, float(np.max(np.abs(database.tau_load))))
            speed = 1.1 * float(np.max(np.abs(database.omega_worm)))
        self.torque_limit = limit
        self.speed_limit = speed
        self.bias = CalibrationBias(self._model_estimate, database) \
            if calibration_bias and database is not None and len(database) else None

    def stream(self, sample_period: float | None = None) -> LoadObserver:
        """A fresh streaming observer with this estimator's model and limits (and calibration bias)."""
        stream = LoadObserver(self.rig, sample_period, load=self.load, torque_limit=self.torque_limit,
                              speed_limit=self.speed_limit)
        if self.correction != SensorCorrection():
            stream = _CorrectedStream(stream, self.correction)
        return stream if self.bias is None else _BiasedStream(stream, self.bias)

    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """Quasi-static τ_d [N m] from ω [rad/s] and the inertia-free current i [A]; never raises."""
        out = self._model_estimate(omega_worm, current_drive)
        if self.bias is None:
            return out
        w = np.broadcast_to(np.asarray(omega_worm, dtype=float), out.torque.shape)
        return TorqueEstimates(out.torque + self.bias.array(w, out.torque), out.uncertainty, out.flags)

    def _model_estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike) -> TorqueEstimates:
        """The model's own quasi-static inverse (no calibration bias)."""
        w, i = np.broadcast_arrays(np.asarray(omega_worm, dtype=float), np.asarray(current_drive, dtype=float))
        valid = np.isfinite(w) & np.isfinite(i)
        ws, is_ = np.where(valid, w, 0.0), np.where(valid, self.correction.current(i), 0.0)
        motor = self.rig.drive_motor
        t_dist = motor.torque_constant * is_ - motor.viscous_drag * ws
        driving, coast, flags, chosen = self.map.invert(ws, t_dist)
        k_plus, k_minus = self.map.factors(ws)
        slope = self.map.k * np.where(np.isfinite(driving) & (chosen == driving), k_plus, np.abs(k_minus))
        with np.errstate(divide="ignore", invalid="ignore"):
            u = motor.torque_constant * math.sqrt(self.noise.current_var) / slope
        other = np.where(chosen == driving, coast, driving)
        u = np.where(flags & int(EstimateFlags.AMBIGUOUS), np.maximum(u, np.abs(other - chosen)), u)
        out = (np.abs(chosen) > self.torque_limit) | (np.abs(ws) > (self.speed_limit or np.inf))
        flags = flags | np.where(out, int(EstimateFlags.OUT_OF_CALIBRATION), 0)
        torque = np.where(valid, self.correction.load(chosen), np.nan)
        u = np.where(valid, u, np.nan)
        flags = np.where(valid, flags, int(EstimateFlags.INVALID_INPUT)).astype(np.int64)
        return TorqueEstimates(torque, u, flags)


class _CorrectedStream:
    """A LoadObserver fed the drive current corrected for the identified sensor errors, its estimate taken
    back to the true load (ObserverEstimator's ``model_file``); the plain observer when there are none."""

    def __init__(self, stream: LoadObserver, correction: SensorCorrection) -> None:
        self.stream = stream
        self.correction = correction
        self._gain = 1.0 / (1.0 + correction.drive_gain)

    def update(self, voltage: float, current: float, omega: float, theta: float | None = None) -> ObserverEstimate:
        c = self.correction
        est = self.stream.update(voltage, (current - c.drive_offset) * self._gain, omega, theta)
        torque = est.torque - (c.load_gain * est.torque + c.load_offset)
        return replace(est, torque=torque)

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


class _BiasedStream:
    """A stream whose estimate gets the calibration's bias at its own speed and torque (ObserverEstimator)."""

    def __init__(self, stream, bias: CalibrationBias) -> None:
        self.stream = stream
        self.bias = bias

    def update(self, voltage: float, current: float, omega: float, theta: float | None = None) -> ObserverEstimate:
        est = self.stream.update(voltage, current, omega, theta)
        if not math.isfinite(est.torque):
            return est
        return replace(est, torque=est.torque + self.bias(est.omega_worm, est.torque))

    def __getattr__(self, name: str):
        return getattr(self.stream, name)


__all__ = ["STANDSTILL", "NoiseFigures", "LoadProcess", "StaticLoadMap", "effective_inertia", "discretise",
           "ObserverEstimate", "LoadObserver", "steady_filter", "predicted_noise", "equivalent_window",
           "steady_state_bound", "jump_bound", "interval_measurement", "ObserverEstimator"]
