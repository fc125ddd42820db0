"""AGMA friction coefficient (Shigley Eq. 15-38) and the friction model registry."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.friction import (
    FT_PER_MIN,
    agma_friction_coefficient,
    friction_coefficient,
    sliding_velocity,
)
from worm_model.parameters import Friction, load_rig

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
