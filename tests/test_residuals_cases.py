"""Issue 15: `residuals` names exactly the true effects, reaches the noise floor, and says "unexplained"
for an effect outside its vocabulary (the case matrix of torque_estimator.experiment.residual_cases).

Data: the project's simulator (SimulatedRig with effect plug-ins the model is not told about), the
analysis given a rig file whose declared numbers are off by realistic amounts (cases.PERTURBATIONS).
The small matrix is the one ``make evaluate`` prints (its ``residuals:`` line is pinned here); the full
one (every effect alone and in pairs, each with the declared values nominal, high and low; clean data;
both out-of-vocabulary effects: 75 cases, ~5 min on 2 cores) runs with RESIDUALS_FULL_MATRIX=1.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

import torque_estimator.experiment.residual_cases as cs
from worm_model.rig_data.schema import write_rig_csv

REPO = Path(__file__).resolve().parents[1]


def _check(results: list[cs.CaseResult]) -> None:
    print("\n".join(cs.format_results(results)))
    line = cs.summary_line(results)
    print(line)
    n = len(results)
    oov = sum(1 for r in results if r.case.extra)
    assert line == (f"residuals: cases={n} exact={n} false_names=0 missed=0 at_floor={n - oov}/{n - oov} "
                    f"unexplained_oov={oov}/{oov} passed={n}")


def test_small_matrix_names_exactly_the_true_effects_at_the_noise_floor() -> None:
    _check(cs.run_matrix(cs.small_matrix()))


#: full-matrix cases measured to fail (open, see the README): a Stribeck rise of x3 at low speed next to order-6
#: cogging is named exactly since the look-ahead from an unphysical start (analysis._look_ahead), but half the
#: cogging ripple stays unfitted (1.9-2.0 x the floor, reported as unexplained at worm order 6, each direction its
#: own phase); with all loads resistive (slow_high_load) K_t and the mu scale trade off, so a 30 % current-sensor
#: gain next to a tooth-pass ripple is not pushed beyond K_t's tolerance (missed, at the floor)
KNOWN_OPEN = {"speed_dependent_mu+motor_cogging/nominal", "speed_dependent_mu+motor_cogging/high",
              "speed_dependent_mu+motor_cogging/low", "tooth_pass+sensor_gain/nominal", "tooth_pass+sensor_gain/low"}


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("RESIDUALS_FULL_MATRIX"), reason="full case matrix: set RESIDUALS_FULL_MATRIX=1")
def test_full_matrix_names_exactly_the_true_effects_at_the_noise_floor() -> None:
    """Measured (75 cases, pwm in the vocabulary, look-ahead): cases=75 exact=73 false_names=0 missed=2
    at_floor=66/69 unexplained_oov=6/6 passed=70 (before the look-ahead: exact=70 false_names=5 missed=8)."""
    results = cs.run_matrix(cs.full_matrix())
    print("\n".join(cs.format_results(results)))
    print(cs.summary_line(results))
    failed = {r.case.name for r in results if not r.passed}
    assert failed <= KNOWN_OPEN, sorted(failed - KNOWN_OPEN)
    assert all(r.passed for r in results if r.case.extra or not r.truth)  # clean and out-of-vocabulary: all


def test_from_an_unphysical_start_the_look_ahead_names_both_effects() -> None:
    """A x3 Stribeck rise at low speed twists the refitted drags ten-fold; alone, a viscous drag made the fit
    physical best and kept both true effects out (found: viscous_drag). The pair that lets the other in is
    taken instead: exactly the two true effects (the cogging's fit stays open: KNOWN_OPEN)."""
    case = next(c for c in cs.full_matrix() if c.name == "speed_dependent_mu+motor_cogging/nominal")
    assert cs.run_case(case).found == ("motor_cogging", "speed_dependent_mu")
    alone = next(c for c in cs.full_matrix() if c.name == "speed_dependent_mu/nominal")
    result = cs.run_case(alone)
    assert result.found == ("speed_dependent_mu",) and result.passed  # the pair's drag is dropped again


def test_a_declared_value_off_is_a_correction_and_beyond_its_tolerance_an_alias_effect() -> None:
    """K_t declared 5 % high is a correction; a drive-current sensor gain of +30 % on top is named sensor_gain."""
    clean = cs.run_case(cs.case_of([], "high", seed=11))
    assert clean.found == () and clean.corrections["drive_motor.torque_constant"] == pytest.approx(1 / 1.05, rel=0.02)
    assert clean.corrections["friction.scale"] == pytest.approx(1 / 1.3, rel=0.05)
    gain = cs.run_case(cs.case_of(["sensor_gain"], "high"))
    assert gain.found == ("sensor_gain",)


def test_out_of_vocabulary_effect_is_reported_unexplained_by_the_executable(tmp_path: Path) -> None:
    """A torque ripple three times per gear turn: nothing named, `unexplained=` on the found line, the
    report says it goes with the gear angle at order 3, and unexplained.png is written."""
    data = cs.simulate(cs.case_of([], "nominal", seed=3, extra=["gear_order3_ripple"]))
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
