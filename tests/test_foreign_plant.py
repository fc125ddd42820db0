"""Sanity of the foreign worm drives (torque_estimator.evaluation.foreign): the plant the project's estimators are
validated on.

The expected values here are written out again from the textbook relations (tooth-normal force at the pitch point,
Coulomb friction along the thread, a PMDC motor), not taken from the plant's own helpers, so that a sign or a
flank mistaken in the plant shows. Recordings are short: the file runs in seconds.
"""
from __future__ import annotations

import ast
import math
import time
from pathlib import Path

import numpy as np
import pytest

from torque_estimator.evaluation.foreign import plant
from torque_estimator.evaluation.foreign.drives import BIG50, DRIVES, FOREIGN30, LIFT40, datasheet_args
from torque_estimator.evaluation.foreign.recordings import (HEADER, excitation, released, speed_range, start_stop,
                                                            steady, validation, write_csv)

FOLDER = Path(plant.__file__).resolve().parent
PROJECT = ("worm_model", "worm_rig_driver", "torque_estimator", "worm_msgs")
CATALOGUE_KEYS = {"ratio", "starts", "hand", "lead_angle_deg", "pressure_angle_deg", "torque_constant",
                  "resistance", "rotor_inertia_gcm2", "inductance_mh", "rated_current", "max_voltage"}


def expected_current(drive, omega: float, load: float, alpha: float = 0.0) -> tuple[float, int]:
    """(current, flank) from the worm-gear relations, written independently of the plant."""
    lam, phi = drive.lead_angle, drive.normal_pressure_angle
    sigma = 1.0 if omega > 0 else -1.0
    v_s = abs(omega) * drive.worm_pitch_radius / math.cos(lam)
    mu = drive.mu_k + drive.mu_s * math.exp(-v_s / drive.v_st)
    rho = math.atan(mu / math.cos(phi))  # K_+ = tan(lambda + rho'), K_- = tan(lambda - rho')
    omega_g = omega * drive.starts / drive.teeth
    drag = math.copysign(drive.gear_coulomb + drive.gear_coulomb_rise * math.exp(-abs(omega_g) / drive.gear_rise_speed),
                         omega_g) + drive.gear_viscous * omega_g
    g_m = sigma * (load + drag + drive.gear_inertia * drive.starts / drive.teeth * alpha)
    flank = 1 if g_m >= 0 else -1
    k = math.tan(lam + rho) if flank > 0 else math.tan(lam - rho)
    t_worm = sigma * drive.worm_pitch_radius / drive.gear_pitch_radius * k * g_m
    torque = (drive.rotor_inertia + drive.worm_inertia) * alpha + drive.motor_viscous * omega \
        + sigma * drive.motor_coulomb + t_worm
    return torque / drive.torque_constant, flank


# ------------------------------------------------------------------------------------------------------------
# the drives

@pytest.mark.parametrize("drive", DRIVES.values(), ids=DRIVES)
def test_catalogue_and_geometry(drive) -> None:
    assert CATALOGUE_KEYS <= set(drive.catalogue)
    assert ("worm_diameter_mm" in drive.catalogue) != ("centre_distance_mm" in drive.catalogue)
    i = drive.starts / drive.teeth
    assert i == pytest.approx(1.0 / drive.catalogue["ratio"])
    assert i == pytest.approx(drive.worm_pitch_radius * math.tan(drive.lead_angle) / drive.gear_pitch_radius, rel=1e-12)
    if "centre_distance_mm" in drive.catalogue:
        assert drive.worm_pitch_radius + drive.gear_pitch_radius == pytest.approx(
            drive.catalogue["centre_distance_mm"] * 1e-3)
    else:
        assert 2 * drive.worm_pitch_radius == pytest.approx(drive.catalogue["worm_diameter_mm"] * 1e-3)
    assert drive.torque_constant == drive.catalogue["torque_constant"]
    assert drive.rotor_inertia == pytest.approx(drive.catalogue["rotor_inertia_gcm2"] * 1e-7)
    args = datasheet_args(drive)
    assert args[:2] == ["--ratio", str(drive.catalogue["ratio"])] and len(args) == 2 * len(drive.catalogue)
    # no jam: the coast flank's effective inertia stays positive even at standstill friction
    assert plant.coast_inertia_min(drive) > 0


def test_self_locking_is_as_catalogued() -> None:
    limit = {d.name: math.cos(d.normal_pressure_angle) * math.tan(d.lead_angle) for d in DRIVES.values()}
    assert limit["foreign30"] == pytest.approx(0.113, abs=1e-3) and not FOREIGN30.self_locking
    assert limit["lift40"] == pytest.approx(0.0575, abs=1e-3) and LIFT40.self_locking
    assert not BIG50.self_locking


def test_the_simulator_imports_nothing_of_the_project() -> None:
    allowed = {"math", "dataclasses", "typing", "collections", "argparse", "sys", "time", "pathlib", "numpy",
               "scipy", "__future__"}
    for path in FOLDER.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                roots = {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                if (node.module or "").startswith("torque_estimator.evaluation.foreign."):
                    continue  # its own folder (the project's imports are absolute)
                roots = {(node.module or "").split(".")[0]}
            else:
                continue
            assert not roots & set(PROJECT), f"{path.name} imports the project: {roots}"
            assert roots <= allowed, f"{path.name} imports {roots - allowed}"


# ------------------------------------------------------------------------------------------------------------
# steady state and dynamics

CASES = [(+0.5, 1.0), (+0.5, -0.4), (-0.5, 1.0), (-0.5, -0.4), (+0.1, 1.2), (-0.1, 1.2)]
"""(speed as a fraction of the excitation's top speed, load as a fraction of the drive's load scale)."""


@pytest.mark.parametrize("drive", DRIVES.values(), ids=DRIVES)
def test_steady_current_matches_the_mesh_relations(drive) -> None:
    top = speed_range(drive)[1]
    for speed_frac, load_frac in CASES:
        omega, load = speed_frac * top, load_frac * drive.load_scale
        rec = steady(drive, omega, load, 1.0, seed=3)
        held = rec.t > 0.6
        current, flank = expected_current(drive, omega, load)
        where = f"{drive.name} at {omega:g} rad/s, {load:g} N m"
        assert np.mean(rec.omega_worm[held]) == pytest.approx(omega, rel=5e-3, abs=0.05), where
        assert set(rec.flank[held]) == {flank}, where
        tol = 4 * drive.current_noise / math.sqrt(held.sum()) + 2e-3 * abs(current) + 2e-4
        assert np.mean(rec.current_drive[held]) == pytest.approx(current, abs=tol), where
        assert plant.steady_current(drive, omega, load) == pytest.approx(current, rel=1e-12, abs=1e-12)
    # the coast flank is reached by an aiding load, and a back-drivable drive then brakes: the current opposes
    # the motion; a self-locking one still drives
    rec = steady(drive, -0.5 * top, drive.load_scale, 1.0)
    i_lowering = np.mean(rec.current_true[rec.t > 0.6])
    assert (i_lowering < 0) == drive.self_locking, drive.name


@pytest.mark.parametrize("load", [0.5, -0.8])
def test_inertia_on_a_ramp_is_the_flanks(load: float) -> None:
    """Accelerating at 500 rad/s^2: the current carries the effective inertia of the engaged flank."""
    drive = FOREIGN30
    rec = steady(drive, 150.0, load, 0.2, ramp=0.3)
    window = (rec.t > 0.12) & (rec.t < 0.28)
    alpha = np.gradient(rec.omega_true, rec.t)
    expected = [expected_current(drive, w, load, a) for w, a in zip(rec.omega_true[window], alpha[window])]
    assert {f for _, f in expected} == ({1} if load > 0 else {-1})
    assert set(rec.flank[window]) == {f for _, f in expected}
    assert np.mean(alpha[window]) == pytest.approx(500.0, rel=0.02)
    want = np.array([c for c, _ in expected])
    assert np.mean(rec.current_true[window]) == pytest.approx(np.mean(want), abs=3e-3)
    # the inertia term is not negligible here: without it the current would be off by much more
    still = np.array([expected_current(drive, w, load)[0] for w in rec.omega_true[window]])
    assert abs(np.mean(still) - np.mean(want)) > 10 * 3e-3


def test_lifting_draws_more_than_lowering_and_no_energy_is_made() -> None:
    for drive in DRIVES.values():
        omega, load = 0.4 * speed_range(drive)[1], drive.load_scale
        lift, lower = (steady(drive, s * omega, load, 1.0) for s in (1.0, -1.0))
        held = lift.t > 0.6
        i_lift, i_lower = np.mean(lift.current_true[held]), np.mean(lower.current_true[held])
        p_lift = np.mean((lift.voltage_drive * lift.current_drive)[held])
        p_lower = np.mean((lower.voltage_drive * lower.current_drive)[held])
        assert abs(i_lift) > abs(i_lower) and p_lift > p_lower, drive.name
        load_power = load * omega * drive.starts / drive.teeth  # lifted or released by the hanging load
        shaft_lift = drive.torque_constant * i_lift * omega
        shaft_lower = drive.torque_constant * i_lower * -omega  # > 0: the motor drives, < 0: it is driven
        assert shaft_lift > load_power, drive.name  # efficiency < 1
        assert -shaft_lower < load_power, drive.name  # it never gives back more than the load released
        assert (shaft_lower > 0) == drive.self_locking, drive.name


# ------------------------------------------------------------------------------------------------------------
# standstill

@pytest.mark.parametrize("load", [1.0, -1.0, 2.0])
def test_a_self_locking_drive_holds_its_load_with_the_motor_off(load: float) -> None:
    rec = released(LIFT40, load * LIFT40.load_scale, 0.5)
    assert np.all(rec.omega_true == 0.0) and np.all(rec.current_true == 0.0)
    assert np.ptp(rec.theta_worm) == 0.0 and np.ptp(rec.theta_true) == 0.0


@pytest.mark.parametrize("drive", [FOREIGN30, BIG50], ids=["foreign30", "big50"])
@pytest.mark.parametrize("load", [1.0, -1.0])
def test_a_back_drivable_drive_runs_away_under_its_load(drive, load: float) -> None:
    rec = released(drive, load * drive.load_scale, 0.3)
    assert np.all(rec.current_true == 0.0)
    w = rec.omega_true
    assert np.sign(w[-1]) == -np.sign(load)  # the load turns it the way it pulls
    assert abs(w[-1]) > abs(w[len(w) // 2]) > 0  # still accelerating
    assert set(rec.flank[len(w) // 2:]) == {-1}  # the gear drives the worm: the coast flank
    assert np.sign(rec.theta_worm[-1] - rec.theta_worm[0]) == -np.sign(load)
    # but a load below the supports' drag does not move it
    small = released(drive, 0.5 * drive.gear_coulomb, 0.2)
    assert np.all(small.omega_true == 0.0)


def test_start_stop_of_the_self_locking_drive() -> None:
    drive, load, speed = LIFT40, 0.8, 20.0
    rec = start_stop(drive, load, speed, rest=0.5, hold=1.0, ramp=0.2)
    # segments: rest 0-0.5, ramp, lower 0.7-1.7, ramp, rest 1.9-2.4, ramp, lift 2.6-3.6, ramp, rest 3.8-4.3
    for a, b in ((0.0, 0.5), (2.1, 2.4), (4.0, 4.3)):
        s = (rec.t >= a) & (rec.t < b)
        assert np.all(rec.omega_true[s] == 0.0), (a, b)
    for a, b, sign in ((1.0, 1.7, -1.0), (2.9, 3.6, 1.0)):
        s = (rec.t >= a) & (rec.t < b)
        assert np.mean(rec.omega_worm[s]) == pytest.approx(sign * speed, rel=0.02)
        current, flank = expected_current(drive, sign * speed, load)
        assert set(rec.flank[s]) == {flank}
        assert np.mean(rec.current_drive[s]) == pytest.approx(current, abs=0.01)
    lower = (rec.t >= 1.0) & (rec.t < 1.7)
    assert np.mean(rec.current_drive[lower]) < 0  # the motor drives the load down through the locked mesh


# ------------------------------------------------------------------------------------------------------------
# sensors, the CSV, determinism

@pytest.mark.parametrize("drive", DRIVES.values(), ids=DRIVES)
def test_sensors(drive) -> None:
    rec = excitation(drive, 3.0, seed=7)
    step = 2 * math.pi / drive.counts_per_rev
    counts = rec.theta_worm / step
    assert np.allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    assert np.all(rec.theta_true - rec.theta_worm >= -1e-9) and np.all(rec.theta_true - rec.theta_worm < step + 1e-9)
    assert np.ptp(rec.theta_worm) > 2 * math.pi  # unwrapped
    ts = 1.0 / drive.sample_rate
    assert np.allclose(np.diff(rec.t), ts)
    if drive.speed_source == "encoder":
        m = drive.speed_average
        expect = (rec.theta_worm[m:] - rec.theta_worm[:-m]) / (m * ts)
        assert np.allclose(rec.omega_worm[m:], expect, rtol=1e-12, atol=1e-9)
    else:
        noise = rec.omega_worm - rec.omega_true
        assert np.std(noise) == pytest.approx(drive.tacho_noise, rel=0.1)
    noise = rec.current_drive - rec.current_true
    assert np.std(noise) == pytest.approx(math.hypot(drive.current_noise, drive.current_lsb / math.sqrt(12)),
                                          rel=0.1)
    if drive.current_lsb:
        assert np.allclose(rec.current_drive / drive.current_lsb, np.round(rec.current_drive / drive.current_lsb))
    assert np.all(np.abs(rec.voltage_drive) <= drive.supply)


def test_excitation_and_validation_profiles() -> None:
    drive = FOREIGN30
    rec = excitation(drive, 30.0, seed=1)
    assert rec.tau_load.min() >= -0.5 and rec.tau_load.max() <= 1.5 and np.ptp(rec.tau_load) > 0.8
    assert len(np.unique(rec.tau_load)) >= 10  # held 1-3 s: 10 to 30 levels in 30 s
    held = rec.speed_ref[1:][np.diff(rec.speed_ref) == 0]
    held = held[held != 0]
    assert np.all((np.abs(held) >= 40 - 1e-9) & (np.abs(held) <= 300 + 1e-9))
    assert held.min() < 0 < held.max()
    assert rec.jams == 0
    other = validation(drive, 30.0, seed=1)
    assert not np.array_equal(other.speed_ref, rec.speed_ref) and not np.array_equal(other.tau_load, rec.tau_load)


def test_csv_is_the_schema_and_deterministic(tmp_path: Path) -> None:
    paths = [tmp_path / name for name in ("a.csv", "b.csv", "c.csv")]
    write_csv(paths[0], excitation(LIFT40, 2.0, seed=5))
    write_csv(paths[1], excitation(LIFT40, 2.0, seed=5))
    write_csv(paths[2], excitation(LIFT40, 2.0, seed=6))
    assert paths[0].read_bytes() == paths[1].read_bytes()
    assert paths[0].read_bytes() != paths[2].read_bytes()
    lines = paths[0].read_text(encoding="utf-8").splitlines()
    assert lines[0] == "t,current_drive,omega_worm,theta_worm,tau_load,voltage_drive" == ",".join(HEADER)
    assert len(lines) == 1 + int(2.0 * LIFT40.sample_rate) + 1
    rows = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    assert np.all(np.isfinite(rows)) and np.all(np.diff(rows[:, 0]) > 0)
    rec = excitation(LIFT40, 2.0, seed=5)
    assert lines[2] == ",".join(repr(float(getattr(rec, c)[1])) for c in HEADER)


def test_the_projects_reader_reads_it(tmp_path: Path) -> None:
    """The schema as the project reads it (the test reads with worm_model; the simulator does not import it)."""
    schema = pytest.importorskip("worm_model.rig_data.schema")
    rec = excitation(BIG50, 1.0, seed=2)
    write_csv(tmp_path / "big50.csv", rec)
    data = schema.read_rig_csv(tmp_path / "big50.csv")
    for name in HEADER:
        assert np.array_equal(getattr(data, name), getattr(rec, name)), name
    assert set(data.run) == {0}


def test_a_recording_is_fast() -> None:
    began = time.perf_counter()
    excitation(FOREIGN30, 10.0, seed=1)
    assert time.perf_counter() - began < 5.0  # 240 s take ~2 s on a 2-core machine; 5 s for 10 s is 120 s for 240
