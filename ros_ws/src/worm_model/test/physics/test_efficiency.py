"""Section 6: flank factor, efficiencies and self-locking against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from worm_model.physics.efficiency import (
    backward_efficiency,
    flank_factor,
    forward_efficiency,
    friction_angle,
    is_self_locking,
    make_flank_factor_float,
)
from worm_model.physics.parameters import load_rig

GB = load_rig().gearbox
MU = np.linspace(0.0, 0.3, 31)


def test_flank_factor_is_tan_lambda_plus_minus_rho() -> None:
    rho = np.arctan(MU / np.cos(GB.normal_pressure_angle))
    assert np.allclose(friction_angle(GB, MU), rho)
    assert np.allclose(flank_factor(GB, MU, 1), np.tan(GB.lead_angle + rho))
    assert np.allclose(flank_factor(GB, MU, -1), np.tan(GB.lead_angle - rho))
    both = flank_factor(GB, MU[:, None], np.array([1, -1]))
    assert both.shape == (31, 2)


def test_flank_factor_float_twin_is_bit_identical() -> None:
    """make_flank_factor_float is flank_factor to the bit (same trigonometry, same order of operations),
    on both flanks, 0-d and vectorised, through the coast flank's pole."""
    factor = make_flank_factor_float(GB)
    mu = np.concatenate([np.linspace(0.0, 0.3, 3001), [GB.self_locking_mu, 1.0, 5.0]])
    for s in (1.0, -1.0):
        floats = np.array([factor(float(m), s) for m in mu])
        assert np.array_equal(floats, flank_factor(GB, mu, s))
        assert all(factor(float(m), s) == float(flank_factor(GB, m, s)) for m in mu[::100])
        assert isinstance(factor(0.05, s), float)


def test_efficiencies_closed_form() -> None:
    rho = np.arctan(MU / np.cos(GB.normal_pressure_angle))
    lam = GB.lead_angle
    assert np.allclose(forward_efficiency(GB, MU), np.tan(lam) / np.tan(lam + rho))
    assert np.allclose(backward_efficiency(GB, MU), np.tan(lam - rho) / np.tan(lam))
    assert forward_efficiency(GB, 0.0) == pytest.approx(1.0)
    # Shigley's form: eta = (cos phi_n - mu tan lambda) / (cos phi_n + mu cot lambda)
    c = np.cos(GB.normal_pressure_angle)
    assert np.allclose(forward_efficiency(GB, MU), (c - MU * np.tan(lam)) / (c + MU / np.tan(lam)))


def test_self_locking_threshold() -> None:
    mu_lock = np.cos(GB.normal_pressure_angle) * np.tan(GB.lead_angle)
    assert GB.self_locking_mu == pytest.approx(mu_lock)
    assert GB.mu_engagement_max == pytest.approx(np.cos(GB.normal_pressure_angle) / np.tan(GB.lead_angle))
    mus = np.array([0.5, 0.999, 1.001, 2.0]) * mu_lock
    assert list(is_self_locking(GB, mus)) == [False, False, True, True]
    assert np.array_equal(is_self_locking(GB, mus), backward_efficiency(GB, mus) < 0)
