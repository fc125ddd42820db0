"""A health check's fit: what wears, with intervals, from the steady points of one short run.

Least squares of the points' torques against :func:`worm_model.health.model.input_torque`, with a
Gaussian prior on every parameter around its reference value (the rig file's: every check of a
gearbox is fitted alike, so that their differences are the gearbox's, not the priors'):

    minimise  sum_j ((T_j - T_model(omega_j, tau_j + R_j; theta)) / sigma_j)^2 + sum_k ((theta_k - theta0_k) / w_k)^2

sigma_j is the point's standard error with the model floor (settings.Priors.model_floor) added in
quadrature, w_k the prior's width (settings.Priors). The wheel runout's ripple is a nuisance: a
gear-side torque once per gear turn, (a_s + l_s |D_mesh|) S_j + (a_c + l_c |D_mesh|) C_j added to the
point's load (so reflected through the engaged flank's factor like the load), S_j, C_j the point's
means of sin and cos of the gear angle; at low speed a point lasts less than a gear turn and would
otherwise keep a random part of it. What the run excites is decided by the data; what it
does not (e.g. mu's load slope on a robot with no load) stays at the reference with the prior's
width, and is reported as not identified (its interval shrank by less than half).

The uncertainties (``sigma``, ``covariance``) are the inverse normal matrix's: what the points' noise
leaves, the check's repeatability, which is what comparing two checks needs (the model's own error
at a point is the same in both; on the simulated rig these sigmas are within 15 % of the scatter of
repeated checks). Where the model is not the plant the points scatter more than their noise: the
interval of an absolute value is sigma x sqrt(reduced chi-square) where that exceeds 1
(:meth:`FitResult.interval`).

The fitted mu scale is the one at the run's oil temperature: the temperature law is applied when
checks are compared (worm_model.health.assess), so that a record keeps what was measured.

Backlash, where a gear encoder exists: the transmission error theta_g - i theta_w sits at
-contact x gap / 2 (plus the encoders' zero), contact = sign(D_mesh) the side the teeth touch in
the fixed frame; points whose mesh load is within :data:`FLANK_MARGIN` of zero are left out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from worm_model.health.model import NAMES, HealthParameters, TemperatureLaw, gear_drag, input_torque
from worm_model.health.points import Points
from worm_model.health.settings import Priors
from worm_model.physics.parameters import Rig
from worm_model.errors import FitError

#: points whose gear-side mesh load is within this of zero [N m] give no backlash (the flank is uncertain)
FLANK_MARGIN = 0.02
#: a parameter counts as identified when the data shrank its prior's width by at least this factor
IDENTIFIED_SHRINK = 0.5
#: the nuisance parameters of the wheel runout's ripple (module docstring), after NAMES in the fit
RUNOUT = ("runout_sin", "runout_cos", "runout_load_sin", "runout_load_cos")
#: a gearbox's shape: what a baseline fixes to within settings.Priors' drift_* widths (fit_points' ``shape``)
SHAPE = ("mu_speed_exponent", "mu_load_slope", "gear_viscous")


@dataclass(frozen=True)
class Temperature:
    """The oil temperature of a check [degC], its standard uncertainty [K] and where it comes from."""

    value: float
    sigma: float
    source: str  # "measured", "estimated" or "assumed"

    def to_dict(self) -> dict:
        return {"value": self.value, "sigma": self.sigma, "source": self.source}


@dataclass
class FitResult:
    """The fit of one run (module docstring); SI."""

    parameters: HealthParameters
    sigma: dict[str, float]  # standard uncertainties from the points' noise (module docstring)
    covariance: np.ndarray  # (8, 8) of HealthParameters' vector, likewise
    identified: dict[str, bool]
    runout: float  # [N m] amplitude of the once-per-gear-turn ripple on the gear shaft, at no load
    backlash: float  # [rad] NaN without a gear encoder or without both flanks
    backlash_sigma: float  # [rad]
    rms: float  # [N m] RMS residual of the points
    chi2_red: float
    points: int
    rig_time: float  # [s] of steady points
    speeds: dict[str, list[float]] = field(default_factory=dict)  # "forward"/"backward": [min, max] |omega|
    loads: list[float] = field(default_factory=list)  # [min, max] tau_load
    residuals: np.ndarray | None = None  # [N m] per point

    def interval(self, name: str) -> float:
        """Standard uncertainty of the absolute value of parameter ``name``: sigma x sqrt(max(1, chi2_red))."""
        return self.sigma[name] * math.sqrt(max(1.0, self.chi2_red))


def _prior_widths(priors: Priors) -> np.ndarray:
    return np.array([getattr(priors, name) for name in NAMES]
                    + [priors.runout, priors.runout, priors.runout_load, priors.runout_load], dtype=float)


def fit_points(points: Points, rig: Rig, reference: HealthParameters, priors: Priors = Priors(),
               law: TemperatureLaw = TemperatureLaw(), shape: HealthParameters | None = None) -> FitResult:
    """Fit the points (module docstring); ``law`` refers points of other temperatures to the run's mean.

    ``shape``: a baseline's mu speed exponent, load slope and gear viscous drag; the fit then centres
    their priors there with the narrow widths of settings.Priors (drift_*): what a gearbox's shape
    may drift between checks (assess.watched_fit).

    Raises:
        FitError: fewer than 3 steady points.
    """
    if len(points) < 3:
        raise FitError(f"{len(points)} steady constant-speed point(s) found; a check needs at least 3 (hold each "
                       "speed and load for about a second)")
    p_count = len(NAMES)
    theta0 = np.concatenate([reference.vector(), np.zeros(len(RUNOUT))])
    width = _prior_widths(priors)
    if shape is not None:
        for name in SHAPE:
            theta0[NAMES.index(name)] = getattr(shape, name)
            width[NAMES.index(name)] = getattr(priors, "drift_" + name)
    sigma = np.sqrt(points.torque_sigma ** 2 + priors.model_floor ** 2)
    temperature = points.temperature
    # within the run the law refers the points to the run's mean temperature (a check is short: this
    # is ~1 unless the oil warmed during it); between runs the assessment applies the law
    mean_t = np.nanmean(temperature) if np.isfinite(temperature).any() else math.nan
    factor = law.factor(temperature) / law.factor(mean_t) if np.isfinite(mean_t) else np.ones(len(points))

    def model(theta: np.ndarray) -> np.ndarray:
        p = HealthParameters.from_vector(theta[:p_count])
        a_s, a_c, l_s, l_c = theta[p_count:]
        load = np.abs(points.tau_load + gear_drag(rig, p, points.omega))
        ripple = (a_s + l_s * load) * points.gear_sin + (a_c + l_c * load) * points.gear_cos
        return input_torque(rig, p, points.omega, points.tau_load + ripple, factor)

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.concatenate([(points.torque - model(theta0 + width * x)) / sigma, x])

    # imported at first use: scipy.optimize takes ~0.4 s to import, paid at start by every executable
    from scipy.optimize import least_squares

    solution = least_squares(residuals, np.zeros(len(theta0)), method="trf", xtol=1e-10, ftol=1e-10, gtol=1e-10,
                             max_nfev=200)
    m = len(points)
    data = solution.fun[:m]
    chi2_red = float(data @ data) / max(1, m - len(theta0))
    normal = solution.jac.T @ solution.jac
    try:
        cov_x = np.linalg.inv(normal)
    except np.linalg.LinAlgError:
        cov_x = np.linalg.pinv(normal)
    cov = cov_x * np.outer(width, width)
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    theta = theta0 + width * solution.x
    params = HealthParameters.from_vector(theta[:p_count])
    residual_torque = data * sigma
    backlash, backlash_sigma = _backlash(points, rig, params)
    forward, backward = points.omega[points.omega > 0], -points.omega[points.omega < 0]
    speeds = {name: [float(v.min()), float(v.max())] for name, v in (("forward", forward), ("backward", backward))
              if v.size}
    return FitResult(
        parameters=params, sigma={name: float(s) for name, s in zip(NAMES, std)},
        covariance=cov[:p_count, :p_count],
        identified={name: bool(s < IDENTIFIED_SHRINK * w) for name, s, w in zip(NAMES, std, width)},
        runout=float(math.hypot(theta[p_count], theta[p_count + 1])),
        backlash=backlash, backlash_sigma=backlash_sigma, rms=float(np.sqrt(np.mean(residual_torque ** 2))),
        chi2_red=chi2_red, points=m, rig_time=points.rig_time, speeds=speeds,
        loads=[float(points.tau_load.min()), float(points.tau_load.max())], residuals=residual_torque)


def _backlash(points: Points, rig: Rig, params: HealthParameters) -> tuple[float, float]:
    """(gap [rad], its standard uncertainty) from the transmission error (module docstring); NaN if not seen."""
    d_mesh = points.tau_load + gear_drag(rig, params, points.omega)
    use = np.isfinite(points.te) & (np.abs(d_mesh) > FLANK_MARGIN)
    contact = np.sign(d_mesh[use])
    te = points.te[use]
    plus, minus = te[contact > 0], te[contact < 0]
    if plus.size < 2 or minus.size < 2:
        return math.nan, math.nan
    gap = float(minus.mean() - plus.mean())
    sigma = math.sqrt(plus.var(ddof=1) / plus.size + minus.var(ddof=1) / minus.size)
    return gap, sigma


__all__ = ["FLANK_MARGIN", "FitResult", "IDENTIFIED_SHRINK", "RUNOUT", "SHAPE", "Temperature",
           "fit_points"]
