"""Figures 6-11 (paper section 3.2): the plotted data obey the physics, and `report` writes six PNGs.

The calibration used here is synthesised with the model itself (quasi-static Eq. 28 with the
AGMA mu and the rig's declared drags), so what the figures must show is known exactly.
"""
from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from ament_index_python.packages import get_package_prefix

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_drag, gear_side_load
from worm_model.physics.modes import Mode
from worm_model.figures.paper_figures import compute, read_calibration, rig_for, trends
from worm_model.errors import ReportError
from worm_model.physics.parameters import Rig, load_rig, rig_to_dict
from worm_model.files.writing import MARKER
from worm_model.figures.report import FIGURES

RIG = load_rig()
SPEEDS = np.array([-300.0, -150.0, -40.0, 40.0, 150.0, 300.0])  # [rad/s]
TORQUES = np.linspace(-0.24, 0.24, 8)  # [N m], no zero: like the paper's grid


def synthetic_calibration(rig: Rig) -> dict:
    """Steady points of the model rig: the current that holds each (speed, load) cell."""
    w, t = (a.ravel() for a in np.meshgrid(SPEEDS, TORQUES, indexing="ij"))
    mu = friction_coefficient(rig.friction, rig.gearbox, w)
    t_mesh = reflected_input_torque(rig.gearbox, mu, gear_side_load(rig, t, w), w)  # Eq. 28, a_w = 0
    m = rig.drive_motor
    current = (t_mesh + m.viscous_drag * w + m.coulomb_drag * np.sign(w)) / m.torque_constant  # Eq. 29
    index = [[k, j] for k in range(len(SPEEDS)) for j in range(len(TORQUES))]
    n = len(w)
    return {
        "format": "worm_torque_calibration", "version": 1, "created": "2024-01-01T00:00:00+00:00",
        "notes": "synthetic, worm_model test", "units": {},
        "grid": {"speed_setpoints": SPEEDS.tolist(), "torque_setpoints": TORQUES.tolist()},
        "rig": rig_to_dict(rig), "steady_state": {},
        "points": {"omega_worm": w.tolist(), "current_drive": current.tolist(), "tau_load": t.tolist(),
                   "omega_std": [0.0] * n, "current_std": [0.0] * n, "tau_std": [0.0] * n,
                   "samples": [100] * n, "setpoint_index": index},
    }


def write(tmp_path: Path, doc: dict, name: str = "cal.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


@pytest.fixture
def calibration(tmp_path: Path) -> Path:
    return write(tmp_path, synthetic_calibration(RIG))


def test_declared_drags_recover_the_mesh_friction_exactly(calibration: Path) -> None:
    points = read_calibration(calibration)
    assert len(points) == len(SPEEDS) * len(TORQUES)
    fig = compute(points, rig_for(points, None), "declared")
    mu_true = friction_coefficient(RIG.friction, RIG.gearbox, fig.omega_worm)
    assert np.allclose(fig.mu, mu_true, rtol=1e-9)  # Fig. 9 is then the friction model itself
    assert np.allclose(fig.friction_force, fig.mu * fig.normal_force, rtol=1e-12)  # F_f = mu N
    assert np.array_equal(fig.mu_filtered, fig.mu)  # all inside [0, mu_max]
    # N = |D_mesh| / (r_g (cos(phi_n) cos(lambda) -+ mu sin(lambda))) (Eq. 20 with a = 0)
    gb = RIG.gearbox
    d_mesh = np.sign(fig.omega_worm) * gear_side_load(RIG, fig.tau_load, fig.omega_worm)
    s = np.sign(d_mesh)
    n_true = d_mesh / (gb.gear_pitch_radius * (s * math.cos(gb.normal_pressure_angle) * math.cos(gb.lead_angle)
                                              - mu_true * math.sin(gb.lead_angle)))
    assert np.allclose(fig.normal_force, n_true, rtol=1e-9)
    assert np.allclose(fig.signed_normal_force, s * fig.normal_force)
    # switching torque: where the external load cancels the load motors' drag, up to the
    # linear interpolation across the kink of s N at D_mesh = 0 (less than a grid step)
    drag = np.abs(gear_side_drag(RIG, fig.speed_setpoints))
    assert np.all(np.abs(fig.switching_torque - drag) < np.diff(TORQUES)[0])
    assert np.all(fig.switching_torque > 0)


def test_paper_method_reads_drag_into_friction(tmp_path: Path) -> None:
    """drag 'none' (T = K_t i): the paper's Figs 7, 8, 9, 11 trends appear on the bundled rig, whose
    worm shaft carries speed-proportional drag; with the AGMA mu alone (drag 'declared') they can't."""
    rig = RIG
    points = read_calibration(write(tmp_path, synthetic_calibration(rig)))
    fig = compute(points, rig_for(points, None), "none")
    assert np.allclose(fig.friction_force, fig.mu * fig.normal_force, rtol=1e-12)
    assert np.allclose(fig.input_torque, rig.drive_motor.torque_constant * points.current_drive)
    # Fig. 8: tau_sw >= 0, the same in both directions, growing with speed
    tsw = fig.switching_torque
    assert np.all(tsw > 0)
    assert np.allclose(tsw, tsw[::-1], rtol=1e-6)  # speeds are symmetric: -300 ... 300
    assert np.all(np.diff(tsw[len(SPEEDS) // 2:]) > 0)
    # modes follow D and the measured tau_sw: resistive for D > 0, assistive for D < -tau_sw
    d = fig.load_along_motion
    assert np.all(fig.mode[d > 0] == Mode.RESISTIVE)
    assert np.all(fig.mode[d < -np.nanmax(tsw)] == Mode.ASSISTIVE)
    tr = trends(fig)
    assert tr["normal_force_linearity"] > 0.99  # Fig. 6
    assert tr["normal_force_speed_spread"] < 0.05
    assert tr["friction_vs_load_slope"] > 0  # Fig. 7
    assert tr["assistive_minus_resistive_friction"] < 0
    assert tr["switching_torque_vs_speed_slope"] > 0  # Fig. 8
    assert tr["mu_vs_load_slope"] < 0  # Fig. 9
    assert tr["friction_vs_speed_slope"] > 0 and tr["mu_vs_speed_slope"] > 0  # Figs 7, 11
    # the rise with speed is the drag: the mesh's own mu (AGMA) falls with sliding speed
    assert trends(compute(points, rig_for(points, None), "declared"))["mu_vs_speed_slope"] < 0


def test_bad_calibration_files_name_the_field(tmp_path: Path) -> None:
    doc = synthetic_calibration(RIG)
    cases = {
        "format": (lambda d: d.update(format="other"), "'format'"),
        "missing column": (lambda d: d["points"].pop("current_drive"), "points.current_drive"),
        "short column": (lambda d: d["points"]["tau_load"].pop(), "points.tau_load"),
        "not finite": (lambda d: d["points"]["omega_worm"].__setitem__(3, None), "point 3"),
        "index outside": (lambda d: d["points"]["setpoint_index"].__setitem__(0, [99, 0]), "outside the grid"),
    }
    for name, (mutate, fragment) in cases.items():
        bad = json.loads(json.dumps(doc))
        mutate(bad)
        path = write(tmp_path, bad, f"{name.replace(' ', '_')}.json")
        with pytest.raises(ReportError, match=fragment) as info:
            read_calibration(path)
        assert str(path) in str(info.value), name
    broken = tmp_path / "broken.json"
    broken.write_text('{"format": ')
    with pytest.raises(ReportError, match="line 1"):
        read_calibration(broken)


def executable(name: str) -> str:
    return str(Path(get_package_prefix("worm_model")) / "lib" / "worm_model" / name)


def test_report_executable_writes_six_pngs(calibration: Path, tmp_path: Path) -> None:
    out = tmp_path / "figs"
    done = subprocess.run([executable("report"), str(calibration), "--out", str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in out.iterdir() if p.name != MARKER) == sorted(FIGURES)
    assert (out / MARKER).read_text() == "report\n"  # what lets `report --force` replace it later
    for name in FIGURES:
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, name
    assert "switching_torque_vs_speed_slope" in done.stdout


def test_report_executable_bad_input_exit_2(tmp_path: Path) -> None:
    missing = subprocess.run([executable("report"), str(tmp_path / "nope.json"), "--out", str(tmp_path)],
                             capture_output=True, text=True, timeout=60)
    assert missing.returncode == 2 and "nope.json" in missing.stderr
    (tmp_path / "cal.json").write_text("{}")
    no_out = subprocess.run([executable("report"), str(tmp_path / "cal.json")], capture_output=True, text=True,
                            timeout=60)
    assert no_out.returncode == 2 and "--out" in no_out.stderr
