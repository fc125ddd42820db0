"""RigPlant against the physics (physics.md sections 4-7): steady state, energy, stick, vectorisation.

Every expectation is derived here from worm_model (Eqs 28-29, the friction model,
the gear-side drag), never copied from a run of the plant.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.efficiency import flank_factor
from worm_model.physics.friction import friction_coefficient, sliding_velocity
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.internal_forces import internal_forces
from worm_model.physics.parameters import load_rig
from worm_model.physics.steady_state import steady_worm_speed
from worm_rig_driver.sim.plant import STANDSTILL_SPEED, RigPlant

RIG = load_rig()
GB = RIG.gearbox
DRIVE = RIG.drive_motor
LOAD = RIG.load_motor
DT = 5e-4  # [s], well below the ~9 ms mechanical and 0.8 ms electrical time constants


def _run(plant: RigPlant, steps: int, voltage, load, dt: float = DT) -> np.ndarray:
    """Step the plant with held commands; return omega history, shape (steps, n)."""
    history = np.empty((steps, plant.n))
    for k in range(steps):
        plant.step(dt, voltage, load)
        history[k] = plant.state.omega_worm
    return history


# --- steady state: Eq. 28 (a_w = 0) + Eq. 29 (di/dt = 0) --------------------------------------------

# (V, tau_load): resistive and assistive loads, both directions of rotation.
STEADY_CASES = [(12.0, 0.2), (12.0, -0.2), (-12.0, -0.2), (-12.0, 0.2), (20.0, 0.1), (-18.0, 0.05)]


def test_steady_state_matches_quasi_static_model() -> None:
    volts = np.array([c[0] for c in STEADY_CASES])
    loads = np.array([c[1] for c in STEADY_CASES])
    plant = RigPlant(RIG, len(STEADY_CASES))
    _run(plant, 1000, volts, loads)  # 0.5 s >> every time constant
    w, i = plant.state.omega_worm, plant.state.current_drive

    # The cases really are both modes in both directions (D = sigma * gear-side load).
    D = np.sign(w) * gear_side_load(RIG, loads, w)
    assert set(np.sign(w)) == {1.0, -1.0} and (D > 0).sum() == 3 and (D < 0).sum() == 3

    expected_w = np.array([steady_worm_speed(RIG, v, t) for v, t in STEADY_CASES])
    np.testing.assert_allclose(w, expected_w, rtol=1e-7)
    # Eq. 29 with di/dt = 0 and Eq. 28 with a_w = 0, as residuals [V] and [N m].
    np.testing.assert_allclose(volts, DRIVE.resistance * i + DRIVE.back_emf_constant * w, atol=1e-9)
    mu = friction_coefficient(RIG.friction, GB, w)
    rhs = (DRIVE.viscous_drag * w + DRIVE.coulomb_drag * np.sign(w)
           + reflected_input_torque(GB, mu, gear_side_load(RIG, loads, w), w))
    np.testing.assert_allclose(DRIVE.torque_constant * i, rhs, atol=1e-10)
    # The load motors settled to what was asked.
    np.testing.assert_allclose(RIG.load_motor_count * LOAD.torque_constant * plant.state.current_load, loads,
                               rtol=1e-12)


# --- energy balance ---------------------------------------------------------------------------------

def test_energy_balance_over_a_run_with_transients_mode_changes_and_reversal() -> None:
    """Electrical input = copper + motor drag + mesh friction (mu N V_s) + gear-shaft power + stored energy.

    The mesh loss uses mu from the friction model and N from Eqs 19-21, so a plant
    whose acceleration ignored the friction law would fail the balance (the mesh
    term is 2-4 % of the input, ten times the tolerance; the discretisation error at
    dt = 1e-4 s is ~0.03 %).
    """
    dt, steps = 1e-4, 2500
    plant = RigPlant(RIG, 2)
    n = plant.n
    rec = {name: np.empty((steps, n)) for name in
           ("v", "i0", "i1", "w0", "w1", "tau_in", "gear_load", "alpha")}
    for k in range(steps):
        t = k * dt
        volts = np.array([12.0, -15.0]) if t < 0.17 else np.array([-8.0, 10.0])  # then both reverse
        loads = np.array([0.1, 0.05]) if t < 0.08 else np.array([-0.15, -0.1])  # resistive <-> assistive
        rec["i0"][k], rec["w0"][k] = plant.state.current_drive, plant.state.omega_worm
        out = plant.step(dt, volts, loads)
        rec["i1"][k], rec["w1"][k] = plant.state.current_drive, plant.state.omega_worm
        rec["v"][k], rec["tau_in"][k] = out.voltage_drive, out.tau_in
        rec["gear_load"][k], rec["alpha"][k] = out.gear_load, out.alpha_worm
    assert np.all(np.sign(rec["w1"][1000]) == [1, -1]) and np.all(np.sign(rec["w1"][-1]) == [-1, 1])

    i_mid = 0.5 * (rec["i0"] + rec["i1"])
    w_mid = 0.5 * (rec["w0"] + rec["w1"])
    w0 = rec["w0"]
    electrical_in = (rec["v"] * i_mid).sum(0) * dt
    copper = (DRIVE.resistance * 0.5 * (rec["i0"] ** 2 + rec["i1"] ** 2)).sum(0) * dt
    magnetic = 0.5 * DRIVE.inductance * plant.state.current_drive ** 2
    motor_drag = ((DRIVE.viscous_drag * w0 + DRIVE.coulomb_drag * np.sign(w0)) * w_mid).sum(0) * dt
    forces = internal_forces(GB, rec["tau_in"], rec["gear_load"], w0, rec["alpha"],
                             worm_inertia=RIG.total_worm_inertia, gear_inertia=RIG.total_gear_inertia)
    mu = friction_coefficient(RIG.friction, GB, w0)
    v_sliding = sliding_velocity(GB, w_mid)
    mesh = (mu * forces.normal_force * v_sliding).sum(0) * dt
    gear_shaft = (rec["gear_load"] * GB.ratio * w_mid).sum(0) * dt  # load motors incl. their drag
    w_end = plant.state.omega_worm
    kinetic = 0.5 * (RIG.total_worm_inertia + RIG.total_gear_inertia * GB.ratio ** 2) * w_end ** 2

    tolerance = 2e-3
    assert np.all(mesh > 5 * tolerance * electrical_in)  # leaving the friction term out would fail
    residual = electrical_in - (copper + magnetic + motor_drag + mesh + gear_shaft + kinetic)
    assert np.all(np.abs(residual) < tolerance * electrical_in), residual / electrical_in


# --- stick at standstill ----------------------------------------------------------------------------

def _breakaway_margin(voltage: float, tau_load: float, sigma: float) -> float:
    """Quasi-static torque surplus [N m] for starting in direction sigma from rest (> 0: it starts).

    Frame of motion sigma: T = sigma K_t V/R - c (drive drag opposes the motion),
    D = sigma tau_load + count c_load (load-motor drag too); the load needs
    (r_w/r_g) K_s(mu_static) D with s = sign(D) (Eq. 28, a_w = 0).
    """
    mu_s = float(friction_coefficient(RIG.friction, GB, 0.0))
    T = sigma * DRIVE.torque_constant * voltage / DRIVE.resistance - DRIVE.coulomb_drag
    D = sigma * tau_load + RIG.load_motor_count * LOAD.coulomb_drag
    s = 1.0 if D >= 0 else -1.0
    return T - GB.radius_ratio * float(flank_factor(GB, mu_s, s)) * D


STUCK_CASES = [(0.0, 0.25), (0.0, -0.25), (0.5, 0.25), (-0.5, -0.25)]


def test_rig_is_self_locking_at_rest() -> None:
    assert float(friction_coefficient(RIG.friction, GB, 0.0)) > GB.self_locking_mu


@pytest.mark.parametrize("voltage, tau_load", STUCK_CASES)
def test_small_voltage_against_large_load_stays_exactly_at_rest(voltage: float, tau_load: float) -> None:
    for sigma in (1.0, -1.0):  # neither direction can start (the physics says so, with margin)
        assert _breakaway_margin(voltage, tau_load, sigma) < -2e-3
    plant = RigPlant(RIG, 1)
    preload = _run(plant, 100, 0.0, tau_load)  # the load builds up first (2 ms current loop)
    held = _run(plant, 400, voltage, tau_load)
    assert np.all(preload == 0.0) and np.all(held == 0.0)  # exactly zero every step: no chatter
    assert plant.state.theta_worm[0] == 0.0


def test_breakaway_direction_follows_the_physics() -> None:
    """Large voltages break away in their own direction, against or with the load; a small
    voltage moves a self-locked worm only when the load aids that direction."""
    cases = [(12.0, 0.25), (-12.0, 0.25), (12.0, -0.25), (-12.0, -0.25), (0.5, -0.25), (-0.5, 0.25)]
    expected = []
    for v, tau in cases:
        margins = {sigma: _breakaway_margin(v, tau, sigma) for sigma in (1.0, -1.0)}
        starts = [sigma for sigma, m in margins.items() if m > 2e-3]
        assert len(starts) == 1 and all(abs(m) > 2e-3 for m in margins.values())
        expected.append(starts[0])
    plant = RigPlant(RIG, len(cases))
    volts = np.array([c[0] for c in cases])
    loads = np.array([c[1] for c in cases])
    assert np.all(_run(plant, 100, 0.0, loads) == 0.0)
    history = _run(plant, 200, volts, loads)
    np.testing.assert_array_equal(np.sign(history[-1]), expected)
    # monotone start: no step goes the wrong way
    assert np.all(np.sign(history) * np.array(expected) >= 0)


def test_deceleration_into_stick_ends_exactly_at_zero() -> None:
    """Many worms coasting into a self-locking load from different speeds all stop at exactly 0.

    Regression: a deceleration that stopped just short of zero (|w| < STANDSTILL_SPEED)
    used to keep that creep speed forever while the worm was held.
    """
    n = 2000
    plant = RigPlant(RIG, n)
    plant.state.omega_worm[:] = np.linspace(1.0, 50.0, n)
    plant.state.current_load[:] = 0.25 / (RIG.load_motor_count * LOAD.torque_constant)
    history = _run(plant, 400, 0.0, 0.25)
    assert np.all(plant.state.omega_worm == 0.0)
    assert np.all(history >= 0.0)  # never reversed
    theta = plant.state.theta_worm.copy()
    _run(plant, 50, 0.0, 0.25)
    np.testing.assert_array_equal(plant.state.theta_worm, theta)


def test_creep_below_standstill_speed_is_held_when_the_worm_cannot_break_away() -> None:
    plant = RigPlant(RIG, 2)
    plant.state.omega_worm[:] = [0.5 * STANDSTILL_SPEED, -0.5 * STANDSTILL_SPEED]
    _run(plant, 5, 0.0, 0.0)
    np.testing.assert_array_equal(plant.state.omega_worm, 0.0)


@pytest.mark.parametrize("tau_load", [0.1, 0.0, -0.1])
def test_speed_reversal_passes_zero_with_a_single_sign_change(tau_load: float) -> None:
    plant = RigPlant(RIG, 1)
    forward = _run(plant, 300, 12.0, tau_load)
    reverse = _run(plant, 600, -12.0, tau_load)
    w = np.concatenate([forward, reverse])[:, 0]
    assert w[299] > 50.0 and w[-1] < -50.0
    signs = np.sign(w[w != 0.0])
    assert np.count_nonzero(np.diff(signs)) == 1
    assert np.count_nonzero(w[300:] == 0.0) <= 3  # passes zero, does not linger


def test_reversal_command_too_weak_to_break_away_stops_exactly_at_zero() -> None:
    volts_back = -0.1
    assert _breakaway_margin(volts_back, 0.0, -1.0) < 0 and _breakaway_margin(volts_back, 0.0, 1.0) < 0
    plant = RigPlant(RIG, 1)
    _run(plant, 300, 12.0, 0.0)
    w = _run(plant, 600, volts_back, 0.0)[:, 0]
    assert np.all(w >= 0.0)  # no sign change at all: no chatter around zero
    assert np.all(w[-200:] == 0.0)


# --- limits and vectorisation -------------------------------------------------------------------------

def test_voltage_and_load_commands_are_clamped_to_the_hardware() -> None:
    plant = RigPlant(RIG, 3)
    out = plant.step(DT, np.array([30.0, -30.0, 5.0]), np.array([10.0, -10.0, 0.0]))
    np.testing.assert_array_equal(out.voltage_drive, [RIG.supply_voltage, -RIG.supply_voltage, 5.0])
    np.testing.assert_array_equal(out.drive_saturated, [True, True, False])
    for _ in range(200):
        out = plant.step(DT, 0.0, np.array([10.0, -10.0, 0.0]))
    np.testing.assert_allclose(out.tau_load, [RIG.max_load_torque, -RIG.max_load_torque, 0.0], rtol=1e-9)


def test_n_rigs_side_by_side_equal_separate_single_rig_runs() -> None:
    rng = np.random.default_rng(3)
    n, steps = 5, 400
    volts = rng.uniform(-20, 20, (steps, n))
    volts[:, 0] = 0.3  # one stays stuck, one reverses
    volts[steps // 2:, 1] *= -1
    loads = rng.uniform(-0.25, 0.25, (steps, n))
    loads[:, 0] = 0.25
    together = RigPlant(RIG, n)
    alone = [RigPlant(RIG, 1) for _ in range(n)]
    for k in range(steps):
        out = together.step(DT, volts[k], loads[k])
        for j, plant in enumerate(alone):
            single = plant.step(DT, volts[k, j:j + 1], loads[k, j:j + 1])
            assert single.alpha_worm[0] == out.alpha_worm[j]
    for name in ("current_drive", "omega_worm", "theta_worm", "current_load"):
        np.testing.assert_array_equal(getattr(together.state, name),
                                      [getattr(p.state, name)[0] for p in alone])


# --- the plant's own Eq. 28 is worm_model's ---------------------------------------------------------

def test_plant_eq28_agrees_with_worm_model_dynamics() -> None:
    from worm_model.physics.dynamics import worm_acceleration
    from worm_rig_driver.sim.plant import Eq28

    rng = np.random.default_rng(5)
    n = 20000
    mu = rng.uniform(0.0, 0.3, n)  # both sides of self-locking (cos(phi_n) tan(lambda) ~ 0.094)
    tau_in, tau_d = rng.normal(0, 0.05, n), rng.normal(0, 0.3, n)
    omega = rng.normal(0, 100, n)
    jw, jg = RIG.total_worm_inertia * 1.3, RIG.total_gear_inertia * 0.7
    alpha, flank = Eq28(RIG, jw, jg)(mu, tau_in, tau_d, omega)
    alpha_ref, flank_ref = worm_acceleration(GB, mu, tau_in, tau_d, omega, jw, jg)
    np.testing.assert_array_equal(flank, flank_ref)
    np.testing.assert_allclose(alpha, alpha_ref, rtol=1e-12, atol=1e-9)


# --- energy balance with every effect on the shafts, backlash included ------------------------------

def test_energy_balance_with_every_plant_effect_and_backlash() -> None:
    """Electrical input = copper + magnetic + motor drag + worm-side effects + mesh friction
    + gear-shaft work (load motors, their drag, gear-side effects) + kinetic energy + impacts.

    Load flips cross the backlash (impacts), reversals pass zero speed; the oil warms.
    Mesh friction is F_f V_s with F_f from Eq. 22 on the torques and the true inertias,
    counted only while the teeth touch. Tolerance 1e-3 of the input (the semi-implicit
    step at dt = 1e-4 s leaves ~3e-4).
    """
    from worm_rig_driver.sim.effects import EFFECTS, EffectsConfig

    shaft_effects = [name for name in EFFECTS if name not in ("sensor_gain", "sensor_offset", "pwm")]
    config = EffectsConfig.defaults(*shaft_effects, oil_temperature={"time_constant": 0.05, "thermal_resistance": 50})
    dt, steps = 1e-4, 4000
    plant = RigPlant(RIG, 2, effects=config)
    names = ("v", "i0", "i1", "w0", "w1", "g0", "g1", "tau_in", "gear_load", "alpha", "worm_fx", "contact", "impact")
    rec = {name: np.empty((steps, 2)) for name in names}
    for k in range(steps):
        t = k * dt
        volts = np.array([12.0, -15.0]) if t < 0.17 else np.array([-8.0, 10.0])
        loads = np.array([0.1, 0.05]) if t < 0.08 else np.array([-0.15, -0.1])
        if t > 0.3:
            loads = np.array([0.2, 0.0])
        s = plant.state
        rec["i0"][k], rec["w0"][k], rec["g0"][k] = s.current_drive, s.omega_worm, s.omega_gear
        out = plant.step(dt, volts, loads)
        rec["i1"][k], rec["w1"][k], rec["g1"][k] = s.current_drive, s.omega_worm, s.omega_gear
        rec["v"][k], rec["tau_in"][k], rec["gear_load"][k] = out.voltage_drive, out.tau_in, out.gear_load
        rec["alpha"][k], rec["worm_fx"][k] = out.alpha_worm, out.worm_effect_torque
        rec["contact"][k], rec["impact"][k] = out.contact, out.impact_loss
    assert np.all((rec["contact"] == 0).sum(0) > 20)  # the teeth did cross the gap
    assert np.all((rec["impact"] > 0).sum(0) >= 2)

    i_mid, w_mid, g_mid, w0 = (0.5 * (rec["i0"] + rec["i1"]), 0.5 * (rec["w0"] + rec["w1"]),
                               0.5 * (rec["g0"] + rec["g1"]), rec["w0"])
    electrical_in = (rec["v"] * i_mid).sum(0) * dt
    copper = (DRIVE.resistance * 0.5 * (rec["i0"] ** 2 + rec["i1"] ** 2)).sum(0) * dt
    magnetic = 0.5 * DRIVE.inductance * plant.state.current_drive ** 2
    motor_drag = ((DRIVE.viscous_drag * w0 + DRIVE.coulomb_drag * np.sign(w0)) * w_mid).sum(0) * dt
    # the worm-side effect torques: tau_in minus the motor's shaft torque
    np.testing.assert_allclose(rec["worm_fx"], rec["tau_in"] - (DRIVE.torque_constant * rec["i1"]
                               - DRIVE.viscous_drag * w0 - DRIVE.coulomb_drag * np.sign(w0)), atol=1e-12)
    worm_effects = (-rec["worm_fx"] * w_mid).sum(0) * dt
    forces = internal_forces(GB, rec["tau_in"], rec["gear_load"], w0, rec["alpha"],
                             worm_inertia=plant.worm_inertia, gear_inertia=plant.gear_inertia)
    touching = rec["contact"] != 0
    mesh = np.where(touching, forces.friction_force * sliding_velocity(GB, w_mid), 0.0).sum(0) * dt
    gear_shaft = (rec["gear_load"] * g_mid).sum(0) * dt
    kinetic = 0.5 * plant.worm_inertia * plant.state.omega_worm ** 2 + 0.5 * plant.gear_inertia \
        * plant.state.omega_gear ** 2
    impacts = rec["impact"].sum(0)
    assert np.all(mesh > 0.005 * electrical_in) and np.all(worm_effects > 0.05 * electrical_in)
    residual = electrical_in - (copper + magnetic + motor_drag + worm_effects + mesh + gear_shaft + kinetic + impacts)
    assert np.all(np.abs(residual) < 1e-3 * electrical_in), residual / electrical_in


# --- self-locking where the parameters say so -------------------------------------------------------

@pytest.mark.parametrize("mu, locks", [(0.15, True), (0.03, False)])
def test_an_aiding_load_back_drives_the_worm_only_when_the_box_does_not_self_lock(mu: float, locks: bool) -> None:
    rig = replace(RIG, friction=replace(RIG.friction, model="constant", mu_constant=mu))
    assert (mu > GB.self_locking_mu) == locks
    plant = RigPlant(rig, 2)
    history = _run(plant, 400, 0.0, np.array([0.25, -0.25]))  # no voltage, the load pushes either way
    if locks:
        assert np.all(history == 0.0)
    else:  # the gear drives the worm, in the direction the load pushes (against the shorted motor's braking)
        np.testing.assert_array_equal(np.sign(history[-1]), [-1.0, 1.0])
        assert np.all(np.abs(history[-1]) > 0.5)
        assert np.all(np.sign(history[100:]) == np.sign(history[-1]))
