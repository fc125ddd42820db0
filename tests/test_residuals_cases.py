"""`residuals` names exactly the true effects, reaches the noise floor, keeps its corrections physical, and names
nothing for an effect outside its vocabulary (the case matrix of torque_estimator.evaluation.residual_cases).

Data: the project's simulator (SimulatedRig with effect plug-ins the model is not told about), the analysis given a
rig file written as a user writes one, its declared numbers off by realistic amounts (rig_files.PERTURBATIONS, the
changed numbers with sources), on two rigs under both friction models (rig_files.RIGS, catalogue.families).  The full
matrix is the one ``make evaluate`` prints (163 cases: 18 min on a shared 2-core machine, load ~5); its
``residuals:`` line is pinned here, as is that of the 22-case subset (``evaluate --residual-cases small``).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

from torque_estimator.evaluation.residual_cases.case import Case, CaseResult
from torque_estimator.evaluation.residual_cases.catalogue import case_of, full_matrix, small_matrix
from torque_estimator.evaluation.residual_cases.report import family_lines, format_results, summary_line
from torque_estimator.evaluation.residual_cases.runner import run_case, run_matrix
from torque_estimator.evaluation.residual_cases.simulation import simulate
from worm_model.rig_data.schema import write_rig_csv

REPO = Path(__file__).resolve().parents[1]

#: every case run in this module, by name: the cases are seeded, so one the full matrix shares with the small one
#: (all 23 of them) or with a test below is run once
_RESULTS: dict[str, CaseResult] = {}


def _results(cases: list[Case]) -> list[CaseResult]:
    todo = [case for case in cases if case.name not in _RESULTS]
    _RESULTS.update(zip((case.name for case in todo), run_matrix(todo) if todo else []))
    assert all(_RESULTS[case.name].case == case for case in cases)  # a name is one case
    return [_RESULTS[case.name] for case in cases]


def _line(results: list[CaseResult]) -> str:
    print("\n".join(format_results(results)))
    print("\n".join(family_lines(results)))
    line = summary_line(results)
    print(line)
    return line


def test_small_matrix_names_exactly_the_true_effects_at_the_noise_floor() -> None:
    results = _results(small_matrix())
    n = len(results)
    oov = [r for r in results if r.case.extra]
    assert _line(results) == (f"residuals: cases={n} exact={n} false_names=0 missed=0 at_floor={n - len(oov)}/"
                              f"{n - len(oov)} "
                              f"unexplained_oov={sum(r.unexplained is not None for r in oov)}/{len(oov)} "
                              f"unphysical=0 passed={n}")
    assert sum(r.unexplained is not None for r in oov) >= 3  # all but the bearing drag mu takes (CaseResult.passed)


@pytest.mark.slow
def test_full_matrix_names_exactly_the_true_effects_at_the_noise_floor() -> None:
    """Measured (173 cases in seven families): the line below (the stribeck family: 10 of 10).  The one left:
    backlash on the NMRV040 (gear-side inertia
    3.6x the NMRV030's): its impacts leave the current at 1.30x the floor, which biases the refitted load-motor drag
    to 0 (true 8 mN m); the modelled flank changes then come at the wrong times and the transmission error's
    backlash fit fails (with the true rig and nothing refitted it takes the TE from 2.29 to 0.46 mrad).  Before the
    mu correction was live under every friction model, drags held at 0, absolute bands around a declared 0 and the
    outside-the-vocabulary check: cases=163 exact=139 false_names=22 missed=6 at_floor=135/137 unexplained_oov=21/26
    unphysical=20 passed=124 (load_dependent_mu the false name in 14 of the 22; the first matrix's 75 cases all exact
    before and after)."""
    assert _line(_results(full_matrix())) == FULL_LINE


FULL_LINE = ("residuals: cases=173 exact=172 false_names=0 missed=1 at_floor=145/145 unexplained_oov=23/28 "
             "unphysical=0 passed=172")


def test_from_an_unphysical_start_the_look_ahead_names_both_effects_and_fits_the_cogging() -> None:
    """A x3 Stribeck rise at low speed twists the refitted drags ten-fold; alone, a viscous drag made the fit
    physical best and kept both true effects out (found: viscous_drag). The pair that lets the other in is
    taken instead: exactly the two true effects. The screening round at that twisted fit (rotor inertia 0)
    once froze the cogging's shape and half the ripple stayed unfitted (1.96x the floor; now 1.21x)."""
    case = next(c for c in full_matrix() if c.name == "speed_dependent_mu+motor_cogging/nominal")
    result = _results([case])[0]
    assert result.found == ("motor_cogging", "speed_dependent_mu") and result.passed
    assert result.rms_after / result.floor < 1.3
    alone = next(c for c in full_matrix() if c.name == "speed_dependent_mu/nominal")
    result = _results([alone])[0]
    assert result.found == ("speed_dependent_mu",) and result.passed  # the pair's drag is dropped again


def test_a_sensor_gain_is_named_when_mu_absorbs_most_of_what_lies_beyond_k_t_tolerance() -> None:
    """A 30 % current-sensor gain next to a tooth-pass ripple, K_t declared 5 % low, loads all resistive: K_t
    comes out at 0.83x declared, and with K_t clamped to its band (0.9x) the mu scale takes most of the rest
    (held-out RMS 0.02235 against 0.02206 A: 1.3 %, under the 2 % an effect needs). The departure is
    significant over the held-out blocks, so it is named (it was missed)."""
    case = next(c for c in full_matrix() if c.name == "tooth_pass+sensor_gain/low")
    result = _results([case])[0]
    assert result.found == ("sensor_gain", "tooth_pass") and result.passed


def test_a_declared_value_off_is_a_correction_and_beyond_its_tolerance_an_alias_effect() -> None:
    """K_t declared 5 % high is a correction; a drive-current sensor gain of +30 % on top is named sensor_gain."""
    clean = run_case(case_of([], "high", seed=11))
    assert clean.found == () and clean.corrections["drive_motor.torque_constant"] == pytest.approx(1 / 1.05, rel=0.02)
    assert clean.corrections["friction.scale"] == pytest.approx(1 / 1.3, rel=0.05)
    gain = run_case(case_of(["sensor_gain"], "high"))
    assert gain.found == ("sensor_gain",)


def test_out_of_vocabulary_effect_is_reported_unexplained_by_the_executable(tmp_path: Path) -> None:
    """A torque ripple three times per gear turn: nothing named, `unexplained=` on the found line, the
    report says it goes with the gear angle at order 3, and unexplained.png is written."""
    data = simulate(case_of([], "nominal", seed=3, extra=["gear_order3_ripple"]))
    path = tmp_path / "oov.csv"
    write_rig_csv(path, data)
    exe = REPO / "ros_ws" / "install" / "worm_model" / "lib" / "worm_model" / "residuals"
    run = subprocess.run([str(exe), str(path), "--out", str(tmp_path / "out"), "--quiet"], capture_output=True,
                         text=True, timeout=300, env=dict(os.environ))
    assert run.returncode == 0, run.stderr
    last = run.stdout.strip().splitlines()[-1]
    assert re.fullmatch(r"found: none rms_before=\S+ rms_after=\S+ A unexplained=\S+ A", last), last
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["effects_found"] == []
    unexplained = report["unexplained"]
    assert unexplained["ratio_to_floor"] > 1.3 and last.endswith(f"unexplained={unexplained['rms']:.4g} A")
    top = unexplained["correlations"][0]
    assert top["quantity"] == "gear angle orders" and "best order 3 " in top["detail"], top
    assert "noise floor" in run.stdout and "UNEXPLAINED residual" in run.stdout
    assert (tmp_path / "out" / "unexplained.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
