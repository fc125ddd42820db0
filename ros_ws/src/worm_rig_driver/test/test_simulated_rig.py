"""SimulatedRig: sample clock, determinism, vectorisation, ground truth (flank, mode, mu)."""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest

from worm_model.friction import friction_coefficient
from worm_model.gear_side import no_load_switching_torque
from worm_model.modes import Flank, Mode
from worm_model.parameters import load_rig
from worm_rig_driver.simulated_rig import SimulatedRig

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
