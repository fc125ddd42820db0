"""Comparing checks: the temperature law learned from the checks, the verdict on a check and on the trend.

Records are made directly with a known truth: mu's scale at the check's oil temperature is
s (1 + k (T - 25)) (1 + rise) plus the check's noise (what a fit of the points would give).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from worm_model.health.assess import (assess, assess_trend, baseline_from_rig, baseline_of, learn_law, mu_change)
from worm_model.health.bound import detection_probability, one_check_sigma
from worm_model.health.fit import Temperature
from worm_model.health.model import NAMES, HealthParameters
from worm_model.health.record import CheckRecord
from worm_model.health.settings import HealthSettings
from worm_model.physics.parameters import load_rig

RIG = load_rig()
SETTINGS = HealthSettings()
K_TRUE, S_TRUE, NOISE = -0.004, 0.95, 0.012


def record(temperature: float, rise: float = 0.0, *, rng: np.random.Generator, drag: float = 1.0,
           temperature_sigma: float = 0.5, source: str = "measured", backlash: float = 0.0044) -> CheckRecord:
    base = HealthParameters.from_rig(RIG)
    scale = S_TRUE * (1 + K_TRUE * (temperature - 25.0)) * (1 + rise) * (1 + rng.normal(0, NOISE))
    params = replace(base, mu_scale=scale, drive_coulomb=base.drive_coulomb * drag)
    sigma = {name: abs(getattr(base, name)) * 0.02 + 1e-6 for name in NAMES}
    sigma["mu_scale"] = NOISE * scale
    cov = np.diag([sigma[name] ** 2 for name in NAMES])
    return CheckRecord(date="d", hours=math.nan, source="test", temperature=Temperature(temperature, temperature_sigma,
                                                                                         source),
                       parameters=params, sigma=sigma, covariance=cov, identified={n: True for n in NAMES}, runout=0.0,
                       backlash=backlash, backlash_sigma=2e-5, points=30, rig_time=20.0, rms=1e-4, chi2_red=1.0)


def healthy_trend(count: int, seed: int = 0) -> list[CheckRecord]:
    rng = np.random.default_rng(seed)
    return [record(t, rng=rng) for t in rng.uniform(25.0, 55.0, count)]


def test_the_temperature_law_is_learned_from_the_checks() -> None:
    records = healthy_trend(25)
    scales = np.array([r.parameters.mu_scale for r in records])
    sigmas = np.array([r.sigma["mu_scale"] for r in records])
    t = np.array([r.temperature.value for r in records])
    s_ref, cov, k = learn_law(scales, sigmas, t, np.full(len(t), 0.5), np.arange(len(t)) >= 5,
                              np.arange(len(t), dtype=float), SETTINGS)
    assert abs(k - K_TRUE) < 3 * math.sqrt(cov[1, 1]) and math.sqrt(cov[1, 1]) < 0.001
    assert abs(s_ref - S_TRUE) < 3 * math.sqrt(cov[0, 0])
    baseline = baseline_of(records, SETTINGS, RIG)
    assert baseline.law.source.startswith("learned from 25 checks")
    assert baseline.count == SETTINGS.limits.baseline_checks


def test_warm_and_cold_healthy_checks_raise_nothing_and_a_rise_does() -> None:
    records = healthy_trend(12, seed=1)
    levels = [a.level for a in assess_trend(records, SETTINGS, RIG) if a is not None]
    assert levels == ["OK"] * 7
    rng = np.random.default_rng(2)
    baseline = baseline_of(records, SETTINGS, RIG)
    earlier = records[SETTINGS.limits.baseline_checks:]
    for temperature in (22.0, 50.0):
        ten = assess(record(temperature, 0.10, rng=rng), baseline, earlier, SETTINGS, RIG)
        assert ten.level == "WARN", ten.lines
        assert ten.mu_change.value == pytest.approx(0.10, abs=4 * ten.mu_change.sigma)
        big = assess(record(temperature, 0.30, rng=rng), baseline, earlier, SETTINGS, RIG)
        assert big.level == "ERROR", big.lines
        drop = assess(record(temperature, -0.15, rng=rng), baseline, earlier, SETTINGS, RIG)
        assert drop.level == "OK" and drop.mu_change.value < -0.08  # reported, never alarmed


def test_a_small_rise_shows_in_the_trend_before_any_one_check() -> None:
    records = healthy_trend(9, seed=3)
    rng = np.random.default_rng(4)
    records += [record(t, 0.05, rng=rng) for t in rng.uniform(25.0, 55.0, 6)]
    results = [a for a in assess_trend(records, SETTINGS, RIG)[9:]]
    trend = [a.trend_change.value for a in results]
    assert trend[-1] == pytest.approx(0.05, abs=0.02)
    assert any(f.quantity == "mu_scale_trend" and f.level == "WARN" for a in results for f in a.findings)
    first_trend = next(i for i, a in enumerate(results) if any(f.quantity == "mu_scale_trend" and f.level != "OK"
                                                                 for f in a.findings))
    assert first_trend >= 1  # it takes more than one check


def test_an_unnoticed_change_does_not_teach_the_law() -> None:
    """A warm check 7 % up (below the single-check limit) would pull k toward 0 if it taught the law."""
    records = healthy_trend(8, seed=5)
    rng = np.random.default_rng(6)
    risen = record(55.0, 0.07, rng=rng)
    risen.level = "OK"
    with_it = baseline_of(records + [risen], SETTINGS, RIG)
    without = baseline_of(records, SETTINGS, RIG)
    assert with_it.learned_from == without.learned_from  # left out: it looked changed
    assert with_it.law.mu_per_kelvin == pytest.approx(without.law.mu_per_kelvin)


def test_an_estimated_temperature_widens_the_interval_by_k_sigma_t() -> None:
    records = healthy_trend(8, seed=7)
    baseline = baseline_of(records, SETTINGS, RIG)
    rng = np.random.default_rng(8)
    sure = record(40.0, rng=rng)
    guessed = replace(sure, temperature=Temperature(40.0, 5.0, "estimated"))
    _, own_sure, _ = mu_change(sure, baseline, RIG, SETTINGS)
    _, own_guessed, _ = mu_change(guessed, baseline, RIG, SETTINGS)
    f = 1 + baseline.law.mu_per_kelvin * 15.0
    ratio = sure.parameters.mu_scale / (f * baseline.mu_scale)
    k = baseline.law.mu_per_kelvin
    assert own_guessed - own_sure == pytest.approx(ratio ** 2 * (k / f) ** 2 * (5.0 ** 2 - 0.5 ** 2), rel=1e-9)


def test_drags_and_backlash_are_compared_too() -> None:
    records = healthy_trend(6, seed=9)
    baseline = baseline_of(records, SETTINGS, RIG)
    rng = np.random.default_rng(10)
    seal = assess(record(35.0, drag=4.0, rng=rng), baseline, [], SETTINGS, RIG)
    drive = next(f for f in seal.findings if f.quantity == "drive_drag")
    assert drive.level in ("WARN", "ERROR") and drive.change > 0.4, seal.lines
    worn = assess(record(35.0, backlash=0.0044 * 2.2, rng=rng), baseline, [], SETTINGS, RIG)
    assert next(f for f in worn.findings if f.quantity == "backlash").level == "ERROR", worn.lines


def test_the_rig_file_as_baseline() -> None:
    baseline = baseline_from_rig(RIG, SETTINGS)
    assert baseline.mu_scale == 1.0 and baseline.law.source == "prior"
    rng = np.random.default_rng(11)
    result = assess(record(25.0, rng=rng), baseline, [], SETTINGS, RIG)
    assert result.mu_change.value == pytest.approx(S_TRUE - 1.0, abs=0.05)
    assert result.mu_change.sigma > 0.1 * S_TRUE  # the rig file's 10 % allowance


def test_no_check_is_judged_surer_than_the_bound_allows() -> None:
    """worm_model.health.bound: the least sigma of a check's mu change given the earlier checks. It grows as the
    check's oil leaves the temperatures the earlier ones saw (25-55 degC here), never falls below the check's own
    error, and the verdict's own sigma is never below it (else the bound or the verdict is wrong)."""
    records = healthy_trend(9, seed=12)
    baseline = baseline_of(records, SETTINGS, RIG)
    rng = np.random.default_rng(13)
    bounds = []
    for temperature in (40.0, 60.0, 75.0, 90.0):
        check = record(temperature, 0.10, rng=rng)
        bound = one_check_sigma(check, records, baseline, K_TRUE, SETTINGS, RIG)
        verdict = assess(check, baseline, records[SETTINGS.limits.baseline_checks:], SETTINGS, RIG)
        assert NOISE < bound <= verdict.mu_change.sigma * 1.02, (temperature, bound, verdict.mu_change.sigma)
        bounds.append(bound)
    assert bounds == sorted(bounds) and bounds[-1] > 1.5 * bounds[0], bounds


def test_the_chance_one_check_finds_a_rise() -> None:
    limits = SETTINGS.limits
    sigma = 0.02
    assert detection_probability(limits.z_min * sigma, sigma, limits) == pytest.approx(0.5)
    # Phi((0.10 - 0.07) / 0.02) = Phi(1.5)
    assert detection_probability(0.10, sigma, limits) == pytest.approx(0.9332, abs=1e-4)
    # a sure but small change stays below the limit: the bar is check_warn (6 %) where z_min sigma is less
    assert detection_probability(limits.check_warn, 0.01, limits) == pytest.approx(0.5)
