"""Backlash: a real dead zone in the mesh, crossed at every flank change (plant.py, effect `backlash`).

What the issue asks: the contact crosses the gap when the flank changes, which is
visible in position (the worm turns while the gear does not) and in current (the
rigid model's current residual: dead time while the teeth are apart), without
numerical chatter. Expectations come from the gap width and from worm_model's
Eqs 28-30, never from a recorded run.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.dynamics import effective_worm_inertia, reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_load, no_load_switching_torque
from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.effects import EffectsConfig
from worm_rig_driver.sim.plant import RigPlant
from worm_rig_driver.sim.simulated_rig import SimulatedRig

RIG = load_rig()
GB = RIG.gearbox
MOTOR = RIG.drive_motor
QUIET = replace(RIG, sensors=replace(RIG.sensors, current_noise_std=0.0, tacho_noise_std=0.0))
BACKLASH = EffectsConfig.defaults("backlash")
GAP = BACKLASH.effects["backlash"]["angle"]  # [rad] at the gear
DT = 5e-4


def _run(effects, commands, n=1):
    """Step a plant through (voltage, load) commands; record what the tests need, shape (steps, n)."""
    plant = RigPlant(RIG, n, effects=effects)
    names = ("current", "omega", "omega_before", "alpha", "tau_load", "theta_worm", "theta_gear", "contact",
             "impact_loss")
    rec = {name: np.empty((len(commands), n)) for name in names}
    for k, (volts, load) in enumerate(commands):
        rec["omega_before"][k] = plant.state.omega_worm
        out = plant.step(DT, volts, load)
        s = plant.state
        rec["current"][k], rec["omega"][k], rec["alpha"][k] = s.current_drive, s.omega_worm, out.alpha_worm
        rec["tau_load"][k], rec["theta_worm"][k], rec["theta_gear"][k] = out.tau_load, s.theta_worm, s.theta_gear
        rec["contact"][k], rec["impact_loss"][k] = s.contact, out.impact_loss
    return rec, plant


def _rigid_model_residual(rec) -> np.ndarray:
    """Measured minus Eq. 28/30 current of the rigid model (what a residual analysis computes) [A]."""
    w, alpha, tau = rec["omega_before"], rec["alpha"], rec["tau_load"]
    mu = friction_coefficient(RIG.friction, GB, w)
    load = gear_side_load(RIG, tau, w)
    flank = np.where(np.sign(w) * load >= 0, 1.0, -1.0)
    torque = (reflected_input_torque(GB, mu, load, w)
              + effective_worm_inertia(GB, mu, flank, RIG.total_worm_inertia, RIG.total_gear_inertia) * alpha
              + MOTOR.viscous_drag * w + MOTOR.coulomb_drag * np.sign(w))
    return rec["current"] - torque / MOTOR.torque_constant


def _transitions(contact: np.ndarray) -> int:
    return int(np.count_nonzero(np.diff(contact, axis=0)))


def test_zero_gap_is_exactly_the_rigid_plant() -> None:
    commands = [(12.0, 0.1)] * 300 + [(-12.0, -0.15)] * 300 + [(0.3, 0.25)] * 200
    rigid, _ = _run(None, commands)
    zero, plant = _run(EffectsConfig.defaults(backlash={"angle": 0.0}), commands)
    assert plant.backlash == 0.0
    for name in ("current", "omega", "theta_worm", "theta_gear"):
        np.testing.assert_array_equal(zero[name], rigid[name], err_msg=name)


def test_reversal_from_rest_turns_the_worm_through_the_gap_while_the_gear_stands() -> None:
    """Driven forward against a small load, stopped (self-locked), load removed, then driven back.

    The gear, held by the load motors' Coulomb drag, stays exactly where it is while the
    worm turns back through the clearance, gap / ratio at the worm; then both move.
    """
    commands = [(3.0, 0.05)] * 400 + [(0.0, 0.05)] * 400 + [(0.0, 0.0)] * 100 + [(-3.0, 0.0)] * 300
    rec, _ = _run(BACKLASH, commands)
    start = 900
    assert rec["omega"][start - 1, 0] == 0.0 and rec["contact"][start - 1, 0] == 1  # at rest, driving flank
    theta_w = rec["theta_worm"][start:, 0] - rec["theta_worm"][start - 1, 0]
    theta_g = rec["theta_gear"][start:, 0] - rec["theta_gear"][start - 1, 0]
    gear_still = np.flatnonzero(theta_g == 0.0)
    assert gear_still.size > 5 and np.all(np.diff(gear_still) == 1)  # one interval, from the start
    lost = -theta_w[gear_still[-1] + 1]  # worm travel until the gear moved
    assert lost == pytest.approx(GAP / GB.ratio, rel=0.05)
    # then the teeth touch on the other side and the gear follows at the ratio
    assert rec["contact"][-1, 0] == -1
    np.testing.assert_allclose(np.diff(rec["theta_gear"][-50:, 0]), GB.ratio * np.diff(rec["theta_worm"][-50:, 0]),
                               rtol=1e-9)
    # rigid: the gear moves with the worm from the first step
    rigid, _ = _run(None, commands)
    assert rigid["theta_gear"][start, 0] != rigid["theta_gear"][start - 1, 0]


def test_the_encoders_see_the_worm_turn_while_the_gear_count_holds() -> None:
    commands = [(3.0, 0.05)] * 200 + [(0.0, 0.05)] * 200 + [(0.0, 0.0)] * 50 + [(-3.0, 0.0)] * 150
    counts_per_gear_count = 1 / GB.ratio  # worm counts per gear count when rigid (both 2000/rev)
    expected = GAP / GB.ratio * 2000 / (2 * np.pi)  # worm counts in the gap: ~42
    for effects, rigid in ((BACKLASH, False), (None, True)):
        sim = SimulatedRig(QUIET, n=1, effects=effects)
        drive, gear = [], []
        for volts, load in commands:
            sim.command(voltage_drive=volts, load_torque=load)
            m = sim.sample()
            drive.append(int(m.count_drive[0]))
            gear.append(int(m.count_load_1[0]))
        drive, gear = np.array(drive[449:]), np.array(gear[449:])  # from rest, then backwards
        held = np.flatnonzero(gear != gear[0])[0]  # samples until the gear count changes
        turned = drive[0] - drive[held - 1]  # worm counts while the gear count held
        if rigid:
            assert turned <= counts_per_gear_count + 1
        else:
            assert turned >= expected - 2 and turned > counts_per_gear_count + 5


def test_flank_change_at_speed_crosses_the_gap_once_and_shows_in_the_current_residual() -> None:
    """Resistive -> assistive load at constant voltage: the gear runs ahead across the gap.

    While the teeth are apart the worm carries no load: the rigid model (Eqs 28-30),
    which assumes the load is transmitted, mispredicts the current; outside the
    crossing it predicts it exactly. The contact goes +1 -> 0 -> -1 once: no chatter.
    """
    commands = [(12.0, 0.2)] * 600 + [(12.0, -0.2)] * 600
    rec, _ = _run(BACKLASH, commands)
    rigid, _ = _run(None, commands)
    contact = rec["contact"][:, 0]
    assert contact[0] == 0 and contact[100] == 1  # assembled mid-gap, engaged within the first steps
    assert _transitions(contact[100:]) == 2
    apart = np.flatnonzero(contact[100:] == 0) + 100
    assert apart.size > 2 and np.all(np.diff(apart) == 1) and 600 <= apart[0] < 610
    assert contact[apart[0] - 1] == 1 and contact[apart[-1] + 1] == -1
    # position: the gear went from one flank to the other, relative to the worm
    mesh = GB.ratio * rec["theta_worm"][:, 0] - rec["theta_gear"][:, 0]
    assert mesh[apart[0] - 1] == pytest.approx(GAP / 2, abs=1e-12)
    assert mesh[apart[-1] + 1] == pytest.approx(-GAP / 2, abs=1e-12)
    # one impact, where the gap closes
    hits = np.flatnonzero(rec["impact_loss"][100:, 0] > 0) + 100
    np.testing.assert_array_equal(hits, [apart[-1] + 1])
    # current: the rigid model's residual is zero except while the teeth are apart
    residual = _rigid_model_residual(rec)[:, 0]
    outside = np.ones(len(commands), bool)
    outside[:100] = False  # the first engagement from mid-gap
    outside[apart[0]:apart[-1] + 2] = False
    assert np.abs(residual[outside]).max() < 1e-9
    assert np.abs(_rigid_model_residual(rigid)[1:]).max() < 1e-9  # the rigid plant is that model (once moving)
    assert residual[apart].max() > 0.02  # [A], the dead time in the current
    # afterwards the two plants run alike again (same steady state)
    assert rec["current"][-1, 0] == pytest.approx(rigid["current"][-1, 0], rel=1e-6)


def test_load_at_the_switching_torque_does_not_chatter() -> None:
    """N ~ 0: an aiding load equal to the gear-side drag leaves the teeth touching or lets them drift over once."""
    fractions = np.array([0.99, 1.0, 1.01])
    plant = RigPlant(RIG, fractions.size, effects=BACKLASH)
    for _ in range(600):
        plant.step(DT, 12.0, 0.0)
    load = -fractions * no_load_switching_torque(RIG, plant.state.omega_worm)
    contact = []
    for _ in range(3000):
        plant.step(DT, 12.0, load)
        contact.append(plant.state.contact.copy())
    contact = np.array(contact)
    assert all(_transitions(contact[:, j]) <= 2 for j in range(fractions.size))
    assert contact[-1, -1] == -1  # beyond the switching torque the coast flank takes over


def test_a_self_locked_worm_holds_the_gear_on_either_flank() -> None:
    """At rest with no voltage an aiding load moves the gear across the gap onto the coast side, where
    the self-locking worm holds it; the contact changes once and everything is then exactly at rest."""
    plant = RigPlant(RIG, 2, effects=BACKLASH)
    for _ in range(200):
        plant.step(DT, 0.0, np.array([0.2, -0.2]))
    np.testing.assert_array_equal(plant.state.contact, [1, -1])
    contact, omega = [], []
    for _ in range(400):
        plant.step(DT, 0.0, np.array([-0.2, 0.2]))
        contact.append(plant.state.contact.copy())
        omega.append(plant.state.omega_worm.copy())
    np.testing.assert_array_equal(plant.state.contact, [-1, 1])
    assert _transitions(np.array(contact)) == 4  # each rig: touching -> apart -> other flank
    np.testing.assert_array_equal(np.array(omega)[-200:], 0.0)
    np.testing.assert_array_equal(plant.state.omega_gear, 0.0)
