"""Residual analysis core: CSV schema, split, model, held-out discipline, extended model; parameter
corrections that stay live under every friction model and physical; effects outside the vocabulary not named.

Data here are synthetic, made by the declared model itself plus Gaussian current noise,
so these tests need no simulator (the simulator-based tests are tests/test_residuals_sim.py).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from worm_model.physics.dynamics import reflected_input_torque, worm_acceleration
from worm_model.physics.friction import FRICTION_MODELS, friction_coefficient
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.parameters import default_rig_path, load_rig
from worm_model.errors import ParameterError, RigDataError
import worm_model.residuals.analysis as an
import worm_model.residuals.cli as cli
from worm_model.residuals.data import load_data
from worm_model.residuals.description.descriptors import time_in_run
from worm_model.residuals.effects import EFFECTS, Backlash, channels_of, gap_crossing
from worm_model.residuals.extended import ExtendedModel, write_parameter_file
from worm_model.residuals.free import (READ_BY_MODEL, LOWER_BOUNDS, MU_PARAMETERS, STANDARD_REFIT, TOLERANCES,
                                       get_value, mu_parameter, read_free, resolve_parameters, set_value,
                                       typical_coulomb_drag)
from worm_model.residuals.report import correction_line, corrections
from worm_model.residuals.model import Signals, evaluate, prepare_signals, ripple_response
from worm_model.rig_data.schema import MeasuredData, read_rig_csv, split_runs, write_rig_csv

RIG = load_rig()


def synthetic(effects=(), seconds: float = 40.0, noise: float = 0.02, seed: int = 0,
              temperatures: tuple[float, ...] | None = None, rig=RIG) -> MeasuredData:
    """Samples of the model of ``rig`` (+ effects) along a smooth speed/load profile, 1 kHz, 4 runs.

    temperatures: oil temperature [degC] of each run, then recorded in the ``temperature`` column.
    """
    rng = np.random.default_rng(seed)
    runs = []
    per_run = seconds / 4
    for r, (w0, sign) in enumerate(((60.0, 1), (250.0, -1), (150.0, 1), (320.0, -1))):
        t = np.arange(0.0, per_run, 1e-3)
        omega = sign * (w0 + 0.4 * w0 * np.sin(2 * np.pi * 0.7 * t + r))
        alpha = sign * 0.4 * w0 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t + r)
        theta = sign * (w0 * t - 0.4 * w0 / (2 * np.pi * 0.7) * (np.cos(2 * np.pi * 0.7 * t + r) - np.cos(r)))
        tau = 0.05 + 0.15 * np.sin(2 * np.pi * 0.23 * t + 2 * r)
        runs.append((t + r * (per_run + 1.0), omega, alpha, theta, tau))
    t, omega, alpha, theta, tau = (np.concatenate(x) for x in zip(*runs))
    run = split_runs(t)
    temperature = None if temperatures is None else np.asarray(temperatures, dtype=float)[run]
    sig = Signals(t=t, omega=omega, alpha=alpha, theta_worm=theta, theta_gear=rig.gearbox.ratio * theta,
                  tau_load=tau, run=run, temperature=temperature)
    current = evaluate(rig, sig, channels_of(list(effects), rig, sig)).current
    current = current + rng.normal(0.0, noise, len(t))
    return MeasuredData(t=t, current_drive=current, omega_worm=omega, theta_worm=theta, tau_load=tau,
                        temperature=temperature)


def problem_of(data: MeasuredData, free=("friction.scale",), **settings) -> an.Problem:
    s = an.Settings(**settings)
    sig = prepare_signals(RIG, data, s.alpha_time_constant, s.reference_temperature)
    return an.Problem(RIG, list(free), sig, data.current_drive, an.make_split(sig, s, rig=RIG), s)


# --------------------------------------------------------------------------- input (schema: test_rig_data.py)
def test_csv_round_trip_keeps_values_optional_columns_and_runs(tmp_path: Path) -> None:
    data = synthetic(seconds=4.0)
    data.temperature = np.linspace(25, 30, len(data))
    path = tmp_path / "run.csv"
    write_rig_csv(path, data)
    back = load_data(path)
    for name in ("t", "current_drive", "omega_worm", "theta_worm", "tau_load", "temperature"):
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name))
    assert back.voltage_drive is None and back.theta_gear is None
    assert list(np.unique(back.run)) == [0, 1, 2, 3]  # the 1 s gaps between runs


HEADER = "t,current_drive,omega_worm,theta_worm,tau_load\n"


def test_one_sample_is_no_data_set_for_the_analysis(tmp_path: Path) -> None:
    path = tmp_path / "one.csv"
    path.write_text(HEADER + "0,1,1,0,0.1\n")
    assert len(read_rig_csv(path)) == 1  # valid rig data (bag import takes it) ...
    with pytest.raises(RigDataError, match="1 sample.s.: a log needs 2 at least") as err:
        load_data(path)  # ... but not enough to analyse
    assert err.value.source == str(path)


def test_cli_bad_csv_exits_2_with_the_place(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(HEADER + "0,1,1,0,0.1\n0.001,1,x1,0,0.1\n")
    assert cli.main([str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert "line 3, column 'omega_worm': 'x1' is not a number" in capsys.readouterr().err


# --------------------------------------------------------------------------- the declared model
def test_quasi_static_current_is_eq_28_with_the_motor_drags() -> None:
    w = np.array([50.0, 200.0, -120.0, -300.0, 80.0])
    tau = np.array([0.2, -0.05, 0.1, -0.2, 0.0])
    sig = Signals(t=np.arange(5) * 1e-3, omega=w, alpha=np.zeros(5), theta_worm=np.zeros(5),
                  theta_gear=np.zeros(5), tau_load=tau, run=np.zeros(5, int))
    m = RIG.drive_motor
    mu = friction_coefficient(RIG.friction, RIG.gearbox, w)
    expected = (reflected_input_torque(RIG.gearbox, mu, gear_side_load(RIG, tau, w), w)
                + m.viscous_drag * w + m.coulomb_drag * np.sign(w)) / m.torque_constant
    np.testing.assert_allclose(evaluate(RIG, sig).current, expected, rtol=1e-12)


def test_inertia_term_inverts_the_coupled_dynamics() -> None:
    """The current the model predicts for (omega, alpha) makes Eq. 28 give back that alpha."""
    w = np.array([50.0, 200.0, -120.0, 300.0])
    alpha = np.array([800.0, -1500.0, 400.0, 2000.0])
    tau = np.array([0.2, -0.05, 0.1, -0.2])
    sig = Signals(t=np.arange(4) * 1e-3, omega=w, alpha=alpha, theta_worm=np.zeros(4), theta_gear=np.zeros(4),
                  tau_load=tau, run=np.zeros(4, int))
    m = RIG.drive_motor
    i = evaluate(RIG, sig).current
    tau_in = m.torque_constant * i - m.viscous_drag * w - m.coulomb_drag * np.sign(w)
    mu = friction_coefficient(RIG.friction, RIG.gearbox, w)
    back, _ = worm_acceleration(RIG.gearbox, mu, tau_in, gear_side_load(RIG, tau, w), w,
                                RIG.total_worm_inertia, RIG.total_gear_inertia)
    np.testing.assert_allclose(back, alpha, rtol=1e-9)


def test_ripple_response_is_one_at_dc_and_vanishes_far_above_the_corner() -> None:
    d = ripple_response(RIG, np.array([0.0, 2 * np.pi * 5, 2 * np.pi * 400]), 1e-3)
    assert d[0] == pytest.approx(1.0)
    assert abs(d[1]) > 0.95 and abs(d[2]) < 0.05
    # signed frequency: the response for reverse rotation is the complex conjugate
    assert ripple_response(RIG, np.array([-2 * np.pi * 30]), 1e-3)[0] == pytest.approx(
        np.conj(ripple_response(RIG, np.array([2 * np.pi * 30]), 1e-3)[0]))


def test_effect_shapes_are_the_declared_rigs_whatever_rig_asks_first() -> None:
    """A screening round at a twisted intermediate fit (rotor inertia 0) once filled the shape cache with a
    cogging response that fitted half the ripple; the shapes are now the declared rig's, in any order."""
    data = synthetic(seconds=8.0)
    twisted = dataclasses.replace(RIG, drive_motor=dataclasses.replace(RIG.drive_motor, rotor_inertia=1e-9))
    grid = {"order": 6.0}
    cogging = EFFECTS["motor_cogging"]
    first_twisted, first_declared = problem_of(data), problem_of(data)
    a = first_twisted.shapes(cogging, twisted, grid)["worm_torque"]
    b = first_declared.shapes(cogging, RIG, grid)["worm_torque"]
    np.testing.assert_array_equal(a, b)
    # the twisted rig's own shapes do differ: the test would see a cache filled from it
    assert np.max(np.abs(cogging.shapes(twisted, first_declared.signals, grid)["worm_torque"] - b)) > 0.05


# --------------------------------------------------------------------------- split and held-out discipline
def test_split_is_disjoint_guarded_and_spread() -> None:
    p = problem_of(synthetic(seconds=24.0), holdout_fraction=1 / 3, block_seconds=1.0, guard_seconds=0.05)
    sp, sig = p.split, p.signals
    assert not np.any(sp.train & sp.held_out)
    assert 0.25 < sp.held_out.sum() / (sp.train.sum() + sp.held_out.sum()) < 0.4
    # every sample within the guard of a block edge is in neither set
    for r in np.unique(sig.run):
        t = sig.t[sig.run == r] - sig.t[sig.run == r][0]
        near_edge = np.minimum(t % 1.0, 1.0 - t % 1.0) < 0.05 - 1e-9
        used = (sp.train | sp.held_out)[sig.run == r]
        assert not np.any(used & near_edge)
    # held-out blocks occur all along the record, not only at its end
    held_blocks = np.unique(sp.block[sp.held_out])
    assert held_blocks.min() < 5 and held_blocks.max() > sp.block.max() - 5


def test_held_out_data_never_changes_a_fit() -> None:
    """Replace every held-out current by garbage: fitted parameters and training residuals stay bit-equal."""
    effect = EFFECTS["viscous_drag"]
    data = synthetic([(effect, {"worm_torque": 4e-3, "gear_torque": 0.0}, {"exponent": 1.0})])
    clean = problem_of(data)
    specs = [(effect, {"exponent": 1.0})]
    a_declared, a_full = an.fit(clean, []), an.fit(clean, specs)

    spoiled = dataclasses.replace(data, current_drive=data.current_drive.copy())
    rng = np.random.default_rng(5)
    spoiled.current_drive[clean.split.held_out] += rng.normal(0.0, 5.0, int(clean.split.held_out.sum()))
    dirty = problem_of(spoiled)
    assert np.array_equal(dirty.split.held_out, clean.split.held_out)
    b_declared, b_full = an.fit(dirty, []), an.fit(dirty, specs)
    for a, b in ((a_declared, b_declared), (a_full, b_full)):
        assert a.free_values == b.free_values
        assert [e.values for e in a.effects] == [e.values for e in b.effects]
        assert np.array_equal(a.residual[clean.split.train], b.residual[clean.split.train])
        assert b.rms_held_out > 10 * a.rms_held_out  # the garbage is seen only by the held-out score


def test_noise_only_finds_nothing_and_a_synthetic_effect_is_found() -> None:
    none = an.analyse(problem_of(synthetic(seed=1)))
    assert none.found == []
    assert none.final.rms_held_out == pytest.approx(0.02, rel=0.05)

    effect = EFFECTS["sensor_offset"]
    found = an.analyse(problem_of(synthetic([(effect, {"drive_current": 0.06, "load_current": 0.0}, {})], seed=2)))
    assert found.found == ["sensor_offset"]
    offset = found.final.effects[0]
    assert offset.values["drive_current"] == pytest.approx(0.06, abs=3 * offset.ci["drive_current"] + 1e-3)
    assert found.final.rms_held_out < 0.5 * found.declared.rms_held_out
    # no gear encoder in these data: backlash is not screened, and the report says why
    backlash = next(c for c in none.rounds[0].candidates if c.name == "backlash")
    assert "theta_gear" in backlash.note and none.final.te is None


# --------------------------------------------------------------------------- backlash: the transmission error
def test_gap_crossing_rests_on_a_flank_crosses_in_the_free_flight_time_and_ignores_a_brief_pull() -> None:
    t = np.arange(100) * 1e-3
    run = np.zeros(len(t), dtype=int)
    gap, a = 4e-3, 100.0  # [rad], [rad/s^2]
    drive = np.where(np.arange(100) < 20, a, -a)  # samples of a force that turns at t = 19.5 ms
    p = gap_crossing(t, drive, run, gap)
    assert np.all(p[:20] == gap / 2)  # resting on the flank the force presses
    # drive linear between samples: from 0 at 19.5 ms to -a at 20 ms, then -a: p falls from gap/2
    ramp = 0.5e-3
    p20, v20 = gap / 2 - a * ramp**2 / 6, -a * ramp / 2
    s = t - t[20]
    expected = p20 + v20 * s - 0.5 * a * s**2
    flying = (s >= 0) & (expected > -gap / 2)
    np.testing.assert_allclose(p[flying], expected[flying], rtol=1e-9, atol=1e-12)
    assert np.all(p[~flying & (s > 0)] == -gap / 2)  # then resting on the other flank
    assert 7 <= flying.sum() <= 10  # the free-flight time sqrt(2 gap / a) = 8.9 ms
    # a pull of 2 samples (noise on the load near the switching torque) moves p a little and it comes back
    blip = np.where((np.arange(100) >= 21) & (np.arange(100) <= 22), -a, a)
    q = gap_crossing(t, blip, run, gap)
    assert q.min() > 0.0 and q.min() < gap / 2 and q[-1] == gap / 2


def test_backlash_is_identified_from_the_transmission_error_and_held_out_te_never_fits() -> None:
    """theta_gear = ratio theta_worm - (mesh position in a 15 arcmin gap) + an encoder offset per run,
    quantised to the gear encoder's 2000 counts/turn: the tool names backlash, gets the gap, halves the
    transmission error's held-out RMS; garbage in the held-out theta_gear changes nothing fitted."""
    data = synthetic(seed=3)
    sig = prepare_signals(RIG, data)
    gap = math.radians(15.0 / 60.0)
    p = gap_crossing(sig.t, Backlash().mesh_drive(RIG, evaluate(RIG, sig)), sig.run, gap)
    lsb = 2 * math.pi / 2000
    theta_gear = np.floor((RIG.gearbox.ratio * data.theta_worm - p + 0.7e-3 * sig.run) / lsb) * lsb
    data = dataclasses.replace(data, theta_gear=theta_gear)
    clean = problem_of(data)
    result = an.analyse(clean)
    assert result.found == ["backlash"]
    fitted = result.final.effects[0]
    assert fitted.values["angle"] == pytest.approx(gap, abs=max(3 * fitted.ci["angle"], 0.02 * gap))
    assert result.final.te.rms_held_out < 0.5 * result.declared.te.rms_held_out
    assert result.final.rms_held_out == pytest.approx(result.declared.rms_held_out, rel=1e-6)  # current untouched

    spoiled = dataclasses.replace(data, theta_gear=theta_gear.copy())
    held = clean.split.held_out
    spoiled.theta_gear[held] += np.random.default_rng(4).normal(0.0, 0.1, int(held.sum()))
    dirty = problem_of(spoiled)
    specs = [(EFFECTS["backlash"], fitted.grid)]
    a, b = an.fit(clean, specs), an.fit(dirty, specs)
    assert a.effects[0].values == b.effects[0].values and a.te.offsets == b.te.offsets
    assert b.te.rms_held_out > 10 * a.te.rms_held_out


# --------------------------------------------------------------------------- oil temperature, measured
def test_measured_oil_temperature_scales_mu_about_the_reference_temperature() -> None:
    effect = EFFECTS["oil_temperature"]
    grid = {"time_constant": 0.0, "reference_temperature": 25.0}
    data = synthetic([(effect, {"mu_per_kelvin": -0.02}, grid)], temperatures=(-20.0, 25.0, 70.0, 0.0), seed=5)
    result = an.analyse(problem_of(data, free=()))
    assert result.found == ["oil_temperature"]
    fitted = result.final.effects[0]
    assert fitted.grid["time_constant"] == 0.0
    assert fitted.values["mu_per_kelvin"] == pytest.approx(-0.02, abs=3 * fitted.ci["mu_per_kelvin"] + 1e-4)
    # the simulator's entry: mu holds at the reference, and a valid (positive) thermal time constant
    entry = effect.simulator_entry(fitted.values, fitted.grid)
    assert entry["ambient"] == 25.0 and entry["time_constant"] > 0.0
    # told a wrong reference, the model is off by a constant relative mu (absorbed by a free mu scale)
    shifted = an.analyse(problem_of(data, free=("friction.scale",), reference_temperature=35.0))
    assert shifted.found == ["oil_temperature"]
    assert shifted.final.free_values["friction.scale"] == pytest.approx(1.0 - 0.02 * 10.0, rel=0.05)


# --------------------------------------------------------------------------- free list and the extended model
def test_free_list_is_read_and_checked(tmp_path: Path) -> None:
    assert read_free(None) == []  # the bundled file declares none
    doc = yaml.safe_load(default_rig_path().read_text())
    doc["free"] = ["friction.scale", "drive_motor.coulomb_drag"]
    good = tmp_path / "rig.yaml"
    good.write_text(yaml.safe_dump(doc))
    assert read_free(good) == ["friction.scale", "drive_motor.coulomb_drag"]
    assert load_rig(good) == dataclasses.replace(load_rig(), source=str(good.resolve()))
    doc["free"] = ["friction.scale", "sensors.current_lsb"]
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(ParameterError, match=r"free\[1\]: 'sensors.current_lsb' cannot be free"):
        read_free(bad)


def test_cli_refuses_a_friction_parameter_the_model_does_not_read(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A rig file under the constant model asking to fit friction.scale (dead there): one line naming the live one,
    exit 2, no output folder."""
    data = tmp_path / "run.csv"
    write_rig_csv(data, synthetic(seconds=4.0))
    doc = yaml.safe_load(default_rig_path().read_text())
    doc["friction"]["model"] = "constant"
    doc["free"] = ["friction.scale"]
    params = tmp_path / "constant.yaml"
    params.write_text(yaml.safe_dump(doc))
    assert cli.main([str(data), "--out", str(tmp_path / "out"), "--rig", str(params), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "friction.scale" in err[0] and "its mu is friction.mu_constant" in err[0], err
    assert not (tmp_path / "out").exists()


def test_extended_parameter_file_round_trips_and_loads_as_a_rig(tmp_path: Path) -> None:
    rig = dataclasses.replace(RIG, friction=dataclasses.replace(RIG.friction, scale=1.2),
                              drive_motor=dataclasses.replace(RIG.drive_motor, coulomb_drag=5e-3))
    effects = [
        (EFFECTS["bearing_coulomb"], {"worm_torque": 3e-3, "gear_torque": 0.015}, {}),
        (EFFECTS["motor_cogging"], {"amplitude_sin": 2e-3, "amplitude_cos": -1e-3}, {"order": 14.0}),
        (EFFECTS["gear_runout"], {"amplitude_sin": 0.01, "amplitude_cos": 0.0, "load_fraction_sin": 0.03,
                                  "load_fraction_cos": 0.0}, {"order": 1.0}),
        (EFFECTS["speed_dependent_mu"], {"low_speed_gain": 0.5}, {"stribeck_speed": 0.3}),
    ]
    model = ExtendedModel(rig, effects)
    path = tmp_path / "extended.yaml"
    free = ["friction.scale", "drive_motor.coulomb_drag"]
    write_parameter_file(path, default_rig_path(), model, free, {"friction.scale": 0.01}, "identified in a test")
    doc = yaml.safe_load(path.read_text())
    assert doc["free"] == free and set(doc["effects"]) == {e.name for e, _v, _g in effects}
    assert doc["effects"]["motor_cogging"]["order"] == 14.0
    assert doc["drive_motor"]["coulomb_drag"]["source"].startswith("identified in a test")
    loaded = load_rig(path)  # load_rig skips free/effects
    assert loaded.friction.scale == pytest.approx(1.2) and loaded.drive_motor.coulomb_drag == pytest.approx(5e-3)
    # the bundled file's load_motor is a YAML alias of drive_motor: the edit must not leak into it
    assert loaded.load_motor.coulomb_drag == RIG.load_motor.coulomb_drag
    back = ExtendedModel.load(path)
    sig = prepare_signals(rig, synthetic(seconds=4.0))
    np.testing.assert_allclose(back.current(sig), model.current(sig), rtol=1e-5, atol=1e-7)


def test_estimate_load_torque_inverts_the_model_current() -> None:
    effects = [(EFFECTS["load_dependent_mu"], {"sensitivity": -0.3}, {}),
               (EFFECTS["worm_runout"], {"amplitude_sin": 2e-3, "amplitude_cos": 0.0, "load_fraction_sin": 0.02,
                                         "load_fraction_cos": 0.0}, {"order": 1.0})]
    model = ExtendedModel(RIG, effects)
    sig = prepare_signals(RIG, synthetic(seconds=4.0))
    moving = np.abs(sig.omega) > 5
    estimate = model.estimate_load_torque(sig, model.current(sig))
    np.testing.assert_allclose(estimate[moving], sig.tau_load[moving], atol=1e-6)
    # a current no load in range can explain: NaN, not a clipped value
    assert math.isnan(model.estimate_load_torque(sig, np.full(len(sig), 50.0))[0])


# --------------------------------------------------------------------------- corrections; outside the vocabulary
FRICTION_FIELDS = ("friction.scale", "friction.mu_constant")


def problem_at(data, rig, bounded: bool = True, **settings) -> an.Problem:
    """The analysis of ``data`` with ``rig`` as the rig file (``bounded`` False: no physical bound on any fit)."""
    settings = an.Settings(**settings)
    signals = prepare_signals(rig, data, settings.alpha_time_constant)
    problem = an.Problem(rig, [], signals, data.current_drive, an.make_split(signals, settings, rig=rig), settings)
    if not bounded:
        problem.lower_bounds = lambda size: np.full(size, -np.inf)
    return problem


def with_model(rig, model: str):
    return dataclasses.replace(rig, friction=dataclasses.replace(rig.friction, model=model))


@pytest.mark.parametrize("model", sorted(FRICTION_MODELS))
def test_every_friction_model_has_a_live_mu_parameter(model: str) -> None:
    """Its mu parameter scales mu; the friction section's other numbers leave that model's mu alone."""
    assert set(MU_PARAMETERS) == set(FRICTION_MODELS)  # a new friction model needs its mu parameter
    rig = with_model(RIG, model)
    omega = np.array([20.0, 150.0, -300.0])
    mu = friction_coefficient(rig.friction, rig.gearbox, omega)
    live = mu_parameter(model)
    bumped = set_value(rig, live, 1.2 * get_value(rig, live))
    np.testing.assert_allclose(friction_coefficient(bumped.friction, bumped.gearbox, omega), 1.2 * mu, rtol=1e-12)
    dead_fields = set(FRICTION_FIELDS) - READ_BY_MODEL[model]
    for dead in dead_fields:
        other = set_value(rig, dead, 3.0 * get_value(rig, dead) + 0.1)
        np.testing.assert_array_equal(friction_coefficient(other.friction, other.gearbox, omega), mu)
    for read in READ_BY_MODEL[model]:  # the model reads it: a refit of it moves mu
        other = set_value(rig, read, 3.0 * get_value(rig, read) + 0.1)
        assert not np.array_equal(friction_coefficient(other.friction, other.gearbox, omega), mu), read
    assert resolve_parameters(rig, STANDARD_REFIT)[0] == live
    for dead in dead_fields:
        with pytest.raises(ParameterError, match=f"not read by the friction model '{model}'"):
            resolve_parameters(rig, [dead], "rig.yaml")


def test_the_constant_models_mu_declared_25_percent_high_is_corrected() -> None:
    """The dead correction printed 'friction.scale: declared 1 -> 1 +- 0'; now mu_constant moves to the truth."""
    rig = with_model(RIG, "constant")
    data = synthetic(seed=3, rig=rig)
    declared = set_value(rig, "friction.mu_constant", 1.25 * rig.friction.mu_constant)
    result = an.analyse(problem_at(data, declared))
    assert result.found == []
    value = result.final.free_values["friction.mu_constant"]
    assert value == pytest.approx(rig.friction.mu_constant, rel=0.03)
    assert result.final.free_ci["friction.mu_constant"] > 0.0
    assert "friction.scale" not in result.final.free_values


def test_a_drag_declared_0_is_held_at_0_and_its_band_is_absolute() -> None:
    """Data whose Coulomb drag 'drives' (a negative drag: what a trade-off with the rest looks like) and a rig file
    declaring 0: the unconstrained fit would say -1 mN m; the correction stays at 0, reported as held at its
    bound, and the band around the declared 0 is absolute (no 'xnan')."""
    plant = set_value(RIG, "drive_motor.coulomb_drag", -1e-3)
    declared = set_value(RIG, "drive_motor.coulomb_drag", 0.0)
    data = synthetic(seed=4, rig=plant)
    problem = problem_at(data, declared)
    result = an.analyse(problem)
    assert result.final.free_values["drive_motor.coulomb_drag"] == LOWER_BOUNDS["drive_motor.coulomb_drag"] == 0.0
    unbounded = an.fit(problem_at(data, declared, bounded=False), [])
    assert unbounded.free_values["drive_motor.coulomb_drag"] == pytest.approx(-1e-3, abs=1e-4)
    row = next(r for r in corrections(problem, result) if r["name"] == "drive_motor.coulomb_drag")
    line = correction_line(row)
    high = TOLERANCES["drive_motor.coulomb_drag"].high * typical_coulomb_drag(RIG.drive_motor)
    assert row["ratio"] is None and row["band"] == [0.0, pytest.approx(high)]
    assert "nan" not in line and "(absolute: declared 0)" in line and "held at its physical bound 0" in line, line


def test_a_drag_declared_0_within_its_absolute_band_is_a_correction_beyond_it_an_effect() -> None:
    """True drag 4 mN m, declared 0: a correction (the band reaches 2.5 x 5 % of the rated torque, 17 mN m);
    a bearing drag of 30 mN m more: beyond it, named bearing_coulomb."""
    declared = set_value(RIG, "drive_motor.coulomb_drag", 0.0)
    quiet = an.analyse(problem_at(synthetic(seed=5), declared))
    assert quiet.found == []
    assert quiet.final.free_values["drive_motor.coulomb_drag"] == pytest.approx(4e-3, abs=5e-4)
    bearing = (EFFECTS["bearing_coulomb"], {"worm_torque": 0.03, "gear_torque": 0.0}, {})
    loud = an.analyse(problem_at(synthetic([bearing], seed=6), declared))
    assert loud.found == ["bearing_coulomb"]


def test_a_drift_is_not_named_as_a_sensor_offset() -> None:
    """The current sensor's zero drifting in time (out of the vocabulary): a constant offset takes its mean and
    earned its keep alone; beside a generic description of the residual (binned over time) it does not, so
    nothing is named and the residual is unexplained, going with time."""
    data = synthetic(seed=7)
    run_time = time_in_run(prepare_signals(RIG, data))
    data.current_drive = data.current_drive + 0.006 * run_time  # 0 -> 0.06 A over each 10 s run
    result = an.analyse(problem_at(data, RIG, block_seconds=0.5))  # enough held-out blocks to accept the offset
    assert result.found == [] and "sensor_offset" in result.outside, (result.found, result.outside)
    assert result.unexplained is not None and result.unexplained.correlations[0].quantity == "time"
    # the search did take it: the check after it is what refuses the name
    assert any(r.accepted == "sensor_offset" for r in result.rounds)


def test_a_true_offset_beside_a_drift_is_named_by_neither() -> None:
    """(What the check gives up: an offset of the vocabulary next to a drift outside it is not named either; the
    unexplained residual's description says time.)"""
    data = synthetic([(EFFECTS["sensor_offset"], {"drive_current": 0.06, "load_current": 0.0}, {})], seed=8)
    run_time = time_in_run(prepare_signals(RIG, data))
    data.current_drive = data.current_drive + 0.006 * run_time
    result = an.analyse(problem_at(data, RIG, block_seconds=0.5))
    assert result.found == [] and result.unexplained is not None


