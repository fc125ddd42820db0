"""The real worm drive study (evaluation.real_drive): every figure docs/real-data.md states, pinned.

The data is fixed (46 files shipped in the repository), so the figures are pinned to the digits the page
prints (one unit of the last digit: a rounding edge may fall either way on another machine's libm).
The study runs once for the module (~1 min).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from worm_model.rig_data.epos import read_epos

from torque_estimator.evaluation import real_drive
from torque_estimator.evaluation.steady_fit import halves

DOC = Path(__file__).resolve().parents[5] / "docs" / "real-data.md"


@pytest.fixture(scope="module")
def study() -> real_drive.Study:
    return real_drive.run_study()


@pytest.fixture(scope="module")
def doc() -> str:
    return DOC.read_text(encoding="utf-8")


def close(printed: str, value: float) -> bool:
    """``value`` rounds to ``printed`` within one unit of its last digit."""
    decimals = len(printed.split(".")[1]) if "." in printed else 0
    return abs(float(printed) - value) <= 1.01 * 10.0 ** -decimals


def test_the_line(study: real_drive.Study, doc: str) -> None:
    line = study.line()
    assert re.fullmatch(r"real: drive=tro2021_worm points=46 fit_rms_mNm=\d\.\d{4} tro_fit_rms_mNm=\d\.\d{4} "
                        r"load_mae_pct=\d+\.\d\d load_max_pct=\d+\.\d\d baseline_mae_pct=\d+\.\d\d mu=0\.\d{4} "
                        r"tro_mu=0\.12", line), line
    printed = re.search(r"^real: drive=.*$", doc, re.M).group(0)
    for (name, shown), (_, value) in zip(re.findall(r"(\w+)=([-\d.]+)", printed), re.findall(r"(\w+)=([-\d.]+)", line)):
        assert close(shown, float(value)), name
    assert study.fit_rms < study.tro_rms / 3.9  # "four times below the T-RO fit"


def test_every_row_of_the_per_point_tables(study: real_drive.Study, doc: str) -> None:
    rows = re.findall(r"^\| (-?\d+) \| (-?[\d.]+) \| ([\d.]+) \| (-?[\d.]+) \| (-?[\d.]+) \| ([-+\d.]+) \| "
                      r"([-+\d.]+) \| ([\d.]+) \|$", doc, re.M)
    assert len(rows) == 46
    by_rpm = {p.rpm: k for k, p in enumerate(study.points)}
    loads = study.loads
    for rpm, measured, sem, tro, ours, err, base, bound in rows:
        k = by_rpm[int(rpm)]
        for shown, value in ((measured, 1e3 * study.measured[k]), (sem, 1e3 * study.points[k].torque_sem),
                             (tro, 1e3 * study.tro[k]), (ours, 1e3 * study.fitted[k]),
                             (err, loads.error_pct[k]), (base, loads.baseline_pct[k]), (bound, loads.bound_pct[k])):
            assert close(shown, value), (rpm, shown, value)


def test_rms_and_summary_figures(study: real_drive.Study, doc: str) -> None:
    rms = real_drive.Study._rms
    assert close("0.1054", 1e3 * study.tro_rms) and close("0.0264", 1e3 * study.fit_rms)
    assert close("0.0252", 1e3 * study.selection.floor)
    assert close("0.0370", 1e3 * study.tro_structure.rms)
    np.testing.assert_allclose(study.declared, study.tro, rtol=0, atol=1e-10)
    lift, lower = study.direction("lifting"), study.direction("lowering")
    figures = {
        "torque RMS, T-RO fit [mN m]": (1e3 * rms(study.tro[lift] - study.measured[lift]),
                                        1e3 * rms(study.tro[lower] - study.measured[lower])),
        "torque RMS, ours fitted [mN m]": (1e3 * rms(study.fitted[lift] - study.measured[lift]),
                                           1e3 * rms(study.fitted[lower] - study.measured[lower])),
        "load error, mean [%]": (study.load_figures(lift)[0], study.load_figures(lower)[0]),
        "load error, largest [%]": (study.load_figures(lift)[1], study.load_figures(lower)[1]),
        "baseline, mean [%]": (study.load_figures(lift)[2], study.load_figures(lower)[2]),
        "the data's bound, mean [%]": (float(np.mean(study.loads.bound_pct[lift])),
                                       float(np.mean(study.loads.bound_pct[lower]))),
    }
    for label, (a, b) in figures.items():
        shown = re.search(rf"^\| {re.escape(label)} \| ([\d.]+) \| ([\d.]+) \|$", doc, re.M)
        assert shown and close(shown.group(1), a) and close(shown.group(2), b), label
    assert not study.loads.ambiguous.any()
    # the torque per unit load: 1/19 lifting, 1/53 lowering (the fitted model's slope at the points)
    sp = real_drive.steady_points(study.points)
    step = 1e-6
    slope = (study.final.torque(sp.omega, sp.tau_load + step) - study.final.torque(sp.omega, sp.tau_load)) / step
    assert round(1 / np.mean(np.abs(slope[lift]))) == 19 and round(1 / np.mean(np.abs(slope[lower]))) == 53


def test_the_wrong_arm_of_the_v_without_the_load_range(study: real_drive.Study) -> None:
    """A table from 0 to twice the load: AMBIGUOUS and the driving flank's candidate at 1, 2 and 6 rpm lowering."""
    loads = real_drive.estimate_loads(study.rig, real_drive.steady_points(study.points),
                                      tuple(study.selection.accepted), margin=1.0)
    rpm = np.array([p.rpm for p in study.points])
    assert sorted(rpm[loads.ambiguous].tolist()) == [-6, -2, -1]
    errors = np.abs(loads.error_pct[loads.ambiguous])
    assert 59.5 <= errors.min() and errors.max() <= 98.5


def test_parameters_and_the_selection(study: real_drive.Study, doc: str) -> None:
    final, refit = study.final.values, study.tro_structure.values
    shown = {
        "kinetic mu": (refit["friction.mu_constant"], final["friction.mu_constant"], 1.0),
        "worm-side Coulomb (`inSupBreak`) [mN m]": (refit["drive_motor.coulomb_drag"],
                                                    final["drive_motor.coulomb_drag"], 1e3),
        "worm-side viscous (`inSupVisc`) [uN m s/rad]": (refit["drive_motor.viscous_drag"],
                                                         final["drive_motor.viscous_drag"], 1e6),
        "gear-side Coulomb (`outSupBreak`) [mN m]": (refit["load_motor.coulomb_drag"],
                                                     final["load_motor.coulomb_drag"], 1e3),
    }
    for label, (a, b, scale) in shown.items():
        row = re.search(rf"^\| {re.escape(label)} \| [\d.]+ \| ([\d.]+) \| ([\d.]+) \|$", doc, re.M)
        assert row and close(row.group(1), scale * a) and close(row.group(2), scale * b), label
    assert close("12.46", 1e3 * final["gear_support_stribeck.torque"])
    assert close("0.2547", final["gear_support_stribeck.speed"])
    assert close("0.0469", refit["friction.stribeck_rise"])
    gearbox = study.rig.gearbox
    speed = refit["friction.stribeck_speed"] * math.cos(gearbox.lead_angle) / gearbox.worm_pitch_radius
    assert close("0.5772", speed)
    assert round(1e3 * (final["load_motor.coulomb_drag"] + final["gear_support_stribeck.torque"])) == 16
    assert refit["load_motor.coulomb_drag"] == pytest.approx(real_drive.LOAD, abs=5e-6)  # = the load
    assert round(refit["friction.mu_constant"], 3) == 0.020
    sel = study.selection
    assert sel.accepted == ["gear_support_stribeck"] and sel.unexplained
    assert close("0.0846", 1e3 * sel.held_out[0]) and close("0.0305", 1e3 * sel.held_out[1])
    assert close("1.21", sel.held_out[-1] / sel.floor)
    square = (sel.final.predicted - study.measured) ** 2
    fast = np.abs([p.rpm for p in study.points]) >= 160
    assert fast.sum() == 6 and round(100 * square[fast].sum() / square.sum()) == 27
    names = {"gear support Stribeck": "gear_support_stribeck", "tooth Stribeck": "tooth_stribeck",
             "viscous drag": "viscous_drag", "flank-dependent mu": "mode_dependent_mu",
             "worm support Stribeck": "worm_support_stribeck"}
    for k, row in enumerate(re.findall(r"^\| ([12]) \| ([a-z].+?) \| .* \|$", doc, re.M)):
        for label, value in re.findall(r"([a-zA-Z -]+?) ([\d.]+)(?:,|$)", row[1]):
            assert close(value, 1e3 * sel.rounds[k][names[label.strip()]]), (row[0], label)
    # the ratio of the low-speed changes: K+/|K-| at the fitted mu, and as measured from 10 to 1 rpm
    gb = study.rig.gearbox
    rho = math.atan(final["friction.mu_constant"] / math.cos(gb.normal_pressure_angle))
    assert round(math.tan(gb.lead_angle + rho) / abs(math.tan(gb.lead_angle - rho)), 1) == 2.8
    t = {p.rpm: abs(p.torque) for p in study.points}
    assert round((t[1] - t[10]) / (t[-10] - t[-1]), 1) == 2.4


def test_the_residuals_tool_on_the_exports(study: real_drive.Study) -> None:
    standard, single = study.residuals
    assert standard.found and standard.unexplained  # names the aliases of runaway corrections
    assert max(b / a for a, b in standard.corrections.values()) > 5
    assert single.found == [] and single.unexplained
    speed = [g for g in single.goes_with if g.startswith("speed ")]
    assert speed and "at -0.105" in speed[0]  # the slowest lowering speed


def test_stick_slip_at_the_slowest_speeds() -> None:
    folder = real_drive.data_folder()
    for name, share in (("1.csv", 43), ("2.csv", 21)):
        w = read_epos(folder / name, skip_bad_rows=True).values["velocity"] * 30 / math.pi
        assert round(100 * np.mean(np.abs(w) < 0.5)) == share


def test_the_plot_and_the_split(study: real_drive.Study, tmp_path: Path) -> None:
    path = real_drive.plot(study, tmp_path / "real.png")
    assert path.stat().st_size > 20_000
    rpm = [p.rpm for p in study.points]
    half = halves(np.array([p.omega for p in study.points]))
    assert [r for r, h in zip(rpm, half) if h == 1 and r > 0] == [2, 6, 10, 17, 25, 40, 60, 80, 100, 140, 180]


def test_the_readme_states_the_pages_figures(study: real_drive.Study) -> None:
    """The README's real-drive section quotes the study's line and its two RMS figures."""
    readme = (DOC.parents[1] / "README.md").read_text(encoding="utf-8")
    printed = re.search(r"^real: drive=.*$", readme, re.M).group(0)
    for (name, shown), (_, value) in zip(re.findall(r"(\w+)=([-\d.]+)", printed),
                                         re.findall(r"(\w+)=([-\d.]+)", study.line())):
        assert close(shown, float(value)), name
    fit, tro = re.search(r"RMS (\d\.\d+) against (\d\.\d+) mN m", readme).groups()
    assert close(fit, study.fit_rms * 1e3) and close(tro, study.tro_rms * 1e3)
    assert "four times more closely" in readme and 3.9 < study.tro_rms / study.fit_rms < 4.5
