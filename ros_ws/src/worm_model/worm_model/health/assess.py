"""Comparing checks: the baseline, the temperature law the checks teach, and the verdict on each new check.

Baseline: the first ``limits.baseline_checks`` checks of a gearbox (or, when asked, the rig file's
values). Its shape (fit.SHAPE: mu's speed and load laws, the gear's viscous drag: the weighted mean
of the baseline checks' own fits) is then held, to within what may drift between two checks
(settings.Priors' drift_* widths), when any check of the gearbox is watched (:func:`watched_fit`:
the check's points fitted again around that shape): mu's scale is then decided to ~1.3 % per check
instead of ~1.5 %, and the same way for every check.

mu's temperature law f_T(T) = 1 + k (T - T_ref) (model.TemperatureLaw) is learned with the baseline's
level s_ref, by weighted least squares with the prior of settings.TemperaturePrior on k, from the
baseline checks and every later check that raised no alarm and lies within :data:`SUSPECT_Z` sigmas
of the baseline under the baseline's own law:

    s_T,i = L_i f_T(T_i)      L_i = s_ref (baseline checks), s_ref + d (a_i - a_0) (later checks)

s_T,i the watched mu scale at the check's oil temperature T_i (its uncertainty sigma_T adds
k sigma_T), a_i its age (hours run where every check has them, else its place in the trend), d a
slow drift the later checks may show (so that wear is not read as temperature). A warm gearbox is
not a worn one: the compensation is the model's, the alarm limits do not widen for it.

A check i is compared on mu's scale at the reference temperature, Delta_i = s_T,i / (f_T(T_i) s_ref) - 1,
its variance from the check's fit, its temperature's uncertainty and the joint (s_ref, k)
covariance; on the drive- and gear-side drag torques at ``limits.drag_speed`` and the backlash,
against the baseline checks' weighted means. The trend is the weighted mean of Delta over the last
``limits.trend_window`` checks after the baseline (the baseline's errors are common to all of them
and are not averaged away). A quantity alarms when its change is both beyond its limit and sure
(z = change / sigma >= limits.z_min): WARN or ERROR (settings.Limits). Only rises alarm.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from worm_model.health.fit import SHAPE, fit_points
from worm_model.health.model import NAMES, HealthParameters, TemperatureLaw
from worm_model.health.record import CheckRecord
from worm_model.health.settings import HealthSettings, Limits
from worm_model.physics.parameters import Rig

#: the 95 % interval's half-width in standard uncertainties (the text's "+-")
Z95 = 1.96
#: relative uncertainty given to the rig file's values when they are the baseline (assumption: the rig
#: file was identified with another model; its values are the health model's only to within ~10 %)
RIG_FILE_ALLOWANCE = 0.1
ORDER = {"OK": 0, "WARN": 1, "ERROR": 2}
#: a later check whose mu scale is this many sigmas from the baseline's does not teach the temperature law
SUSPECT_Z = 2.0


@dataclass(frozen=True)
class Estimate:
    """A value and its standard uncertainty."""

    value: float
    sigma: float

    def __str__(self) -> str:
        return f"{self.value:.4g} +- {Z95 * self.sigma:.2g}"


@dataclass
class Baseline:
    """What later checks are compared with (module docstring)."""

    source: str
    mu_scale: float  # s_ref: mu's scale at the reference temperature
    covariance: np.ndarray  # (2, 2) of (s_ref, k)
    law: TemperatureLaw
    drive_drag: Estimate  # [N m] at limits.drag_speed
    gear_drag: Estimate  # [N m] at limits.drag_speed, on the gear shaft
    backlash: Estimate  # [rad] (NaN value: not seen)
    shape: HealthParameters | None  # the baseline's mean parameters (fit.SHAPE held by watched_fit); None: rig file
    parameters: HealthParameters  # the baseline's health parameters, mu_scale at the reference temperature
    count: int
    temperature_span: float  # [K] the checks that taught k span
    learned_from: int = 0  # checks the law was learned from


@dataclass(frozen=True)
class Finding:
    """One compared quantity: its change against the baseline and the level it raises."""

    quantity: str
    change: float  # relative
    sigma: float  # of the change
    level: str
    text: str


@dataclass
class Assessment:
    """The verdict on one check: its level and the findings behind it."""

    level: str
    findings: list[Finding] = field(default_factory=list)
    mu_change: Estimate | None = None  # this check's Delta
    trend_change: Estimate | None = None  # the trend's mean Delta (None: not enough checks yet)

    @property
    def lines(self) -> list[str]:
        return [f.text for f in self.findings]


def drag_torques(record: CheckRecord, speed: float, ratio: float) -> tuple[Estimate, Estimate]:
    """(drive drag, gear drag) torques [N m] at worm speed ``speed`` [rad/s] (the gear at ratio x speed),
    their sigmas from the record's covariance."""
    cov = np.asarray(record.covariance)
    p = record.parameters
    out = []
    for coulomb, viscous, w in (("drive_coulomb", "drive_viscous", speed),
                                ("gear_coulomb", "gear_viscous", ratio * speed)):
        g = np.zeros(len(NAMES))
        g[NAMES.index(coulomb)], g[NAMES.index(viscous)] = 1.0, w
        value = getattr(p, coulomb) + getattr(p, viscous) * w
        out.append(Estimate(float(value), float(math.sqrt(max(g @ cov @ g, 0.0)))))
    return out[0], out[1]


def _weighted(values: np.ndarray, sigmas: np.ndarray) -> Estimate:
    """Weighted mean, its sigma scaled by the Birge ratio where the values scatter more than their sigmas."""
    ok = np.isfinite(values) & np.isfinite(sigmas) & (sigmas > 0)
    if not ok.any():
        return Estimate(math.nan, math.nan)
    v, s = values[ok], sigmas[ok]
    w = 1.0 / s ** 2
    mean = float((w * v).sum() / w.sum())
    sigma = math.sqrt(1.0 / w.sum())
    if ok.sum() > 1:
        sigma *= math.sqrt(max(1.0, float((w * (v - mean) ** 2).sum()) / (ok.sum() - 1)))
    return Estimate(mean, sigma)


def shape_of(records: list[CheckRecord]) -> HealthParameters:
    """The baseline's parameters: each the weighted mean of the checks' own fits."""
    mean = []
    for name in NAMES:
        est = _weighted(np.array([getattr(r.parameters, name) for r in records]),
                        np.array([r.sigma[name] for r in records]))
        mean.append(est.value if math.isfinite(est.value) else getattr(records[0].parameters, name))
    return HealthParameters.from_vector(mean)


def watched_fit(record: CheckRecord, shape: HealthParameters | None, rig: Rig,
                settings: HealthSettings) -> tuple[float, float]:
    """(mu scale at the check's temperature, its sigma) with the gearbox's shape held (module docstring).

    The check's points are fitted again (once per shape; cached on the record); a record without its
    points, or no shape, gives its own fit's values.
    """
    if shape is None or record.steady_points is None or len(record.steady_points) < 3:
        return record.parameters.mu_scale, record.sigma["mu_scale"]
    key = tuple(round(getattr(shape, name), 12) for name in SHAPE)
    if key not in record.cache:
        fit = fit_points(record.steady_points, rig, HealthParameters.from_rig(rig), settings.priors, shape=shape)
        record.cache[key] = (fit.parameters.mu_scale, fit.sigma["mu_scale"])
    return record.cache[key]


def _age(records: list[CheckRecord]) -> np.ndarray:
    hours = np.array([r.hours for r in records])
    return hours if np.all(np.isfinite(hours)) else np.arange(len(records), dtype=float)


def learn_law(scales: np.ndarray, sigmas: np.ndarray, temperatures: np.ndarray, temperature_sigmas: np.ndarray,
              later: np.ndarray, age: np.ndarray, settings: HealthSettings) -> tuple[float, np.ndarray, float]:
    """(s_ref, cov of (s_ref, k), k) from checks (module docstring); ``later`` marks the checks after the baseline."""
    prior = settings.temperature
    dt = temperatures - prior.reference
    drift = int(later.sum()) >= 3
    a = np.where(later, age - (age[~later].max() if (~later).any() else 0.0), 0.0)
    s, d, k = float(np.mean(scales)), 0.0, prior.mu_per_kelvin
    normal = np.eye(3)
    for _ in range(10):
        f = 1.0 + k * dt
        level = s + d * a
        w = 1.0 / (sigmas ** 2 + (level * k * temperature_sigmas) ** 2)
        jac = np.column_stack([f, a * f, level * dt])
        r = scales - level * f
        normal = jac.T @ (w[:, None] * jac) + np.diag([0.0, 0.0 if drift else 1e12, 1.0 / prior.sigma ** 2])
        rhs = jac.T @ (w * r) + np.array([0.0, -d * (0.0 if drift else 1e12), (prior.mu_per_kelvin - k)
                                          / prior.sigma ** 2])
        step = np.linalg.solve(normal, rhs)
        s, d, k = s + step[0], d + step[1], k + step[2]
    cov = np.linalg.inv(normal)
    level = s + d * a
    chi2 = float(((scales - level * (1.0 + k * dt)) ** 2 / (sigmas ** 2 + (level * k * temperature_sigmas) ** 2)).sum())
    dof = len(scales) - 1 - int(drift)
    if dof >= 2:
        cov = cov * max(1.0, chi2 / dof)
    return float(s), cov[np.ix_([0, 2], [0, 2])], float(k)


def baseline_of(records: list[CheckRecord], settings: HealthSettings, rig: Rig) -> Baseline:
    """The baseline (the first limits.baseline_checks of ``records``) with the law learned from ``records``:
    the baseline checks and the later ones that raised no alarm (module docstring).

    Raises:
        ValueError: no records.
    """
    if not records:
        raise ValueError("no checks to make a baseline of")
    n = min(settings.limits.baseline_checks, len(records))
    base = records[:n]
    shape = shape_of(base)
    use = base + [r for r in records[n:] if r.level == "OK"]
    watched = np.array([watched_fit(r, shape, rig, settings) for r in use])
    t = np.array([r.temperature.value for r in use])
    t_sigma = np.array([r.temperature.sigma for r in use])
    later = np.arange(len(use)) >= n
    age = _age(use)
    s_ref, cov, k = learn_law(watched[:n, 0], watched[:n, 1], t[:n], t_sigma[:n], later[:n], age[:n], settings)
    if later.any():
        # a later check teaches the law only if it looks like the baseline's gearbox (|z| < SUSPECT_Z under
        # the baseline's own law): one that changed but raised no alarm would pull k (a warm, worn check
        # reads as a weaker temperature law)
        f = 1.0 + k * (t - settings.temperature.reference)
        z = (watched[:, 0] / f - s_ref) / np.hypot(watched[:, 1] / f, math.sqrt(cov[0, 0]))
        keep = ~later | (np.abs(z) < SUSPECT_Z)
        use = [r for r, ok in zip(use, keep) if ok]
        watched, t, t_sigma, later, age = watched[keep], t[keep], t_sigma[keep], later[keep], age[keep]
        s_ref, cov, k = learn_law(watched[:, 0], watched[:, 1], t, t_sigma, later, age, settings)
    prior = settings.temperature
    span = float(t.max() - t.min())
    source = f"learned from {len(use)} checks over {span:.0f} K" if span >= prior.min_span else "prior"
    law = TemperatureLaw(prior.reference, k, float(math.sqrt(cov[1, 1])), source)
    speed = settings.limits.drag_speed
    drags = [drag_torques(r, speed, rig.gearbox.ratio) for r in base]
    drive = _weighted(np.array([d[0].value for d in drags]), np.array([d[0].sigma for d in drags]))
    gear = _weighted(np.array([d[1].value for d in drags]), np.array([d[1].sigma for d in drags]))
    backlash = _weighted(np.array([r.backlash for r in base]), np.array([r.backlash_sigma for r in base]))
    return Baseline(f"first {n} check{'s' if n > 1 else ''}", s_ref, cov, law, drive, gear, backlash, shape,
                    replace(shape, mu_scale=s_ref), n, span, len(use))


def baseline_from_rig(rig: Rig, settings: HealthSettings) -> Baseline:
    """The rig file's values as the baseline, each to within :data:`RIG_FILE_ALLOWANCE` (relative)."""
    p = HealthParameters.from_rig(rig)
    prior = settings.temperature
    law = TemperatureLaw(prior.reference, prior.mu_per_kelvin, prior.sigma, "prior")
    speed = settings.limits.drag_speed
    drive = p.drive_coulomb + p.drive_viscous * speed
    gear = p.gear_coulomb + p.gear_viscous * speed * rig.gearbox.ratio
    a = RIG_FILE_ALLOWANCE
    return Baseline("rig file", 1.0, np.diag([a ** 2, prior.sigma ** 2]), law, Estimate(drive, a * drive),
                    Estimate(gear, a * gear), Estimate(math.nan, math.nan), None, p, 0, 0.0)


def mu_change(record: CheckRecord, baseline: Baseline, rig: Rig, settings: HealthSettings
              ) -> tuple[float, float, np.ndarray]:
    """(Delta, the variance of the check's own errors, its gradient on the baseline's (s_ref, k))."""
    law = baseline.law
    dt = record.temperature.value - law.reference
    f = max(1.0 + law.mu_per_kelvin * dt, 0.1)
    s_t, sigma = watched_fit(record, baseline.shape, rig, settings)
    ratio = s_t / (f * baseline.mu_scale)
    own = ratio ** 2 * ((sigma / s_t) ** 2 + (law.mu_per_kelvin * record.temperature.sigma / f) ** 2)
    gradient = np.array([-ratio / baseline.mu_scale, -ratio * dt / f])
    return ratio - 1.0, own, gradient


def _level(change: float, sigma: float, warn: float, error: float, z_min: float, floor_ok: bool = True) -> str:
    if not (floor_ok and sigma > 0 and change / sigma >= z_min):
        return "OK"
    return "ERROR" if change > error else ("WARN" if change > warn else "OK")


def worst(levels) -> str:
    """The highest of some levels ("OK" for none)."""
    return max(levels, key=lambda x: ORDER[x], default="OK")


def assess(record: CheckRecord, baseline: Baseline, earlier: list[CheckRecord], settings: HealthSettings,
           rig: Rig) -> Assessment:
    """The verdict on ``record`` against ``baseline``; ``earlier``: the checks after the baseline before it."""
    limits: Limits = settings.limits
    findings = []
    delta, own, grad = mu_change(record, baseline, rig, settings)
    mu = Estimate(delta, math.sqrt(own + grad @ baseline.covariance @ grad))
    level = _level(delta, mu.sigma, limits.check_warn, limits.check_error, limits.z_min)
    law = baseline.law
    findings.append(Finding("mu_scale", delta, mu.sigma, level,
                            f"mu scale {delta:+.1%} +- {Z95 * mu.sigma:.1%} of the baseline at {law.reference:g} degC "
                            f"(oil {record.temperature.value:.1f} +- {Z95 * record.temperature.sigma:.1f} degC, "
                            f"{record.temperature.source}; k = {law.mu_per_kelvin:+.4f} +- {Z95 * law.sigma:.4f}/K, "
                            f"{law.source}){_say(level)}"))
    trend = None
    window = (earlier + [record])[-limits.trend_window:]
    if len(window) >= 2:
        parts = [mu_change(r, baseline, rig, settings) for r in window]
        w = np.array([1.0 / p[1] for p in parts])
        mean = float(sum(wi * p[0] for wi, p in zip(w, parts)) / w.sum())
        g = sum(wi * p[2] for wi, p in zip(w, parts)) / w.sum()
        trend = Estimate(mean, math.sqrt(1.0 / w.sum() + g @ baseline.covariance @ g))
        t_level = _level(mean, trend.sigma, limits.trend_warn, limits.trend_error, limits.z_min)
        findings.append(Finding("mu_scale_trend", mean, trend.sigma, t_level,
                                f"mu scale over the last {len(window)} checks {mean:+.1%} +- "
                                f"{Z95 * trend.sigma:.1%}{_say(t_level)}"))
    drive, gear = drag_torques(record, limits.drag_speed, rig.gearbox.ratio)
    for name, now, base in (("drive_drag", drive, baseline.drive_drag), ("gear_drag", gear, baseline.gear_drag)):
        if not (math.isfinite(base.value) and base.value > 0):
            continue
        change = (now.value - base.value) / base.value
        sigma = math.hypot(now.sigma, base.sigma) / base.value
        d_level = _level(change, sigma, limits.drag_warn, limits.drag_error, limits.z_min,
                         now.value - base.value > limits.drag_floor)
        side = "drive-side (worm shaft)" if name == "drive_drag" else "gear-side"
        findings.append(Finding(name, change, sigma, d_level,
                                f"{side} drag at {limits.drag_speed:g} rad/s {1e3 * now.value:.2f} mN m, "
                                f"{change:+.0%} +- {Z95 * sigma:.0%} of the baseline{_say(d_level)}"))
    if math.isfinite(record.backlash) and math.isfinite(baseline.backlash.value) and baseline.backlash.value > 0:
        base = baseline.backlash
        change = (record.backlash - base.value) / base.value
        sigma = math.hypot(record.backlash_sigma, base.sigma) / base.value
        b_level = _level(change, sigma, limits.backlash_warn, limits.backlash_error, limits.z_min,
                         record.backlash - base.value > limits.backlash_floor)
        findings.append(Finding("backlash", change, sigma, b_level,
                                f"backlash {math.degrees(record.backlash) * 60:.1f} arcmin, {change:+.0%} +- "
                                f"{Z95 * sigma:.0%} of the baseline{_say(b_level)}"))
    return Assessment(worst(f.level for f in findings), findings, mu, trend)


def _say(level: str) -> str:
    return "" if level == "OK" else f"  [{level}]"


def assess_trend(records: list[CheckRecord], settings: HealthSettings, rig: Rig,
                 fixed: Baseline | None = None) -> list[Assessment | None]:
    """Every check of a trend assessed in order, as health_check did when each was added (each record's
    ``level`` and ``findings`` are set); None for the baseline checks. ``fixed``: compare every check with this
    baseline (e.g. :func:`baseline_from_rig`) instead of the trend's first checks."""
    n = 0 if fixed is not None else settings.limits.baseline_checks
    out: list[Assessment | None] = []
    for i, record in enumerate(records):
        if i < n:
            record.level, record.findings = "OK", [f"baseline check {i + 1} of {n}"]
            out.append(None)
            continue
        baseline = fixed if fixed is not None else baseline_of(records[:i], settings, rig)
        result = assess(record, baseline, records[n:i], settings, rig)
        record.level, record.findings = result.level, result.lines
        out.append(result)
    return out


__all__ = ["Assessment", "Baseline", "Estimate", "Finding", "RIG_FILE_ALLOWANCE", "Z95", "assess", "assess_trend",
           "baseline_from_rig", "baseline_of", "drag_torques", "learn_law", "mu_change", "shape_of", "watched_fit",
           "worst"]
