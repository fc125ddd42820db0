"""Eq. 29: PMDC current dynamics and shaft torque."""

from __future__ import annotations

import numpy as np
import pytest

from worm_model.physics.motor import (
    current_derivative,
    electromagnetic_torque,
    exact_current_step,
    shaft_torque,
    steady_state_current,
)
from worm_model.physics.parameters import load_rig

M = load_rig().drive_motor


def test_steady_state_zeroes_derivative() -> None:
    v, w = np.array([24.0, -12.0, 5.0]), np.array([300.0, -100.0, 0.0])
    i_ss = steady_state_current(M, v, w)
    assert np.allclose(current_derivative(M, v, i_ss, w), 0.0)
    assert i_ss[2] == pytest.approx(5.0 / M.resistance)


def test_exact_step_matches_fine_integration_and_is_stable() -> None:
    v, w, i0, dt = 24.0, 100.0, 0.0, 2e-3
    i = i0
    h = dt / 20000
    for _ in range(20000):  # reference: fine explicit Euler on one sample
        i += h * float(current_derivative(M, v, i, w))
    assert exact_current_step(M, v, i0, w, dt) == pytest.approx(i, rel=1e-3)
    assert exact_current_step(M, v, i0, w, 10.0) == pytest.approx(steady_state_current(M, v, w))
    assert exact_current_step(M, v, 3.0, w, 0.0) == pytest.approx(3.0)
    steps = exact_current_step(M, np.full(4, v), np.zeros(4), w, np.array([0, 1e-4, 1e-3, 1.0]))
    assert np.all(np.diff(steps) > 0)


def test_shaft_torque_signs() -> None:
    i, w = np.array([2.0, 2.0, -2.0]), np.array([100.0, 0.0, -100.0])
    tau = shaft_torque(M, i, w)
    em = electromagnetic_torque(M, i)
    assert np.allclose(em, M.torque_constant * i)
    assert tau[0] == pytest.approx(em[0] - M.viscous_drag * 100 - M.coulomb_drag)
    assert tau[1] == pytest.approx(em[1])
    assert tau[2] == pytest.approx(-tau[0])
