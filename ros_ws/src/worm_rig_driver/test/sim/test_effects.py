"""Effect plug-ins (physics.md section 9): each changes what it should and nothing else.

Every expectation is derived from the effect's definition and worm_model's
Eqs 28-30 (steady states by root finding, friction from Eq. 23 through the
simulator's ground truth), or from comparing a run with the effect against the
same run without it; never copied from a run.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import yaml
from scipy.optimize import brentq

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient, sliding_velocity
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.parameters import default_rig_path, load_rig
from worm_model.effects import VOCABULARY
from worm_model.effects.parameters import UNITS, Parameter
from worm_model.errors import EffectsError
from worm_rig_driver.sim.effects import (EFFECTS, EffectsConfig, EffectStack, SenseContext, load_effects, main,
    template)
from worm_rig_driver.sim.plant import RigPlant
from worm_rig_driver.sim.simulated_rig import SimulatedRig

RIG = load_rig()
GB = RIG.gearbox
MOTOR = RIG.drive_motor
QUIET = replace(RIG, sensors=replace(RIG.sensors, current_noise_std=0.0, tacho_noise_std=0.0))
DT = 5e-4

#: the names a residual analysis looks for (the issue's vocabulary), and what each may change
EXPECTED_HOOKS = {
    "bearing_coulomb": {"worm_torque", "gear_torque"},
    "viscous_drag": {"worm_torque", "gear_torque"},
    "speed_dependent_mu": {"friction"},
    "load_dependent_mu": {"friction"},
    "oil_temperature": {"friction", "advance", "observe"},
    "worm_runout": {"worm_torque"},
    "tooth_pass": {"gear_torque"},
    "gear_runout": {"gear_torque"},
    "motor_cogging": {"worm_torque"},
    "backlash": {"backlash"},
    "sensor_gain": {"sense"},
    "sensor_offset": {"sense"},
    "inertia_error": {"inertia"},
    "pwm": {"drive_voltage", "sense"},
    "wear": {"friction", "worm_torque", "gear_torque", "backlash", "advance", "observe"},
    "lubricant_loss": {"friction", "advance"},
    "seal_drag": {"worm_torque", "gear_torque", "advance"},
}


# --- registry and configuration -------------------------------------------------------------------

def test_registry_has_the_issue_vocabulary_and_each_effect_changes_only_its_hooks() -> None:
    assert set(EFFECTS) == set(EXPECTED_HOOKS)
    for name, cls in EFFECTS.items():
        assert cls.name == name and VOCABULARY[name].summary and cls.__doc__
        assert cls.hooks() == EXPECTED_HOOKS[name], name
        for key, p in VOCABULARY[name].parameters.items():
            assert isinstance(p, Parameter) and p.doc, f"{name}.{key}"
            assert p.unit in {base for _, base in UNITS.values()}, f"{name}.{key}: {p.unit}"
    # a full configuration builds, with every parameter at its default
    stack = EffectStack.build(EffectsConfig.defaults(*EFFECTS), 3, RIG)
    assert stack.names == tuple(EFFECTS)


def test_template_round_trips_through_the_loader(tmp_path) -> None:
    path = tmp_path / "effects.yaml"
    path.write_text(template())
    config = load_effects(path)
    assert config.names == tuple(EFFECTS) and config.source == str(path)
    assert config.effects == EffectsConfig.defaults(*EFFECTS).effects
    assert main(["--check", str(path)]) == 0


def test_units_enabled_flag_and_plain_numbers(tmp_path) -> None:
    path = tmp_path / "effects.yaml"
    path.write_text(yaml.safe_dump({"format": "worm_rig_effects", "version": 1, "effects": {
        "backlash": {"angle": {"value": 30, "unit": "arcmin"}},
        "bearing_coulomb": {"worm_torque": {"value": 5, "unit": "mN m"}, "gear_torque": 0.02},
        "tooth_pass": {"enabled": False},
        "oil_temperature": None,
    }}))
    config = load_effects(path)
    assert config.names == ("backlash", "bearing_coulomb", "oil_temperature")
    assert config.effects["backlash"]["angle"] == pytest.approx(math.radians(0.5))
    assert config.effects["bearing_coulomb"] == {"worm_torque": pytest.approx(5e-3), "gear_torque": 0.02}
    assert config.effects["oil_temperature"]["time_constant"] == VOCABULARY["oil_temperature"].default("time_constant")


def test_an_effects_section_of_a_rig_parameter_file_is_read(tmp_path) -> None:
    document = yaml.safe_load(default_rig_path().read_text())
    document["effects"] = {"gear_runout": {"amplitude": 0.02}}
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(document))
    config = load_effects(path)
    assert config.names == ("gear_runout",) and config.effects["gear_runout"]["amplitude"] == 0.02


@pytest.mark.parametrize("effects, key, message", [
    ({"no_such_effect": {}}, "effects.no_such_effect", "unknown effect"),
    ({"backlash": {"width": 1.0}}, "effects.backlash.width", "unknown parameter"),
    ({"backlash": {"angle": -1.0}}, "effects.backlash.angle", "must be >= 0"),
    ({"backlash": {"angle": {"value": 1, "unit": "N m"}}}, "effects.backlash.angle", "is not a 'rad'"),
    ({"backlash": {"angle": {"value": 1, "unit": "furlong"}}}, "effects.backlash.angle", "unknown unit"),
    ({"backlash": {"angle": "wide"}}, "effects.backlash.angle", "not numeric"),
    ({"backlash": {"angle": float("nan")}}, "effects.backlash.angle", "not finite"),
    ({"motor_cogging": {"order": 2.5}}, "effects.motor_cogging.order", "integer"),
    ({"sensor_gain": {"drive_current": -1.5}}, "effects.sensor_gain.drive_current", "> -1"),
    ({"backlash": {"enabled": "yes"}}, "effects.backlash.enabled", "true or false"),
    ({"backlash": [1, 2]}, "effects.backlash", "expected a mapping"),
])
def test_bad_entries_name_the_file_and_the_key(tmp_path, effects, key, message) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"format": "worm_rig_effects", "version": 1, "effects": effects}))
    with pytest.raises(EffectsError, match=message) as info:
        load_effects(path)
    assert info.value.key == key and str(path) in str(info.value)
    assert main(["--check", str(path)]) == 2


@pytest.mark.parametrize("document, key", [
    ({"format": "something_else", "version": 1}, "format"),
    ({"format": "worm_rig_effects", "version": 7}, "version"),
    ({"format": "worm_rig_effects", "version": 1, "effect": {}}, "effect"),
    ("just a string", ""),
])
def test_bad_files_are_refused(tmp_path, document, key) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(document))
    with pytest.raises(EffectsError) as info:
        load_effects(path)
    assert info.value.key == key
    with pytest.raises(EffectsError, match="cannot read"):
        load_effects(tmp_path / "missing.yaml")


def test_each_rig_gets_its_own_effect_state() -> None:
    config = EffectsConfig.defaults("oil_temperature")
    a, b = RigPlant(RIG, 1, effects=config), RigPlant(RIG, 1, effects=config)
    for _ in range(200):
        a.step(DT, 12.0, 0.2)
    assert a.fx.observe()["oil_temperature"][0] > 25.0
    assert b.fx.observe()["oil_temperature"][0] == 25.0


# --- shaft torques and friction: the steady state they must produce ------------------------------

def _steady_speed(voltage, tau_load, worm_extra=lambda w: 0.0, gear_extra=lambda wg: 0.0,
                  mu_of=lambda mu, w, load: mu) -> float:
    """Root of the quasi-static torque balance (Eq. 28, a_w = 0 with Eq. 29) with an effect's terms.

    worm_extra(w): extra worm torque (+ drives); gear_extra(w_gear): extra gear torque
    (+ opposes); mu_of(mu, w, mesh load): the effect's friction.
    """

    def surplus(w: float) -> float:
        load = float(gear_side_load(RIG, tau_load, w)) + gear_extra(GB.ratio * w)
        mu = mu_of(float(friction_coefficient(RIG.friction, GB, w)), w, abs(float(gear_side_load(RIG, tau_load, w))))
        current = (voltage - MOTOR.back_emf_constant * w) / MOTOR.resistance
        return (MOTOR.torque_constant * current - MOTOR.viscous_drag * w - MOTOR.coulomb_drag * np.sign(w)
                + worm_extra(w) - float(reflected_input_torque(GB, mu, load, w)))

    top = 1.5 * abs(voltage) / MOTOR.back_emf_constant
    return brentq(surplus, 1e-3, top, xtol=1e-12) if voltage > 0 else brentq(surplus, -top, -1e-3, xtol=1e-12)


CASES = [(12.0, 0.2), (12.0, -0.15), (-8.0, 0.1), (20.0, 0.05)]  # resistive and assistive, both ways


def _settle(effects, steps: int = 1500) -> RigPlant:
    plant = RigPlant(RIG, len(CASES), effects=effects)
    volts, loads = np.array([c[0] for c in CASES]), np.array([c[1] for c in CASES])
    for _ in range(steps):
        plant.step(DT, volts, loads)
    return plant


def test_bearing_coulomb_is_a_sign_step_on_each_shaft() -> None:
    c_w, c_g = 4e-3, 20e-3
    plant = _settle(EffectsConfig.defaults(bearing_coulomb={"worm_torque": c_w, "gear_torque": c_g}))
    base = _settle(None)
    expected = [_steady_speed(v, t, lambda w: -c_w * np.sign(w), lambda wg: c_g * np.sign(wg)) for v, t in CASES]
    np.testing.assert_allclose(plant.state.omega_worm, expected, rtol=1e-7)
    assert np.all(np.abs(plant.state.omega_worm - base.state.omega_worm) > 0.1)  # it does change the rig


@pytest.mark.parametrize("exponent", [1.0, 0.5])
def test_viscous_drag_follows_its_speed_law(exponent: float) -> None:
    t_w, t_g, ref = 3e-3, 10e-3, 300.0
    config = EffectsConfig.defaults(viscous_drag={"worm_torque": t_w, "gear_torque": t_g, "reference_speed": ref,
                                                  "exponent": exponent})
    plant = _settle(config)

    def law(torque, worm_speed):
        return torque * np.sign(worm_speed) * (abs(worm_speed) / ref) ** exponent

    expected = [_steady_speed(v, t, lambda w: -law(t_w, w), lambda wg: law(t_g, wg / GB.ratio)) for v, t in CASES]
    np.testing.assert_allclose(plant.state.omega_worm, expected, rtol=1e-7)


def _truth_mu(effects, volts, loads, steps: int = 600):
    sim = SimulatedRig(QUIET, n=len(volts), effects=effects)
    sim.command(voltage_drive=volts, load_torque=loads)
    for _ in range(steps):
        sim.sample()
    return sim.truth()


def test_speed_dependent_mu_rises_at_low_sliding_speed() -> None:
    gain, v_st = 0.5, 0.3
    volts = np.array([2.0, 6.0, 12.0, 22.0, -4.0])
    loads = np.array([0.1, 0.1, 0.1, 0.1, -0.1])
    truth = _truth_mu(EffectsConfig.defaults(speed_dependent_mu={"low_speed_gain": gain, "stribeck_speed": v_st}),
                      volts, loads)
    w = truth.omega_worm
    v = sliding_velocity(GB, w)
    law = friction_coefficient(RIG.friction, GB, w)
    # Eq. 23 on the ground truth recovers the effect's mu: the dynamics used it
    np.testing.assert_allclose(truth.mu, law * (1 + gain * np.exp(-v / v_st)), rtol=1e-6)
    assert np.all(truth.mu / law > 1.0) and np.all(np.diff((truth.mu / law)[:4]) < 0)  # falls with speed
    steady = [_steady_speed(V, t, mu_of=lambda mu, ww, load: mu * (1 + gain * np.exp(
        -float(sliding_velocity(GB, ww)) / v_st))) for V, t in zip(volts, loads)]
    np.testing.assert_allclose(w, steady, rtol=1e-6)


def test_load_dependent_mu_changes_with_the_mesh_load() -> None:
    k, ref = -0.2, 0.25
    volts = np.full(4, 12.0)
    loads = np.array([0.05, 0.15, 0.25, -0.2])
    truth = _truth_mu(EffectsConfig.defaults(load_dependent_mu={"sensitivity": k, "reference_torque": ref}),
                      volts, loads)
    w = truth.omega_worm
    mesh = np.abs(gear_side_load(RIG, loads, w))
    np.testing.assert_allclose(truth.mu, friction_coefficient(RIG.friction, GB, w) * (1 + k * mesh / ref), rtol=1e-6)
    steady = [_steady_speed(V, t, mu_of=lambda mu, ww, load: mu * (1 + k * load / ref)) for V, t in zip(volts, loads)]
    np.testing.assert_allclose(w, steady, rtol=1e-6)


def test_oil_temperature_drifts_with_its_time_constant_and_scales_mu() -> None:
    """A constant operating point: T rises first-order to ambient + R_th x (mesh friction power)."""
    tau, r_th, k, ambient = 0.2, 20.0, -0.005, 25.0
    config = EffectsConfig.defaults(oil_temperature={"time_constant": tau, "thermal_resistance": r_th,
                                                     "mu_per_kelvin": k, "ambient": ambient, "initial": ambient})
    sim, base = SimulatedRig(QUIET, n=1, effects=config), SimulatedRig(QUIET, n=1)
    for s in (sim, base):
        s.command(voltage_drive=12.0, load_torque=0.2)
    temperature, current, current_base = [], [], []
    for _ in range(1500):  # 7.5 time constants
        sim.sample()
        base.sample()
        temperature.append(sim.plant.fx.observe()["oil_temperature"][0])
        current.append(sim.plant.state.current_drive[0])
        current_base.append(base.plant.state.current_drive[0])
    truth = sim.truth()
    assert truth.effects["oil_temperature"][0] == temperature[-1]
    # the heat is the mesh friction power F_f V_s (Eq. 22 on the truth)
    heat = [truth.friction_force[0] * sliding_velocity(GB, truth.omega_worm[0])]
    temperature, heat = np.array(temperature), np.array(heat)
    assert temperature[-1] == pytest.approx(ambient + r_th * heat[-1], rel=1e-3)  # steady state
    rise = (temperature[199] - ambient) / (temperature[-1] - ambient)  # one time constant (t = 0.2 s)
    assert rise == pytest.approx(1 - math.exp(-1), abs=0.03)
    np.testing.assert_allclose(truth.mu, friction_coefficient(RIG.friction, GB, truth.omega_worm)
                               * (1 + k * (temperature[-1] - ambient)), rtol=1e-6)
    # the signature: a slow drift of the current at a constant operating point, to the quasi-static
    # current with the warm oil's mu; none without the effect
    warm = _steady_speed(12.0, 0.2, mu_of=lambda mu, w, load: mu * (1 + k * (temperature[-1] - ambient)))
    assert current[-1] == pytest.approx((12.0 - MOTOR.back_emf_constant * warm) / MOTOR.resistance, rel=1e-4)
    assert current[300] - current[-1] > 0 and np.all(np.diff(current[300:]) < 1e-12)
    assert current[-1] < current_base[-1]
    assert abs(current_base[300] - current_base[-1]) < 1e-9


def test_inertia_error_changes_transients_not_steady_states() -> None:
    config = EffectsConfig.defaults(inertia_error={"worm": 0.3, "gear": 0.3})
    plant, base = RigPlant(RIG, 1, effects=config), RigPlant(RIG, 1)
    assert plant.worm_inertia == pytest.approx(1.3 * RIG.total_worm_inertia)
    assert plant.gear_inertia == pytest.approx(1.3 * RIG.total_gear_inertia)
    speeds = {id(plant): [], id(base): []}
    for _ in range(2000):
        for p in (plant, base):
            p.step(DT, 12.0, 0.1)
            speeds[id(p)].append(p.state.omega_worm[0])
    fast, slow = np.array(speeds[id(base)]), np.array(speeds[id(plant)])
    assert slow[-1] == pytest.approx(fast[-1], rel=1e-9)  # same steady state
    final = fast[-1]
    rise = [np.argmax(w > 0.632 * final) for w in (fast, slow)]
    # the mechanical time constant scales with the inertia (the armature's 0.8 ms blurs it a little)
    assert rise[1] / rise[0] == pytest.approx(1.3, rel=0.08)


# --- periodic torques: a line in the angle spectrum, nothing else -----------------------------------

def _angle_spectrum(effects, voltage: float, loads, revolutions: int, shaft: str = "worm", dt: float = DT):
    """Amplitude per order (cycles per revolution of `shaft`) of the true drive current, per rig.

    Runs at constant voltage, then resamples the current on a uniform grid of the shaft's
    angle over a whole number of revolutions (the angle-domain averaging of section 9).
    """
    loads = np.asarray(loads, float)
    plant = RigPlant(RIG, loads.size, effects=effects)
    for _ in range(int(0.3 / dt)):
        plant.step(dt, voltage, loads)
    theta, current = [], []
    start = plant.state.theta_worm if shaft == "worm" else plant.state.theta_gear
    start = start.copy()
    while True:
        plant.step(dt, voltage, loads)
        angle = plant.state.theta_worm if shaft == "worm" else plant.state.theta_gear
        theta.append(angle.copy())
        current.append(plant.state.current_drive.copy())
        if np.all(angle - start > 2 * np.pi * revolutions + 0.1):
            break
    theta, current = np.array(theta), np.array(current)
    per_rev = 256
    spectra, means = [], []
    for j in range(loads.size):
        grid = start[j] + 0.05 + np.arange(revolutions * per_rev) * 2 * np.pi / per_rev
        resampled = np.interp(grid, theta[:, j], current[:, j])
        spectrum = np.abs(np.fft.rfft(resampled)) * 2 / resampled.size
        spectra.append(spectrum[::revolutions][:per_rev // 2])  # index = order
        means.append(resampled.mean())
    return np.array(spectra), np.array(means)


@pytest.mark.parametrize("name, params, shaft, order", [
    ("worm_runout", {"amplitude": 1e-3, "load_fraction": 0.05}, "worm", 1),
    ("motor_cogging", {"amplitude": 2e-3, "order": 14}, "worm", 14),
    ("tooth_pass", {"amplitude": 5e-3, "load_fraction": 0.05}, "gear", int(GB.gear_teeth)),
    ("gear_runout", {"amplitude": 10e-3, "load_fraction": 0.05}, "gear", 1),
])
def test_periodic_effect_adds_a_line_at_its_order_and_leaves_the_mean(name, params, shaft, order) -> None:
    revolutions = 8 if shaft == "worm" else 1
    voltage = 6.0 if shaft == "worm" else 20.0  # a gear turn takes 30 worm turns: run faster
    loads = [0.02, 0.2]
    config = EffectsConfig.defaults(**{name: params})
    spectrum, mean = _angle_spectrum(config, voltage, loads, revolutions, shaft)
    base_spectrum, base_mean = _angle_spectrum(None, voltage, loads, revolutions, shaft)
    line = spectrum[:, order]
    assert np.all(line > 1e-3)  # [A]: a visible ripple in the current
    assert np.all(line > 50 * base_spectrum[:, order])  # that the rig without it does not have
    others = np.delete(np.abs(spectrum - base_spectrum)[:, 1:], order - 1, axis=1)
    assert np.all(others.max(axis=1) < 0.05 * line)  # no other order
    assert np.all(np.abs(mean - base_mean) < 0.05 * line)  # no change of the mean
    if params.get("load_fraction"):  # the load-proportional part: a bigger line at the bigger load
        assert line[1] > 1.3 * line[0]


def test_cogging_holds_a_worm_at_rest_without_chatter() -> None:
    """Cogging is a detent: a small voltage that would turn the free worm is held by it, exactly."""
    plant = RigPlant(RIG, 1, effects=EffectsConfig.defaults(motor_cogging={"amplitude": 10e-3, "order": 14}))
    plant.state.theta_worm[:] = plant.state.theta_gear[:] = 0.0
    history = []
    for _ in range(400):
        plant.step(DT, 0.3, 0.0)  # 0.3 V: 8.7 mN m of motor torque < drags + 10 mN m detent at theta 0+
        history.append(plant.state.omega_worm[0])
    assert np.all(np.array(history) >= 0)
    assert np.all(np.array(history)[-100:] == 0.0)


# --- sensor effects: readings change, the rig does not ------------------------------------------------

def _sensed_run(effects, seed=4, steps=400):
    sim = SimulatedRig(RIG, n=3, seed=seed, effects=effects)
    sim.command(voltage_drive=np.array([12.0, -6.0, 18.0]), load_torque=np.array([0.2, -0.1, 0.05]))
    readings, truths = [], []
    for _ in range(steps):
        readings.append(sim.sample())
        truths.append(sim.truth())
    return readings, truths


def _stack(items, field):
    return np.array([getattr(x, field) for x in items])


@pytest.mark.parametrize("name", ["sensor_gain", "sensor_offset"])
def test_sensor_effects_change_the_readings_and_not_the_rig(name: str) -> None:
    base_readings, base_truths = _sensed_run(None)
    readings, truths = _sensed_run(EffectsConfig.defaults(name))
    for field in ("omega_worm", "current_drive", "tau_load", "omega_gear", "theta_worm", "normal_force", "mu"):
        np.testing.assert_array_equal(_stack(truths, field), _stack(base_truths, field), err_msg=field)
    for field in ("count_drive", "count_load_1", "theta_gear"):  # encoders are digital: untouched
        np.testing.assert_array_equal(_stack(readings, field), _stack(base_readings, field), err_msg=field)
    p = EffectsConfig.defaults(name).effects[name]
    true_current = _stack(truths, "current_drive")[100:]
    measured, measured_base = _stack(readings, "current_drive")[100:], _stack(base_readings, "current_drive")[100:]
    load_1, load_1_base = _stack(readings, "current_load_1")[100:], _stack(base_readings, "current_load_1")[100:]
    true_load = _stack(truths, "tau_load")[100:] / (RIG.load_motor_count * RIG.load_motor.torque_constant)
    lsb = RIG.sensors.current_lsb
    # same seed, same noise: the difference is the effect, up to one ADC step per sample
    if name == "sensor_offset":
        assert (measured - measured_base).mean() == pytest.approx(p["drive_current"], abs=0.1 * lsb)
        assert (load_1 - load_1_base).mean() == pytest.approx(p["load_current"], abs=0.1 * lsb)
    else:
        np.testing.assert_allclose((measured - measured_base).mean(0), p["drive_current"] * true_current.mean(0),
                                   atol=0.1 * lsb)
        np.testing.assert_allclose((load_1 - load_1_base).mean(0), p["load_current"] * true_load.mean(0),
                                   atol=0.1 * lsb)
    change = p["drive_current"] * (np.abs(true_current).max() if name == "sensor_gain" else 1.0)
    assert np.all(np.abs(measured - measured_base) <= abs(change) + lsb)


def test_pwm_quantises_the_duty_and_adds_the_sampled_ripple() -> None:
    import worm_rig_driver.protocol.table as protocol_table

    levels = VOCABULARY["pwm"].default("duty_levels")
    assert levels == protocol_table.PWM_TOP + 1  # the firmware's timer: 800 steps at 20 kHz
    # the vocabulary's PWM is the firmware's (worm_model does not import the protocol table)
    assert VOCABULARY["pwm"].default("frequency") == protocol_table.F_CPU_HZ / (protocol_table.PWM_TOP + 1)
    config = EffectsConfig.defaults("pwm")
    sim, base = (SimulatedRig(QUIET, n=2, effects=e) for e in (config, None))
    volts = np.array([10.0, -7.3])
    for s in (sim, base):
        s.command(voltage_drive=volts, load_torque=np.array([0.1, 0.1]))
    readings = [sim.sample() for _ in range(600)]
    base_readings = [base.sample() for _ in range(600)]
    applied = readings[-1].voltage_drive
    np.testing.assert_allclose(applied, np.round(volts / RIG.supply_voltage * levels) / levels * RIG.supply_voltage)
    assert np.all(applied != volts) and np.all(base_readings[-1].voltage_drive == volts)
    # the triangle ripple, peak to peak V_s d (1 - d) / (L f), through the sensor's filter
    f = VOCABULARY["pwm"].default("frequency")
    cutoff = VOCABULARY["pwm"].default("filter_cutoff")
    duty = np.abs(applied) / RIG.supply_voltage
    ripple_pp = RIG.supply_voltage * duty * (1 - duty) / (MOTOR.inductance * f) / np.hypot(1, f / cutoff)
    stack = EffectStack.build(config, 2, RIG)
    seen = []
    for t in np.linspace(0.0, 1.0 / f, 400, endpoint=False):
        signals = {"current_drive": np.zeros(2)}
        stack.sense(signals, SenseContext({"current_drive": t}, applied, RIG.supply_voltage))
        seen.append(signals["current_drive"])
    seen = np.array(seen)
    np.testing.assert_allclose(seen.max(0) - seen.min(0), ripple_pp, rtol=0.02)
    np.testing.assert_allclose(seen.mean(0), 0.0, atol=0.01 * ripple_pp.max())  # zero mean: the average model
    # through the ADC: the noise-free reading stays within the ripple and half a step of the true current
    current = _stack(readings, "current_drive")[300:]
    true = sim.truth().current_drive
    assert np.all(np.abs(current - true) <= 0.5 * ripple_pp + 0.5 * RIG.sensors.current_lsb + 1e-12)
