"""SimulatedRig: sample clock, determinism, vectorisation, ground truth (flank, mode, mu)."""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest

from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import no_load_switching_torque
from worm_model.physics.modes import Flank, Mode
from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.simulated_rig import SimulatedRig

RIG = load_rig()
QUIET = replace(RIG, sensors=replace(RIG.sensors, current_noise_std=0.0, tacho_noise_std=0.0))


def _samples(sim: SimulatedRig, count: int) -> list:
    return [sim.sample() for _ in range(count)]


def _field_arrays(measurement) -> dict:
    return {f.name: getattr(measurement, f.name) for f in fields(measurement)}


def test_sample_clock_and_argument_checks() -> None:
    sim = SimulatedRig(RIG, n=2)
    with pytest.raises(RuntimeError):
        sim.truth()
    _samples(sim, 40)
    assert sim.seq == 40
    assert sim.time == pytest.approx(40 / RIG.sensors.sample_rate_hz)
    with pytest.raises(ValueError):
        SimulatedRig(RIG, substeps=0)


def _run(seed: int, rig=RIG, n: int = 3):
    sim = SimulatedRig(rig, n=n, seed=seed)
    sim.command(voltage_drive=np.array([12.0, -6.0, 0.5]), load_torque=np.array([0.1, -0.1, 0.25]))
    out = _samples(sim, 80)
    sim.command(load_torque=0.0)
    out += _samples(sim, 20)
    return out, sim.truth()


def test_same_seed_gives_identical_samples_and_different_seed_different_noise() -> None:
    a, truth_a = _run(seed=11)
    b, truth_b = _run(seed=11)
    c, truth_c = _run(seed=12)
    for ma, mb in zip(a, b):
        for name, value in _field_arrays(ma).items():
            np.testing.assert_array_equal(value, getattr(mb, name), err_msg=name)
    current_a = np.array([m.current_drive for m in a])
    current_c = np.array([m.current_drive for m in c])
    tacho_a = np.array([m.omega_worm for m in a])
    tacho_c = np.array([m.omega_worm for m in c])
    # (the drive tacho's ADC step is ~2 noise sigmas: different noise often rounds alike)
    assert np.mean(current_a != current_c) > 0.5 and np.mean(tacho_a != tacho_c) > 0.3
    # the noise is in the sensors only: the plant (truth) does not depend on the seed
    np.testing.assert_array_equal(truth_a.omega_worm, truth_c.omega_worm)
    np.testing.assert_array_equal(truth_a.current_drive, truth_c.current_drive)


def test_n_rigs_side_by_side_equal_single_rigs_without_noise() -> None:
    together, truth = _run(seed=0, rig=QUIET)
    volts, loads = [12.0, -6.0, 0.5], [0.1, -0.1, 0.25]
    for j in range(3):
        sim = SimulatedRig(QUIET, n=1, seed=99)
        sim.command(voltage_drive=volts[j], load_torque=loads[j])
        alone = _samples(sim, 80)
        sim.command(load_torque=0.0)
        alone += _samples(sim, 20)
        for mt, ma in zip(together, alone):
            for name, value in _field_arrays(mt).items():
                np.testing.assert_array_equal(value[j], getattr(ma, name)[0], err_msg=name)
        assert sim.truth().omega_worm[0] == truth.omega_worm[j]


def test_flank_and_mode_follow_the_load_through_all_three_modes() -> None:
    """Resistive -> pseudo-resistive -> assistive at positive speed (physics.md section 3)."""
    sim = SimulatedRig(QUIET, n=2)
    sim.command(voltage_drive=np.array([12.0, -12.0]), load_torque=np.array([0.2, -0.2]))
    _samples(sim, 300)
    resistive = sim.truth()
    w = resistive.omega_worm
    assert w[0] > 0 > w[1]
    np.testing.assert_array_equal(resistive.flank, Flank.DRIVING)
    np.testing.assert_array_equal(resistive.mode, Mode.RESISTIVE)

    # aiding, but weaker than the gear-side drag: N stays on the driving flank
    tau_sw = no_load_switching_torque(RIG, w)
    sim.command(load_torque=-0.5 * tau_sw * np.sign(w))
    _samples(sim, 300)
    pseudo = sim.truth()
    np.testing.assert_array_equal(pseudo.flank, Flank.DRIVING)
    np.testing.assert_array_equal(pseudo.mode, Mode.PSEUDO_RESISTIVE)

    sim.command(load_torque=np.array([-0.2, 0.2]))  # overrunning load
    _samples(sim, 300)
    assistive = sim.truth()
    assert np.all(np.sign(assistive.omega_worm) == np.sign(w))
    np.testing.assert_array_equal(assistive.flank, Flank.COAST)
    np.testing.assert_array_equal(assistive.mode, Mode.ASSISTIVE)


def test_truth_friction_matches_the_friction_law_while_moving_and_standstill_is_reported() -> None:
    sim = SimulatedRig(QUIET, n=3)
    sim.command(voltage_drive=np.array([12.0, -15.0, 0.0]), load_torque=np.array([0.15, -0.1, 0.2]))
    _samples(sim, 400)
    truth = sim.truth()
    moving = truth.omega_worm[:2]
    # Eq. 23 recovers the mu the plant integrates with (friction law holds in the dynamics)
    np.testing.assert_allclose(truth.mu[:2], friction_coefficient(RIG.friction, RIG.gearbox, moving), rtol=1e-6)
    assert np.all(truth.normal_force[:2] > 0) and np.all(truth.friction_force[:2] > 0)
    # truth load torque is what the load motors make (count * K_t * i_load)
    np.testing.assert_allclose(truth.tau_load, RIG.load_motor_count * RIG.load_motor.torque_constant
                               * sim.plant.state.current_load, rtol=1e-12)
    np.testing.assert_allclose(truth.tau_load, [0.15, -0.1, 0.2], rtol=1e-9)
    # the third rig never moved (self-locked, no voltage)
    assert truth.omega_worm[2] == 0.0
    assert truth.flank[2] == Flank.NONE and truth.mode[2] == Mode.STANDSTILL


# --- the acceptance checks at the level of what the sensors report ---------------------------

def test_without_effects_the_measured_steady_current_is_the_eq28_30_prediction() -> None:
    """Mean measured drive current at steady state vs K_t i = b w + c sign w + (r_w/r_g) K_s(mu) D (Eqs 28, 30).

    The prediction uses the mean measured speed and load torque only (as a user would),
    so ADC quantisation, noise and sampling instants are all inside the comparison.
    """
    from worm_model.physics.dynamics import reflected_input_torque
    from worm_model.physics.gear_side import gear_side_load

    volts = np.array([12.0, -12.0, 20.0, 6.0, -18.0])
    loads = np.array([0.2, 0.2, -0.15, 0.05, -0.1])  # resistive and assistive, both directions
    sim = SimulatedRig(RIG, n=volts.size, seed=3)
    sim.command(voltage_drive=volts, load_torque=loads)
    _samples(sim, 400)
    samples = _samples(sim, 2000)
    current = np.array([m.current_drive for m in samples])
    omega = np.array([m.omega_worm for m in samples]).mean(0)
    tau = np.array([m.tau_load for m in samples]).mean(0)
    mu = friction_coefficient(RIG.friction, RIG.gearbox, omega)
    motor = RIG.drive_motor
    torque = (motor.viscous_drag * omega + motor.coulomb_drag * np.sign(omega)
              + reflected_input_torque(RIG.gearbox, mu, gear_side_load(RIG, tau, omega), omega))
    predicted = torque / motor.torque_constant
    standard_error = current.std(0) / np.sqrt(len(samples))
    # (samples are independent: open loop, white noise; 5 standard errors ~ 2.4 mA, while e.g. the
    # default bearing drag would shift the current by ~60 mA)
    assert np.all(np.abs(current.mean(0) - predicted) < 5 * standard_error), current.mean(0) - predicted


def test_same_seed_same_run_with_every_effect_on() -> None:
    from worm_rig_driver.sim.effects import EFFECTS, EffectsConfig

    config = EffectsConfig.defaults(*EFFECTS, oil_temperature={"time_constant": 0.1})

    def run(seed):
        sim = SimulatedRig(RIG, n=2, seed=seed, effects=config)
        sim.command(voltage_drive=np.array([12.0, -9.0]), load_torque=np.array([0.2, -0.05]))
        out = _samples(sim, 150)
        sim.command(load_torque=np.array([-0.2, 0.1]))
        out += _samples(sim, 150)
        return out, sim.truth()

    (a, truth_a), (b, truth_b), (c, truth_c) = run(7), run(7), run(8)
    for ma, mb in zip(a, b):
        for name, value in _field_arrays(ma).items():
            np.testing.assert_array_equal(value, getattr(mb, name), err_msg=name)
    for truth in (truth_b, truth_c):  # the plant and its effects do not depend on the noise seed
        np.testing.assert_array_equal(truth.omega_worm, truth_a.omega_worm)
        np.testing.assert_array_equal(truth.effects["oil_temperature"], truth_a.effects["oil_temperature"])
    assert np.mean(np.array([m.current_drive for m in a]) != np.array([m.current_drive for m in c])) > 0.5


def test_truth_reports_the_teeth_apart_in_the_backlash() -> None:
    from worm_rig_driver.sim.effects import EffectsConfig

    sim = SimulatedRig(QUIET, n=1, substeps=10, effects=EffectsConfig.defaults("backlash"))
    sim.command(voltage_drive=12.0, load_torque=0.2)
    _samples(sim, 300)
    sim.command(load_torque=-0.2)
    seen = []
    for _ in range(20):
        sim.sample()
        t = sim.truth()
        seen.append((int(t.contact[0]), int(t.flank[0]), float(t.normal_force[0])))
    contacts = [c for c, _, _ in seen]
    assert contacts[0] == 1 and 0 in contacts and contacts[-1] == -1
    for contact, flank, normal in seen:
        if contact == 0:
            assert flank == Flank.NONE and normal == 0.0
        else:
            assert flank == contact and normal > 0  # moving forward: fixed-frame side = flank
