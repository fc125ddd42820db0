"""AGMA friction coefficient (Shigley Eq. 15-38) and the friction model registry."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.friction import (
    FT_PER_MIN,
    agma_friction_coefficient,
    friction_coefficient,
    make_friction_coefficient_float,
    sliding_velocity,
    stribeck_friction_coefficient,
)
from worm_model.physics.parameters import Friction, load_rig

RIG = load_rig()


@pytest.mark.parametrize(
    "v_ftmin, expected",
    [
        (0.0, 0.15),  # static value
        (1.0, 0.124 * np.exp(-0.074)),  # 0.11516
        (10.0, 0.08936),  # end of the low-speed branch
        (100.0, 0.103 * np.exp(-0.110 * 100**0.45) + 0.012),  # 0.04357
        (1000.0, 0.02078),
    ],
)
def test_agma_published_points(v_ftmin: float, expected: float) -> None:
    assert agma_friction_coefficient(v_ftmin * FT_PER_MIN) == pytest.approx(expected, rel=1e-3)


def test_agma_shape() -> None:
    assert FT_PER_MIN == pytest.approx(0.00508)
    # the two branches nearly meet at 10 ft/min (a "+0.013" on the low branch would jump 0.015)
    below, above = agma_friction_coefficient(np.array([10.0, 10.0001]) * FT_PER_MIN)
    assert abs(below - above) < 0.003
    v = np.geomspace(11, 1e4, 50) * FT_PER_MIN
    assert np.all(np.diff(agma_friction_coefficient(v)) < 0)
    assert agma_friction_coefficient(-0.1) == agma_friction_coefficient(0.1)
    assert np.isnan(agma_friction_coefficient(np.nan))


def test_sliding_velocity_and_models() -> None:
    gb = RIG.gearbox
    w = np.array([-200.0, 0.0, 200.0])
    vs = sliding_velocity(gb, w)
    assert np.allclose(vs, np.abs(w) * gb.worm_pitch_radius / np.cos(gb.lead_angle))
    mu = friction_coefficient(RIG.friction, gb, w)
    assert np.allclose(mu, agma_friction_coefficient(vs))
    doubled = friction_coefficient(replace(RIG.friction, scale=2.0), gb, w)
    assert np.allclose(doubled, 2 * mu)
    const = friction_coefficient(Friction("constant", 0.07, 1.0), gb, w)
    assert np.allclose(const, 0.07) and const.shape == (3,)


STRIBECK = Friction("stribeck", 0.12, 1.1, 0.06, 0.0034443)


@pytest.mark.parametrize("friction", [RIG.friction, replace(RIG.friction, scale=1.3), Friction("constant", 0.07, 1.0),
                                      STRIBECK], ids=["agma", "agma-scaled", "constant", "stribeck"])
def test_float_twin(friction) -> None:
    """make_friction_coefficient_float agrees with friction_coefficient to round-off (libm's exp and pow
    against numpy's: measured up to 3 ulp, on ~3-5 % of speeds), both signs, through the AGMA break and at
    rest; NaN gives NaN."""
    gb = RIG.gearbox
    mu_float = make_friction_coefficient_float(friction, gb)
    w = np.concatenate([np.geomspace(1e-6, 2000.0, 4001), [0.0]])
    w = np.concatenate([w, -w])
    floats = np.array([mu_float(float(x)) for x in w])
    arrays = np.array([float(friction_coefficient(friction, gb, x)) for x in w])  # 0-d, as a per-sample caller
    assert np.all(np.abs(floats - arrays) <= 4 * np.spacing(arrays))
    assert all(isinstance(mu_float(float(x)), float) for x in w[:3])
    assert np.isnan(mu_float(float("nan")))


def test_stribeck_law_as_the_t_ro_scripts_evaluate_it() -> None:
    """mu = mu_k + mu_s exp(-|v|/v_st)^2 (their getFrictionCoeff: the square on the exponential, i.e.
    exp(-2|v|/v_st), not the Gaussian exp(-(v/v_st)^2)); with their drive No. 3: 0.12 + 0.06 = 0.18 at rest,
    0.12 + 0.06 e^-2 = 0.128120 at v = v_st, 0.12 + 0.06 e^-4 = 0.121099 at 2 v_st; scale multiplies it all."""
    v = np.array([0.0, 0.0034443, -0.0068886])
    np.testing.assert_allclose(stribeck_friction_coefficient(v, 0.12, 0.06, 0.0034443), [0.18, 0.128120, 0.121099],
                               atol=1e-6)
    gb = RIG.gearbox
    w = v * np.cos(gb.lead_angle) / gb.worm_pitch_radius  # the worm speeds of those sliding speeds
    np.testing.assert_allclose(friction_coefficient(STRIBECK, gb, w), 1.1 * np.array([0.18, 0.128120, 0.121099]),
                               atol=2e-6)


def test_agma_metric_form_checks_the_unit_conversion() -> None:
    """The same AGMA relation printed in SI (engineersedge.com, "AGMA WormGear Equations For
    Rating Factors", https://engineersedge.com/calculators/agma_wormgear_equations_15309.htm):
    mu = 0.124 exp(-2.233 V^0.645) for 0 < V <= 0.0508 m/s, 0.103 exp(-1.185 V^0.45) above,
    V in m/s.  The exponent factors are ours (0.074, 0.110 per ft/min) times 196.85^0.645 and
    196.85^0.45, so this checks the ft/min conversion independently of our code.  That page
    omits Shigley's "+ 0.012" on the high branch (Shigley 9th ed. Eq. 15-38 has it; Mott's
    Example 10-7 reading, test_textbook_example.py, confirms it), so it is added here.
    """
    assert 10.0 * FT_PER_MIN == pytest.approx(0.0508)
    low = np.array([0.001, 0.01, 0.03, 0.0508])
    high = np.array([0.06, 0.2, 1.0, 2.5, 10.0])
    assert np.allclose(agma_friction_coefficient(low), 0.124 * np.exp(-2.233 * low**0.645), rtol=2e-3)
    assert np.allclose(agma_friction_coefficient(high), 0.103 * np.exp(-1.185 * high**0.45) + 0.012, rtol=2e-3)
