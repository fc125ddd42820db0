"""The steady-point road of identify (torque_estimator.identification.steady): held runs as points, the base fit,
and the term selection (a planted low-speed rise found, none found where there is none, a term that fits only by
trading the base away refused).

The records are synthetic: the NMRV030 rig file under a constant mu of 0.06 (the base's law) is the truth and the
declared rig; every run is 200 samples (1 kHz) held at one speed and load, the model's steady current plus 0.02 A
of white noise and the speed plus 0.5 rad/s. The speeds are dense where a low-speed rise shows (3-20 rad/s): each
half of the cross-fit then sees the rise (with 5, 10, 20, ... only, the half without the slowest speed at times
extrapolated a rise to its bound, and the selection took the support's rise first in only 5 of 8 seeds).
Tolerances from eight seeds (noted in each test).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_model.residuals.extended import ExtendedModel
from worm_model.rig_data.schema import MeasuredData

from torque_estimator.identification.steady import (MIN_IMPROVEMENT, MIN_RUN_SAMPLES, TRADED_RATIO, fit, halves,
                                                    model_current, select, steady_points)

RIG = load_rig()
TRUE = replace(RIG, friction=replace(RIG.friction, model="constant", mu_constant=0.06))
#: the gear shaft supports' Coulomb drag rising by 0.01 N m towards standstill over 0.3 rad/s of the gear
RISE = replace(TRUE, load_motor=replace(TRUE.load_motor, stribeck_rise=0.01, stribeck_speed=0.3))
SPEEDS = [sign * s for sign in (1, -1) for s in (3.0, 5.0, 7.0, 10.0, 14.0, 20.0, 40.0, 80.0, 150.0, 250.0, 340.0)]
LOADS = (0.05, 0.15)  # [N m]
SAMPLES, CURRENT_NOISE, SPEED_NOISE = 200, 0.02, 0.5
SEM = CURRENT_NOISE / math.sqrt(SAMPLES)  # [A] a point's standard error
TERMS = ("gear_support_stribeck", "tooth_stribeck")  # the planted term and the one it is told from


def _record(rig, loads=LOADS, seed: int = 0, speeds=SPEEDS) -> MeasuredData:
    """Held runs (module docstring), one per speed and load, 1 s apart."""
    rng = np.random.default_rng(seed)
    model = ExtendedModel(rig)
    t, current, omega, tau, run = [], [], [], [], []
    for r, (load, speed) in enumerate((load, speed) for load in loads for speed in speeds):
        steady = float(model_current(model, [speed], [load])[0])
        t.append(r * (SAMPLES * 1e-3 + 1.0) + np.arange(SAMPLES) * 1e-3)
        current.append(steady + rng.normal(0.0, CURRENT_NOISE, SAMPLES))
        omega.append(speed + rng.normal(0.0, SPEED_NOISE, SAMPLES))
        tau.append(np.full(SAMPLES, load))
        run.append(np.full(SAMPLES, r))
    t, current, omega, tau, run = (np.concatenate(x) for x in (t, current, omega, tau, run))
    return MeasuredData(t, current, omega, np.zeros(len(t)), tau, run=run)


def _one_run(data: MeasuredData, r: int, **channels) -> MeasuredData:
    """``data`` with run ``r``'s channels replaced (arrays of its length)."""
    out = data.subset(np.arange(len(data)))
    at = data.run == r
    for name, value in channels.items():
        getattr(out, name)[at] = value
    return out


# --------------------------------------------------------------------------- points
def test_held_runs_are_steady_points() -> None:
    """One point per run: mean speed (within 0.15 rad/s of the set-point; measured up to 0.12), mean current
    (within 3.5 standard errors of the model's; measured up to 2.8), the load, the run, the speed's spread
    (0.5 rad/s +-20 %; measured 0.413..0.587) and a noise floor of the points' standard errors from 10 blocks
    (0.02 A / sqrt(200) +-8 %; measured 0.942..1.055)."""
    data = _record(TRUE)
    points = steady_points(data)
    assert points is not None and len(points) == 44
    assert np.all(np.abs(points.omega - np.tile(SPEEDS, 2)) < 0.15)
    expected = model_current(ExtendedModel(TRUE), points.omega, points.tau_load)
    assert np.all(np.abs(points.current - expected) < 3.5 * SEM)
    np.testing.assert_allclose(points.tau_load, np.repeat(LOADS, 22), rtol=1e-12)
    np.testing.assert_array_equal(points.run, np.arange(44))
    np.testing.assert_allclose(points.speed_sd, SPEED_NOISE, rtol=0.2)
    assert points.noise_floor == pytest.approx(SEM, rel=0.08)
    np.testing.assert_allclose(points.loads, LOADS, rtol=0.0, atol=1e-9 * max(LOADS))  # to 1e-9 of the largest
    blocks = np.array_split(data.current_drive[data.run == 3], 10)
    assert points.current_sem[3] == pytest.approx(np.std([b.mean() for b in blocks], ddof=1) / math.sqrt(10))


def test_a_slow_run_held_is_a_point() -> None:
    """A run at 1 rad/s under a 0.5 rad/s speed noise (a drive that sticks and slips) is held: its mean is clear
    of 0 by far more than 3 standard errors."""
    data = _record(TRUE, seed=1)
    slow = _one_run(data, 0, omega_worm=1.0 + np.random.default_rng(2).normal(0.0, SPEED_NOISE, SAMPLES))
    points = steady_points(slow)
    assert points is not None and points.omega[0] == pytest.approx(1.0, abs=0.15)


@pytest.mark.parametrize("change", ["ramp", "standing", "load", "nan", "short", "one run"])
def test_what_is_not_a_steady_record(change: str) -> None:
    """None when a run moves through speeds (a ramp 20 -> 60 rad/s), stands (mean 0 within its noise), changes
    its load, has a NaN, is shorter than MIN_RUN_SAMPLES, or when there is a single run."""
    data = _record(TRUE, seed=2)
    ramp = np.linspace(20.0, 60.0, SAMPLES)
    noise = np.random.default_rng(3).normal(0.0, SPEED_NOISE, SAMPLES)
    if change == "ramp":
        data = _one_run(data, 5, omega_worm=ramp + noise)
    elif change == "standing":
        data = _one_run(data, 5, omega_worm=noise - noise.mean())
    elif change == "load":
        data = _one_run(data, 5, tau_load=np.where(np.arange(SAMPLES) < 100, 0.05, 0.06))
    elif change == "nan":
        data = _one_run(data, 5, current_drive=np.where(np.arange(SAMPLES) == 7, np.nan, 0.2))
    elif change == "short":
        data = data.subset((data.run != 5) | (np.arange(len(data)) % SAMPLES < MIN_RUN_SAMPLES - 1))
    else:
        data = data.subset(data.run == 5)
    assert steady_points(data) is None


def test_halves_alternate_speeds_in_each_direction_and_load() -> None:
    """In each load and direction, by rising |speed|: halves 0, 1, 0, 1, ... (the slowest in half 0), so each half
    spans the whole range of speeds."""
    points = steady_points(_record(TRUE))
    half = halves(points)
    for load in LOADS:
        for side in (points.omega > 0, points.omega < 0):
            idx = np.flatnonzero(side & np.isclose(points.tau_load, load))
            assert list(half[idx[np.argsort(np.abs(points.omega[idx]))]]) == [0, 1] * 5 + [0]
    assert np.sum(half == 0) == 24 and np.sum(half == 1) == 20


# --------------------------------------------------------------------------- fit and selection
def test_the_base_fit_finds_the_rig() -> None:
    """Two loads, both directions, the base's own law: mu, the worm shaft's drags and the gear shaft's Coulomb drag
    come back (measured over eight seeds: x0.981..1.010, 0.989..1.006, 0.990..1.007, 0.958..1.156), the residual
    at the noise floor (0.83..1.12 x)."""
    points = steady_points(_record(TRUE))
    fitted = fit(TRUE, points)
    v = fitted.values
    assert v["friction.mu_constant"] == pytest.approx(0.06, rel=0.025)
    assert v["drive_motor.coulomb_drag"] == pytest.approx(TRUE.drive_motor.coulomb_drag, rel=0.015)
    assert v["drive_motor.viscous_drag"] == pytest.approx(TRUE.drive_motor.viscous_drag, rel=0.012)
    assert v["load_motor.coulomb_drag"] == pytest.approx(TRUE.load_motor.coulomb_drag, rel=0.18)
    assert fitted.rms < 1.3 * points.noise_floor
    assert "drive_motor.torque_constant" not in v  # no current measured: no K_t knob
    assert "drive_motor.torque_constant" in fit(TRUE, points, current_measured=True).values


def test_a_planted_support_rise_is_selected() -> None:
    """The gear supports' low-speed rise in the data: adding it takes the cross-fitted held-out RMS from 2.7 x the
    floor to the floor (1.06 x), the tooth mu's rise only to 1.8 x (two loads tell a support's rise from the
    tooth's). Over eight seeds the support's rise was taken every time and the tooth's never; the fitted rise
    0.0089..0.0123 N m over 0.23..0.37 rad/s (planted: 0.01 over 0.3)."""
    points = steady_points(_record(RISE))
    selection = select(TRUE, points, TERMS)
    assert selection.accepted == ["gear_support_stribeck"] and selection.traded == {}
    first = selection.rounds[0]
    assert first["gear_support_stribeck"] < first["tooth_stribeck"]
    assert selection.held_out[1] == first["gear_support_stribeck"]
    assert selection.held_out[1] <= (1.0 - MIN_IMPROVEMENT) * selection.held_out[0]
    assert not selection.unexplained and selection.lines()[-1].endswith("(at the floor)")
    assert "-> gear_support_stribeck" in selection.lines()[1]
    rise = fit(TRUE, points, selection.accepted).values
    assert rise["load_motor.stribeck_rise"] == pytest.approx(0.01, rel=0.3)
    assert rise["load_motor.stribeck_speed"] == pytest.approx(0.3, rel=0.35)


def test_no_term_where_the_data_have_none() -> None:
    """The same record without the rise: both terms are tried (the base's held-out RMS, 1.18 x the floor, is above
    AT_FLOOR) and neither lowers it by MIN_IMPROVEMENT (1.18 and 1.19 x). Eight seeds: none taken (in four the base
    was already at the floor)."""
    points = steady_points(_record(TRUE, seed=1))
    selection = select(TRUE, points, TERMS)
    assert selection.accepted == [] and selection.traded == {} and selection.unexplained
    assert set(selection.rounds[0]) == set(TERMS)
    assert all(v > (1.0 - MIN_IMPROVEMENT) * selection.held_out[0] for v in selection.rounds[0].values())
    assert "none (no term lowers it by 10%)" in selection.lines()[1]


def test_a_term_that_fits_by_trading_the_base_is_refused() -> None:
    """One load (0.25 N m), the support's rise planted: the tooth mu's rise fits it only with mu and the gear
    supports' drag traded (mu 0.0036..0.005 instead of 0.06, the drag 0.064..0.090 N m instead of 0.004, eight
    seeds), the drag's band then TRADED_RATIO x its tolerance or more (5.4..10.7 x; this seed 6.9): it is not
    tried. The support's rise is taken (every seed)."""
    points = steady_points(_record(RISE, loads=(0.25,)))
    selection = select(TRUE, points, TERMS)
    assert list(selection.traded) == ["tooth_stribeck"] and selection.traded["tooth_stribeck"] >= TRADED_RATIO
    assert all("tooth_stribeck" not in tried for tried in selection.rounds)
    assert selection.accepted == ["gear_support_stribeck"]
    assert any(line.startswith("  not tried: tooth_stribeck, it fits only by trading the base away")
               for line in selection.lines())
    traded = fit(TRUE, points, ["tooth_stribeck"]).values
    assert traded["friction.mu_constant"] < 0.1 * 0.06
    assert traded["load_motor.coulomb_drag"] > 15 * TRUE.load_motor.coulomb_drag
