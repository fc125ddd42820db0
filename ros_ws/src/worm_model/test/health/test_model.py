"""The health model is the paper's model (Eq. 28 with the drags) at the rig file's values, and its loss is Eq. 22's.

Expectations from worm_model.physics (reflected_input_torque, gear_side_load, the motor's drags) and from
Eqs 21-23 (internal_forces: F_f V_s is the mesh's loss), never from the health module itself.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.health.model import (HealthParameters, TemperatureLaw, drag_power, input_torque, mesh_loss, mesh_mu,
                                     reference_load)
from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient, sliding_velocity
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.internal_forces import internal_forces
from worm_model.physics.parameters import load_rig

RIG = load_rig()
OMEGA = np.array([40.0, 150.0, 320.0, -60.0, -200.0, 150.0, -150.0])
LOAD = np.array([0.2, -0.15, 0.05, 0.25, -0.2, -0.003, 0.0])


def test_at_the_rig_files_values_the_model_is_eq28_with_the_files_drags() -> None:
    p = HealthParameters.from_rig(RIG)
    motor = RIG.drive_motor
    mu = friction_coefficient(RIG.friction, RIG.gearbox, OMEGA)
    expected = reflected_input_torque(RIG.gearbox, mu, gear_side_load(RIG, LOAD, OMEGA), OMEGA) \
        + motor.viscous_drag * OMEGA + motor.coulomb_drag * np.sign(OMEGA)
    np.testing.assert_allclose(input_torque(RIG, p, OMEGA, LOAD), expected, rtol=1e-12, atol=1e-15)


def test_mu_scale_speed_and_load_laws_and_temperature_law() -> None:
    base = HealthParameters.from_rig(RIG)
    mu_file = friction_coefficient(RIG.friction, RIG.gearbox, OMEGA)
    v = sliding_velocity(RIG.gearbox, OMEGA)
    p = replace(base, mu_scale=1.2, mu_speed_exponent=-0.1, mu_load_slope=-0.5)
    mesh = np.abs(LOAD)
    expected = 1.2 * mu_file * v ** -0.1 * (1 - 0.5 * (mesh - reference_load(RIG)))
    np.testing.assert_allclose(mesh_mu(RIG, p, OMEGA, mesh), expected, rtol=1e-12)
    law = TemperatureLaw(reference=25.0, mu_per_kelvin=-0.004)
    np.testing.assert_allclose(law.factor([25.0, 40.0, np.nan]), [1.0, 0.94, 1.0])
    warm = mesh_mu(RIG, p, OMEGA, mesh, law.factor(40.0))
    np.testing.assert_allclose(warm, 0.94 * expected, rtol=1e-12)
    # D_ref: 0.8 x the load motors' torque
    assert reference_load(RIG) == pytest.approx(0.8 * RIG.max_load_torque)


def test_the_mesh_loss_is_the_friction_force_times_the_sliding_speed() -> None:
    """At a_w = 0 the power the mesh takes (T w - D i w) is F_f V_s (Eqs 21-23 on the same torques)."""
    p = replace(HealthParameters.from_rig(RIG), mu_scale=1.3)
    loss = mesh_loss(RIG, p, OMEGA, LOAD)
    d_mesh = LOAD + p.gear_coulomb * np.sign(OMEGA) + p.gear_viscous * RIG.gearbox.ratio * OMEGA
    torque = input_torque(RIG, p, OMEGA, LOAD) - p.drive_coulomb * np.sign(OMEGA) - p.drive_viscous * OMEGA
    forces = internal_forces(RIG.gearbox, torque, d_mesh, OMEGA, 0.0)
    np.testing.assert_allclose(loss, forces.friction_force * sliding_velocity(RIG.gearbox, OMEGA), rtol=1e-7,
                               atol=1e-12)
    assert np.all(loss >= 0)


def test_drag_power_is_torque_times_speed() -> None:
    p = HealthParameters.from_rig(RIG)
    worm, gear = drag_power(RIG, p, 200.0)
    assert worm == pytest.approx((p.drive_coulomb + p.drive_viscous * 200.0) * 200.0)
    w_g = RIG.gearbox.ratio * 200.0
    assert gear == pytest.approx((p.gear_coulomb + p.gear_viscous * w_g) * w_g)


def test_parameters_round_trip_and_refuse_a_missing_value() -> None:
    p = replace(HealthParameters.from_rig(RIG), mu_scale=1.1, torque_offset=-2e-3)
    assert HealthParameters.from_vector(p.vector()) == p
    assert HealthParameters.from_dict(p.to_dict(), "x") == p
    doc = p.to_dict()
    doc.pop("gear_viscous")
    with pytest.raises(ValueError, match="x: parameters.gear_viscous"):
        HealthParameters.from_dict(doc, "x")
