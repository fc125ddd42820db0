"""The check's fit recovers the parameters of a run whose truth is known, within its intervals; what the run
does not excite stays the prior's; the backlash comes from the transmission error; the wheel's runout is
taken out as a nuisance."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from fixtures.health_runs import check_segments, steady_run

from worm_model.health.blocks import blocks_from_data
from worm_model.health.fit import fit_points
from worm_model.errors import FitError
from worm_model.health.model import NAMES, HealthParameters
from worm_model.health.points import Points, steady_points
from worm_model.physics.parameters import load_rig

RIG = load_rig()
TRUE = replace(HealthParameters.from_rig(RIG), mu_scale=1.15, mu_speed_exponent=-0.1, mu_load_slope=-0.6,
               drive_coulomb=0.006, drive_viscous=4e-5, gear_coulomb=0.03, gear_viscous=1e-3, torque_offset=0.002)


def _points(params=TRUE, segments=None, seed=0, **kwargs) -> Points:
    data = steady_run(RIG, params, segments or check_segments(RIG), seed=seed, **kwargs)
    return steady_points(blocks_from_data(data, RIG.gearbox.ratio), RIG)


def test_the_fit_recovers_what_wears_within_its_intervals() -> None:
    fit = fit_points(_points(gap=math.radians(20 / 60)), RIG, HealthParameters.from_rig(RIG))
    for name in NAMES:
        z = (getattr(fit.parameters, name) - getattr(TRUE, name)) / fit.sigma[name]
        assert abs(z) < 4.0, (name, getattr(fit.parameters, name), getattr(TRUE, name), fit.sigma[name])
        assert fit.identified[name], name
    assert fit.sigma["mu_scale"] < 0.02  # a check decides mu's scale to ~1 %
    assert fit.backlash == pytest.approx(math.radians(20 / 60), abs=3 * fit.backlash_sigma + 1e-9)
    assert 0.3 < fit.chi2_red < 2.5  # the model is the plant: the points scatter as their noise says
    assert fit.points == 30 and fit.speeds == {"forward": [60.0, 300.0], "backward": [60.0, 300.0]}


def test_repeated_checks_scatter_as_their_sigmas_say() -> None:
    fits = [fit_points(_points(seed=s), RIG, HealthParameters.from_rig(RIG)) for s in range(12)]
    scale = np.array([f.parameters.mu_scale for f in fits])
    sigma = np.median([f.sigma["mu_scale"] for f in fits])
    # (12 checks: the scatter's own estimate is uncertain by ~20 %)
    assert 0.6 * sigma < scale.std(ddof=1) < 1.5 * sigma, (scale.std(ddof=1), sigma)


def test_a_run_without_load_leaves_mu_to_the_prior_and_watches_the_drags() -> None:
    segments = [(d * w, 0.0) for d in (1.0, -1.0) for w in (60.0, 160.0, 300.0)]
    fit = fit_points(_points(segments=segments), RIG, HealthParameters.from_rig(RIG))
    assert not fit.identified["mu_load_slope"]
    assert fit.identified["drive_coulomb"] and fit.identified["drive_viscous"]
    assert math.isnan(fit.backlash)  # one flank only


def test_the_wheel_runout_is_a_nuisance_not_a_change_of_mu() -> None:
    """A once-per-gear-turn ripple on the gear shaft (10 mN m, the simulator's default) added to the points' loads
    as the points' means of sin/cos of the gear angle: the fit takes it out and finds its amplitude."""
    points = _points(seed=3)
    rng = np.random.default_rng(4)
    phase = rng.uniform(0, 2 * np.pi, len(points))
    span = rng.uniform(0.5, 2.5, len(points))  # the part of a gear turn each point covers [rad]
    points.gear_sin = (np.cos(phase) - np.cos(phase + span)) / span
    points.gear_cos = (np.sin(phase + span) - np.sin(phase)) / span
    ripple = 0.01 * points.gear_sin  # gear-side torque: at the worm through the flank's factor, ~1/20
    from worm_model.health.model import input_torque

    points.torque = points.torque + input_torque(RIG, TRUE, points.omega, points.tau_load + ripple) \
        - input_torque(RIG, TRUE, points.omega, points.tau_load)
    fit = fit_points(points, RIG, HealthParameters.from_rig(RIG))
    assert fit.runout == pytest.approx(0.01, abs=0.003)
    assert abs(fit.parameters.mu_scale - TRUE.mu_scale) < 4 * fit.sigma["mu_scale"]


def test_too_few_points_is_refused() -> None:
    points = _points(segments=[(100.0, 0.1), (200.0, 0.1)])
    with pytest.raises(FitError, match="2 steady constant-speed point"):
        fit_points(points, RIG, HealthParameters.from_rig(RIG))
