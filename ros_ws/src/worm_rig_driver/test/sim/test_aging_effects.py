"""The aging effects (wear, lubricant_loss, seal_drag): a new gearbox at their defaults, and each ages what it says.

Expectations come from the effects' definitions and the simulator's ground truth (mu from Eq. 23 on the
true torques, the plant's backlash), or from a run with the effect against the same run without it.
"""
from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np
import pytest

from worm_model.physics.friction import friction_coefficient
from worm_model.physics.parameters import load_rig
from worm_rig_driver.sim.effects import EffectsConfig
from worm_rig_driver.sim.simulated_rig import SimulatedRig

RIG = load_rig()
QUIET = replace(RIG, sensors=replace(RIG.sensors, current_noise_std=0.0, tacho_noise_std=0.0))
AGING = ("wear", "lubricant_loss", "seal_drag")


def _run(effects, steps: int, n: int = 1, scalar=None, voltage=12.0, load=0.15, seed=1):
    sim = SimulatedRig(RIG, n=n, seed=seed, effects=effects, scalar=scalar)
    sim.command(voltage_drive=voltage, load_torque=load)
    return sim, [sim.sample() for _ in range(steps)]


def test_at_their_defaults_the_aging_effects_leave_the_gearbox_as_new() -> None:
    """Bit for bit, on both paths: 'every effect at its default' stays a new gearbox."""
    for scalar in (True, False):
        _, plain = _run(None, 400, scalar=scalar)
        sim, aged = _run(EffectsConfig.defaults(*AGING), 400, scalar=scalar)
        assert sim.scalar is scalar and sim.plant.backlash == 0.0
        for a, b in zip(plain, aged):
            for f in fields(a):
                np.testing.assert_array_equal(getattr(a, f.name), getattr(b, f.name), err_msg=f.name)


def test_wear_raises_mu_and_the_drags_with_the_hours_and_widens_the_gap() -> None:
    hours, mu_rate, worm_rate, gear_rate = 2000.0, 0.05, 1e-3, 2e-3
    backlash_rate = math.radians(3 / 60)
    config = EffectsConfig.defaults(wear={"hours": hours}, backlash={})
    new = EffectsConfig.defaults("backlash")
    sim, _ = _run(config, 600, n=2, scalar=False, voltage=np.array([12.0, -12.0]), load=np.array([0.15, -0.1]))
    base, _ = _run(new, 600, n=2, scalar=False, voltage=np.array([12.0, -12.0]), load=np.array([0.15, -0.1]))
    truth = sim.truth()
    mu_rig = friction_coefficient(RIG.friction, RIG.gearbox, truth.omega_worm)
    np.testing.assert_allclose(truth.mu, mu_rig * (1 + mu_rate * hours / 1000), rtol=1e-9)
    assert sim.plant.backlash == pytest.approx(base.plant.backlash + backlash_rate * hours / 1000, rel=1e-12)
    # the drags: the worm shaft's effect torque is -2 mN m sign(omega), the gear shaft's +4 mN m sign(omega_gear)
    w = truth.omega_worm
    out = sim.plant._forces(w, RIG.gearbox.ratio * w, truth.current_drive, truth.tau_load)
    np.testing.assert_allclose(out[3], -worm_rate * hours / 1000 * np.sign(w), rtol=1e-12)
    np.testing.assert_allclose(out[4], gear_rate * hours / 1000 * np.sign(w), rtol=1e-12)


def test_wear_runs_on_with_its_time_factor_and_each_rig_keeps_its_own_age() -> None:
    config = EffectsConfig.defaults(wear={"hours": 100.0, "time_factor": 3600.0, "mu_rate": 0.1})
    sim = SimulatedRig(QUIET, n=3, effects=config)
    wear = sim.plant.fx.effects[0]
    wear.hours[:] = [0.0, 500.0, 1000.0]  # rigs of different ages side by side
    sim.command(voltage_drive=12.0, load_torque=0.15)
    for _ in range(1000):  # 1 s of rig time: one hour of wear each
        sim.sample()
    truth = sim.truth()
    np.testing.assert_allclose(truth.effects["wear_hours"], [1.0, 501.0, 1001.0], rtol=1e-9)
    mu_rig = friction_coefficient(RIG.friction, RIG.gearbox, truth.omega_worm)
    # (the truth's mu is the last step's: its age one substep, 0.5 ms of an hour per second, younger)
    np.testing.assert_allclose(truth.mu / mu_rig, 1 + 0.1 * np.array([1.0, 501.0, 1001.0]) / 1000, rtol=1e-7)


@pytest.mark.parametrize("duration", [0.0, 0.2])
def test_lubricant_loss_steps_mu_up_at_its_time(duration: float) -> None:
    config = EffectsConfig.defaults(lubricant_loss={"rise": 0.3, "at": 0.3, "duration": duration})
    sim = SimulatedRig(QUIET, n=1, effects=config)
    sim.command(voltage_drive=12.0, load_torque=0.15)
    ratio = []
    for _ in range(700):
        sim.sample()
        truth = sim.truth()
        ratio.append(truth.mu[0] / friction_coefficient(RIG.friction, RIG.gearbox, truth.omega_worm)[0])
    ratio = np.array(ratio)
    # (Eq. 23 on the truth gives the law's mu once the speed is steady: from rest it takes ~0.15 s)
    assert np.allclose(ratio[150:299], 1.0, rtol=0, atol=1e-6)
    assert ratio[-1] == pytest.approx(1.3, rel=1e-6)
    if duration:
        assert ratio[399] == pytest.approx(1.15, abs=0.01)  # half-way up the ramp at 0.4 s


def test_seal_drag_starts_at_its_onset_and_slows_the_worm() -> None:
    config = EffectsConfig.defaults(seal_drag={"worm_torque": 5e-3, "gear_torque": 10e-3, "onset": 0.5})
    sim, base = SimulatedRig(QUIET, n=1, effects=config), SimulatedRig(QUIET, n=1)
    for s in (sim, base):
        s.command(voltage_drive=12.0, load_torque=0.1)
    speeds = []
    for _ in range(1200):
        sim.sample()
        base.sample()
        speeds.append((sim.truth().omega_worm[0], base.truth().omega_worm[0]))
    speeds = np.array(speeds)
    assert np.array_equal(speeds[:499, 0], speeds[:499, 1])  # nothing before the onset
    # after it: the drags cost speed; the loss matches the extra torque over the motor's slope K_t K_e / R
    motor = RIG.drive_motor
    extra = 5e-3 + 10e-3 * RIG.gearbox.ratio / 0.7  # worm drag + gear drag reflected (~70 % efficiency)
    slope = motor.torque_constant * motor.back_emf_constant / motor.resistance
    drop = speeds[-1, 1] - speeds[-1, 0]
    assert drop == pytest.approx(extra / slope, rel=0.05)


def test_the_aging_effects_agree_on_the_scalar_and_the_vectorised_path() -> None:
    config = EffectsConfig.defaults(wear={"hours": 3000.0, "time_factor": 3600.0}, backlash={},
                                    lubricant_loss={"rise": 0.3, "at": 0.2, "duration": 0.1},
                                    seal_drag={"worm_torque": 4e-3, "gear_torque": 8e-3, "onset": 0.3})
    fast, slow = (SimulatedRig(RIG, n=1, seed=5, effects=config, scalar=s) for s in (True, False))
    assert fast.scalar and not slow.scalar
    for k in range(800):
        load = 0.15 if (k // 200) % 2 == 0 else -0.12  # flank changes: the gap crossed
        for sim in (fast, slow):
            sim.command(voltage_drive=10.0, load_torque=load)
        a, b = fast.sample(), slow.sample()
        np.testing.assert_allclose(a.current_drive, b.current_drive, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(a.count_drive, b.count_drive)
    ta, tb = fast.truth(), slow.truth()
    for name in ("omega_worm", "mu", "tau_in"):
        np.testing.assert_allclose(getattr(ta, name), getattr(tb, name), rtol=1e-12, err_msg=name)
    np.testing.assert_allclose(ta.effects["wear_hours"], tb.effects["wear_hours"], rtol=1e-12)
