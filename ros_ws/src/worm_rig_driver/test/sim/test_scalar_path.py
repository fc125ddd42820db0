"""The scalar fast path for one rig against the vectorised path it must reproduce.

SimulatedRig(n=1) steps ScalarPlant + ScalarSensors (plain float math) unless told
scalar=False. Both implement the same model with the same floating-point operations
in the same order; they can still differ in the last bit where numpy's vectorised
exp/pow (friction law, Stribeck effect) round differently from libm's. Measured over
the demanding run below (3600 samples in lockstep, noise on; no effects, backlash,
every effect): every Measurement field identical (ADC codes, encoder counts, status:
the noise is drawn alike); of the ~46800 truth values per run, 98-137 not
bit-identical, at most 6.7e-16 of the field's range apart (mu: 3.7e-15 relative).
The tests allow RTOL = 1e-12 and, for the quantised channels, at most MAX_EDGE_FLIPS
samples one code apart (a value within round-off of a quantisation edge): none occurred.
"""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest

from worm_model.physics.friction import FLOAT_FRICTION_MODELS, FRICTION_MODELS
from worm_model.physics.gear_side import no_load_switching_torque
from worm_model.physics.modes import Flank, Mode
from worm_model.physics.parameters import load_rig
from worm_model.effects import Declaration, register, unregister
from worm_rig_driver.sim.effects import EFFECTS, EffectBase, EffectsConfig
from worm_rig_driver.sim.plant import RigPlant
from worm_rig_driver.sim.scalar_plant import ScalarPlant, float_hooks_missing
from worm_rig_driver.sim.scalar_sensors import BLOCK
from worm_rig_driver.sim.sensors import STATUS_DRIVE_LIMIT
from worm_rig_driver.sim.simulated_rig import SimulatedRig

RIG = load_rig()
#: agreement of the continuous quantities, relative to each field's range over the run
RTOL = 1e-12
#: samples in a run where a quantised channel may differ by one code (round-off at an edge)
MAX_EDGE_FLIPS = 2
#: every effect, the oil's time constant shortened so that its drift shows within the run
ALL_EFFECTS = EffectsConfig.defaults(*EFFECTS, oil_temperature={"time_constant": 0.5})
CONFIGS = {"none": None, "backlash": EffectsConfig.defaults("backlash"), "all_effects": ALL_EFFECTS}


def _commands(k: int, omega: float) -> tuple[float, float]:
    """(voltage [V], load [N m]) at sample k of the demanding run; omega [rad/s] is the worm's speed now.

    Speed steps and reversals, resistive / pseudo-resistive / assistive loads (flank
    changes, the gap crossed with backlash), load steps, a self-locked stop and
    standstill under an aiding load, voltage saturation, and breakaway from rest.
    """
    segment, within = divmod(k, 300)
    tau_sw = float(no_load_switching_torque(RIG, omega))
    direction = 1.0 if omega >= 0.0 else -1.0
    plan = [
        (12.0, 0.15),  # resistive, forward
        (12.0, -0.5 * tau_sw * direction),  # pseudo-resistive: aiding, below the switching torque
        (12.0, -0.2),  # assistive: coast flank
        (-12.0, -0.1 if within < 150 else -0.2),  # reversal through zero, resistive backwards, load step
        (-12.0, 0.2),  # assistive backwards
        (0.0, 0.2),  # no voltage: slows down and stops (the box self-locks)
        (0.0, -0.2),  # aiding load at rest: held (with backlash: crosses the gap at rest)
        (40.0, 0.25 if within < 150 else -0.1),  # beyond the supply: saturation, load steps
        (0.4, 0.0),  # barely any voltage: stays at rest
        (3.0, 0.05),  # breaks away and creeps forward
        (-30.0, 0.0),  # saturated reversal
        (6.0, 0.1 if within % 100 < 50 else -0.1),  # fast load steps across the flanks
    ]
    return plan[min(segment, len(plan) - 1)]


STEPS = 12 * 300


def _lockstep(effects, rig=RIG, seed=3):
    """Run the scalar and the vectorised path on the same commands; return both records."""
    fast = SimulatedRig(rig, n=1, seed=seed, effects=effects)
    slow = SimulatedRig(rig, n=1, seed=seed, effects=effects, scalar=False)
    assert fast.scalar and not slow.scalar
    records = {"fast": ([], []), "slow": ([], [])}
    for k in range(STEPS):
        volts, load = _commands(k, float(slow.plant.state.omega_worm[0]))
        for name, sim in (("fast", fast), ("slow", slow)):
            sim.command(voltage_drive=volts, load_torque=load)
            measured, truths = records[name]
            measured.append(sim.sample())
            truths.append(sim.truth())
    return records, fast, slow


def _stack(items, name) -> np.ndarray:
    return np.array([np.asarray(getattr(item, name), dtype=float)[0] for item in items])


@pytest.fixture(scope="module", params=list(CONFIGS))
def lockstep(request):
    return request.param, _lockstep(CONFIGS[request.param])


def test_the_run_is_demanding(lockstep) -> None:
    """The trajectory visits what the issue lists: all modes, both flanks, reversals, rest, breakaway, saturation."""
    key, (records, _, _) = lockstep
    measured, truths = records["slow"]
    omega, mode, flank = _stack(truths, "omega_worm"), _stack(truths, "mode"), _stack(truths, "flank")
    for wanted in Mode:
        assert np.any(mode == wanted), wanted.name
    assert np.any(flank == Flank.DRIVING) and np.any(flank == Flank.COAST)
    assert np.any(omega > 50) and np.any(omega < -50)  # both directions, through zero
    at_rest = np.flatnonzero(omega == 0.0)
    assert at_rest.size > 100 and np.any(omega[at_rest[-1] + 1:] != 0.0)  # standstill, then breakaway
    assert np.any(_stack(measured, "status").astype(int) & STATUS_DRIVE_LIMIT)
    if key != "none":
        contact = _stack(truths, "contact")
        assert np.count_nonzero(np.diff(contact)) >= 6 and np.any(contact == 0)  # the gap crossed, often


def test_scalar_and_vectorised_agree_on_every_measurement_field(lockstep) -> None:
    _, (records, _, _) = lockstep
    fast, slow = records["fast"][0], records["slow"][0]
    for f in fields(fast[0]):
        a, b = _stack(fast, f.name), _stack(slow, f.name)
        assert getattr(fast[-1], f.name).dtype == getattr(slow[-1], f.name).dtype, f.name
        assert getattr(fast[-1], f.name).shape == (1,), f.name
        if f.name in ("voltage_drive",):  # not quantised (the PWM effect's duty levels aside)
            np.testing.assert_allclose(a, b, rtol=RTOL, atol=0, err_msg=f.name)
            continue
        # quantised (ADC codes, encoder counts, status): identical except at an edge, one step apart
        flips = np.flatnonzero(a != b)
        assert flips.size <= MAX_EDGE_FLIPS, (f.name, flips)
        if flips.size:
            step = np.min(np.abs(np.diff(np.unique(b))))  # one code of this channel
            np.testing.assert_allclose(np.abs(a[flips] - b[flips]), step, rtol=1e-9, err_msg=f.name)


def test_scalar_and_vectorised_agree_on_the_truth(lockstep) -> None:
    _, (records, fast_sim, slow_sim) = lockstep
    fast, slow = records["fast"][1], records["slow"][1]
    for f in fields(fast[0]):
        if f.name == "effects":
            for name in slow[0].effects:
                a = np.array([t.effects[name][0] for t in fast])
                b = np.array([t.effects[name][0] for t in slow])
                np.testing.assert_allclose(a, b, rtol=RTOL, err_msg=name)
            continue
        a, b = _stack(fast, f.name), _stack(slow, f.name)
        if f.name in ("mode", "flank", "contact"):
            np.testing.assert_array_equal(a, b, err_msg=f.name)
            continue
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=f.name)
        ok = ~np.isnan(b)
        scale = np.max(np.abs(b[ok]), initial=0.0)
        # mu = F_f / N: relative to itself (N passes zero at flank changes, where mu is ill-conditioned)
        atol = 0.0 if f.name == "mu" else RTOL * scale
        np.testing.assert_allclose(a[ok], b[ok], rtol=RTOL, atol=atol, err_msg=f.name)
    # and the plant's state at the end
    for name in ("current_drive", "omega_worm", "theta_worm", "current_load", "omega_gear", "theta_gear"):
        np.testing.assert_allclose(getattr(fast_sim.plant.state, name), getattr(slow_sim.plant.state, name),
                                   rtol=RTOL, atol=RTOL, err_msg=name)
    np.testing.assert_array_equal(fast_sim.plant.state.contact, slow_sim.plant.state.contact)


# --- noise ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("current_std, tacho_std", [(0.02, 0.5), (0.0, 0.5), (0.3, 0.0)])
def test_same_seed_same_noise_over_several_blocks(current_std: float, tacho_std: float) -> None:
    """At rest with no commands every reading is quantised noise: the two paths draw it alike,
    over more than one block of the scalar path and with either noise switched off."""
    rig = replace(RIG, sensors=replace(RIG.sensors, current_noise_std=current_std, tacho_noise_std=tacho_std))
    sims = [SimulatedRig(rig, n=1, seed=21, scalar=scalar) for scalar in (True, False)]
    currents, tachos = [], []
    for _ in range(int(2.5 * BLOCK)):
        a, b = (sim.sample() for sim in sims)
        for f in fields(a):
            np.testing.assert_array_equal(getattr(a, f.name), getattr(b, f.name), err_msg=f.name)
        currents.append(a.current_drive[0])
        tachos.append(a.omega_worm[0])
    # the noise does reach the readings (the plant is at rest: the readings are quantised noise)
    assert np.any(np.array(currents) != 0.0) == (current_std > 0)
    assert np.any(np.array(tachos) != 0.0) == (tacho_std > 0)


# --- selection and the interface the rest of the code uses ----------------------------------------------

def test_one_rig_takes_the_scalar_path_unless_told_otherwise() -> None:
    assert SimulatedRig(RIG).scalar
    assert SimulatedRig(RIG, effects=ALL_EFFECTS).scalar  # every effect has float hooks
    assert not SimulatedRig(RIG, scalar=False).scalar
    assert not SimulatedRig(RIG, n=2).scalar
    with pytest.raises(ValueError, match="one rig"):
        SimulatedRig(RIG, n=2, scalar=True)
    assert float_hooks_missing(ALL_EFFECTS) == []


class _VectorisedOnly(EffectBase):
    """An effect written for arrays only (no float hooks)."""

    name = "vectorised_only"

    def worm_torque(self, s):
        return np.zeros(self.n)


@pytest.fixture
def vectorised_only():
    register(Declaration(_VectorisedOnly.name, "an effect written for arrays only"), simulator=_VectorisedOnly)
    yield
    unregister(_VectorisedOnly.name)


def test_an_effect_without_float_hooks_falls_back_to_the_vectorised_path(vectorised_only) -> None:
    config = EffectsConfig.defaults("backlash", "vectorised_only")
    assert float_hooks_missing(config) == ["vectorised_only"]
    sim = SimulatedRig(RIG, effects=config)
    assert not sim.scalar
    sim.sample()
    with pytest.raises(ValueError, match="vectorised_only"):
        SimulatedRig(RIG, effects=config, scalar=True)


def test_state_written_from_outside_reaches_the_scalar_plant_as_it_does_the_vectorised_one() -> None:
    """fil.harness writes state.current_load[:] in place; virtual_rig sets load_current_time_constant."""
    sims = [SimulatedRig(RIG, n=1, seed=4, scalar=scalar) for scalar in (True, False)]
    for sim in sims:
        sim.plant.load_current_time_constant = 5e-3
        sim.command(voltage_drive=9.0, load_torque=0.1)
    for k in range(300):
        for sim in sims:
            sim.plant.state.current_load[:] = 0.01 * k  # in place, as the harness does
            if k == 150:
                sim.plant.state.theta_worm = np.array([1.0])  # a field assigned
            sim.sample()
        a, b = (sim.plant.state for sim in sims)
        for name in ("current_load", "current_drive", "omega_worm", "theta_worm", "theta_gear"):
            np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=RTOL, atol=1e-15, err_msg=name)
    np.testing.assert_array_equal(sims[0].applied_load_torque, sims[1].applied_load_torque)
    kept = sims[0].plant.state.omega_worm
    sims[0].sample()
    assert kept[0] != sims[0].plant.state.omega_worm[0]  # an array kept across a step is a snapshot


def test_truth_and_applied_load_need_a_sample_first() -> None:
    sim = SimulatedRig(RIG)
    with pytest.raises(RuntimeError):
        sim.truth()
    with pytest.raises(RuntimeError):
        sim.applied_load_torque  # noqa: B018 - reading the property is what must raise
    sim.sample()
    assert sim.truth().omega_worm.shape == (1,)


# --- the pieces shared or twinned between the paths --------------------------------------------------

@pytest.mark.parametrize("model", sorted(FRICTION_MODELS))
def test_float_friction_laws_are_the_array_laws(model: str) -> None:
    friction = replace(RIG.friction, model=model)
    v = np.concatenate([[0.0], np.geomspace(1e-9, 50.0, 3000), [10 * 0.3048 / 60.0]])  # incl. the AGMA break
    array = FRICTION_MODELS[model](friction, v)
    floats = np.array([FLOAT_FRICTION_MODELS[model](friction, float(x)) for x in v])
    np.testing.assert_allclose(floats, array, rtol=4e-16, atol=0)
    assert np.isnan(FLOAT_FRICTION_MODELS[model](friction, float("nan")))


@pytest.mark.parametrize("key", ["none", "backlash", "all_effects"])
def test_scalar_plant_step_is_rig_plant_step(key: str) -> None:
    """ScalarPlant.step (one step, as RigPlant.step) and its outputs() over reversals, rest and gap crossings."""
    fast, slow = ScalarPlant(RIG, effects=CONFIGS[key]), RigPlant(RIG, 1, effects=CONFIGS[key])
    dt = 2.5e-4
    for k in range(4000):
        volts, load = [(15.0, 0.2), (15.0, -0.2), (-30.0, 0.1), (0.0, 0.25), (0.0, -0.25)][k // 800]
        fast.step(dt, volts, load)
        out = slow.step(dt, volts, load)
    mine = fast.outputs()
    for name in ("tau_in", "tau_load", "gear_load", "alpha_worm", "alpha_gear", "mu", "voltage_drive",
                 "worm_effect_torque", "gear_effect_torque", "impact_loss", "heat"):
        a, b = getattr(mine, name), getattr(out, name)
        assert (a is None) == (b is None), name
        if b is not None:
            np.testing.assert_allclose(a, b, rtol=RTOL, atol=1e-15, err_msg=name)
    np.testing.assert_array_equal(mine.contact, out.contact)
    np.testing.assert_array_equal(mine.drive_saturated, out.drive_saturated)
    for name in ("current_drive", "omega_worm", "theta_worm", "current_load", "omega_gear", "theta_gear", "contact"):
        np.testing.assert_allclose(getattr(fast.state, name), getattr(slow.state, name), rtol=RTOL, atol=1e-15,
                                   err_msg=name)


def test_the_written_out_rigid_step_is_the_general_one_bit_for_bit() -> None:
    """_step_rigid_plain (moving, no effects: the live simulator's common case) against _step_rigid."""
    rng = np.random.default_rng(12)
    plants = ScalarPlant(RIG), ScalarPlant(RIG)
    names = ("omega_worm", "theta_worm", "omega_gear", "theta_gear", "contact", "tau_in", "gear_load", "alpha_worm",
             "alpha_gear", "mu", "contact_out", "impact_loss")
    for _ in range(5000):
        omega = [rng.normal(0, 200), rng.normal(0, 2e-3), 0.0][rng.integers(3)]  # moving, creeping, at rest
        state = (float(rng.normal(0, 2.0)), float(omega), float(rng.normal(0, 50)))
        tau_load, dt = float(rng.normal(0, 0.2)), [1e-4, 5e-4, 1e-3][rng.integers(3)]
        for plant in plants:
            plant.current_drive, plant.omega_worm, plant.theta_worm = state
        plants[0]._step_rigid_plain(dt, tau_load)
        plants[1]._step_rigid(dt, tau_load)
        assert [getattr(plants[0], n) for n in names] == [getattr(plants[1], n) for n in names]


def test_scalar_plant_matches_the_rig_plant_attributes() -> None:
    plant = ScalarPlant(RIG, effects=EffectsConfig.defaults("inertia_error", "backlash"))
    assert plant.worm_inertia == pytest.approx(1.2 * RIG.total_worm_inertia)
    assert plant.backlash > 0 and int(plant.state.contact[0]) == 0  # assembled mid-gap, as RigPlant
    assert plant.state.omega_worm.shape == (1,) and plant.state.contact.dtype == np.int8
