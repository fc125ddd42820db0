"""worm_calc: the installed executable's JSON equals the core's answer; bad input exits 2."""
from __future__ import annotations

import json
import math
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from ament_index_python.packages import get_package_prefix

from worm_model.calc.calculator import efficiencies, forces, make_gearbox
from worm_model.errors import CalculatorError
from worm_model.physics.efficiency import backward_efficiency, forward_efficiency
from worm_model.physics.friction import sliding_velocity
from worm_model.physics.internal_forces import internal_forces
from worm_model.physics.parameters import load_rig

GB = load_rig().gearbox
EXE = str(Path(get_package_prefix("worm_model")) / "lib" / "worm_model" / "worm_calc")


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([EXE, *args], capture_output=True, text=True, timeout=60)


def run_json(*args: str) -> dict:
    done = run(*args, "--json")
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_forces_json_matches_the_core() -> None:
    geometry = dict(r_w=0.01, r_g=0.04, lam=8.0, phi=14.5)
    out = run_json("--r-worm", "0.01", "--r-gear", "0.04", "--lead-angle-deg", "8", "--pressure-angle-deg", "14.5",
                   "--tau-in", "0.01", "--tau-load", "0.6", "--omega", "-120", "--alpha-worm", "30",
                   "--worm-inertia", "2e-5", "--gear-inertia", "1e-4")
    gb = replace(GB, worm_pitch_radius=geometry["r_w"], gear_pitch_radius=geometry["r_g"],
                 lead_angle=math.radians(geometry["lam"]), normal_pressure_angle=math.radians(geometry["phi"]))
    ratio = gb.geometric_ratio
    ref = internal_forces(gb, 0.01, 0.6, -120.0, 30.0, ratio * 30.0, worm_inertia=2e-5, gear_inertia=1e-4)
    assert out["normal_force"] == pytest.approx(float(ref.normal_force), rel=1e-12)
    assert out["friction_force"] == pytest.approx(float(ref.friction_force), rel=1e-12)
    assert out["mu"] == pytest.approx(float(ref.mu), rel=1e-12)
    assert out["flank_sign"] == int(ref.flank)
    # worm turns -, the load +0.6 N m pushes + : it aids the motion, coast flank
    assert out["mode"] == "assistive" and out["flank"] == "coast"
    assert out["sliding_velocity"] == pytest.approx(float(sliding_velocity(gb, -120.0)))
    # power balance at the mesh, as printed
    assert out["input_power"] == pytest.approx(out["output_power"] + out["friction_power"], rel=1e-9)
    assert out["speed_ratio"] == pytest.approx(ratio)


def test_forces_default_geometry_is_the_bundled_rig() -> None:
    out = run_json("--tau-in", "0.02", "--tau-load", "0.3")
    assert out["worm_pitch_radius"] == pytest.approx(GB.worm_pitch_radius)
    assert out["lead_angle"] == pytest.approx(GB.lead_angle)
    assert out["omega_worm"] is None and out["input_power"] is None  # no speed given: no powers
    assert out["mode"] == "resistive" and out["flank"] == "driving"
    assert out == pytest.approx(forces(GB, 0.02, 0.3), nan_ok=True)  # the core's answer, key for key


@pytest.mark.parametrize("mu", [0.03, 0.2])
def test_efficiency_json_matches_the_core(mu: float) -> None:
    out = run_json("--mu", str(mu), "--lead-angle-deg", "5.710593")
    assert out["efficiency_forward"] == pytest.approx(float(forward_efficiency(GB, mu)), rel=1e-6)
    assert out["efficiency_backward"] == pytest.approx(float(backward_efficiency(GB, mu)), rel=1e-6)
    assert out["self_locking"] is (mu > GB.self_locking_mu)  # 0.094 for the bundled geometry
    assert out["self_locking"] is (out["efficiency_backward"] <= 0)
    assert set(out) >= {"mu", "efficiency_forward", "efficiency_backward", "self_locking", "friction_angle"}


def test_text_output_and_help() -> None:
    text = run("--mu", "0.05")
    assert text.returncode == 0 and "forward efficiency" in text.stdout and "self-locking" in text.stdout
    helped = run("--help")
    for option in ("--r-worm", "--r-gear", "--lead-angle-deg", "--pressure-angle-deg", "--tau-in", "--tau-load",
                   "--omega", "--alpha-worm", "--worm-inertia", "--gear-inertia", "--mu", "--json", "--rig"):
        assert option in helped.stdout
    assert "[m]" in helped.stdout and "[N m]" in helped.stdout


@pytest.mark.parametrize(
    "args, fragment",
    [
        (("--r-worm", "-0.01", "--mu", "0.1"), "worm pitch radius"),
        (("--lead-angle-deg", "95", "--mu", "0.1"), "lead angle"),
        (("--mu", "0.1", "--tau-in", "0.2"), "cannot be combined"),
        (("--mu", "0.1", "--omega", "10"), "cannot be combined"),
        (("--tau-in", "0.2"), "missing --tau-load"),
        ((), "give --tau-in and --tau-load"),
        (("--mu", "-0.1"), "mu"),
        (("--mu", "abc"), "not a number"),
        (("--tau-in", "0.1", "--tau-load", "0.1", "--gear-inertia", "-1"), "gear inertia"),
        (("--tau-in", "0.1", "--tau-load", "0.1", "--rig", "/nonexistent/rig.yaml"), "rig.yaml"),
        (("--tau-in", "0.001", "--tau-load", "0.3", "--omega", "150"), "more out than in"),
    ],
)
def test_bad_input_exits_2(args: tuple[str, ...], fragment: str) -> None:
    done = run(*args)
    assert done.returncode == 2 and fragment in done.stderr, done.stderr
    assert done.stdout == ""


def test_core_rejects_bad_geometry_and_computes_efficiency_table() -> None:
    with pytest.raises(CalculatorError, match="gear pitch radius"):
        make_gearbox(GB, 0.01, 0.0, 0.1, 0.3)
    with pytest.raises(CalculatorError, match="tau_in"):
        forces(GB, math.nan, 0.1)
    # efficiency falls with mu; the drive locks exactly at mu = cos(phi_n) tan(lambda)
    mus = np.linspace(0.0, 0.2, 9)
    eta = [efficiencies(GB, m)["efficiency_forward"] for m in mus]
    assert np.all(np.diff(eta) < 0) and eta[0] == pytest.approx(1.0)
    assert not efficiencies(GB, 0.999 * GB.self_locking_mu)["self_locking"]
    assert efficiencies(GB, 1.001 * GB.self_locking_mu)["self_locking"]


def test_torques_that_would_make_energy_are_refused() -> None:
    """Friction only takes power out of the mesh: 0.001 N m in against 0.3 N m at the gear, 150 rad/s (0.15 W
    in, 1.5 W out, mu -0.084) is refused, with and without a speed; 0.02 N m in (mu 0.09) is a real point."""
    with pytest.raises(CalculatorError, match="0.15 W in and the gear takes 1.5 W out"):
        forces(GB, 0.001, 0.3, 150.0)
    with pytest.raises(CalculatorError, match=r"mu = -0.0845 < 0"):
        forces(GB, 0.001, 0.3)
    with pytest.raises(CalculatorError, match="more out than in"):  # assistive: the gear drives the worm
        forces(GB, -0.02, -0.3, 150.0)
    ok = forces(GB, 0.02, 0.3, 150.0)
    assert ok["mu"] > 0 and ok["input_power"] > ok["output_power"] > 0
