"""`identify --from`: a recorded run in, an extended rig file out; bad input is one line and exit 2."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml

from worm_model.physics.parameters import load_rig
from worm_model.residuals.extended import ExtendedModel
from worm_model.rig_data.schema import write_rig_csv
from worm_model.ros.ament import find_executable

from torque_estimator.estimation.extended_model import ExtendedModelEstimator, identification_ranges
from torque_estimator.estimation.observer import ObserverEstimator
from torque_estimator.evaluation.residual_cases.rig_files import write_rig_file
from torque_estimator.identification.excitation import default_excitation
from torque_estimator.identification.fit import default_refit
from worm_model.residuals.free import STANDARD_REFIT
from torque_estimator.identification.identify import main
from torque_estimator.identification.simulated import record_on_simulator

RIG = load_rig()
LINE = re.compile(r"^identify: rig_time_s=30\.0 samples=30000 road=time_series found=\S+ held=\S+ rms_before=[\d.]+ "
                  r"rms_after=[\d.]+ A -> \S+$")


@pytest.fixture(scope="module")
def record(tmp_path_factory) -> tuple[Path, Path]:
    """A 30 s excitation on the simulated rig (no effects), and a rig file with mu declared 30 % high (a source)."""
    folder = tmp_path_factory.mktemp("identify")
    write_rig_csv(folder / "run.csv", record_on_simulator(RIG, default_excitation(RIG, 30.0), seed=4))
    return folder / "run.csv", write_rig_file(folder / "declared.yaml", "nmrv030", {"mu": 1.3})


def test_identify_from_a_record(record, tmp_path, capsys) -> None:
    csv, declared = record
    out = tmp_path / "identified.yaml"
    assert main(["--from", str(csv), "--rig", str(declared), "--out", str(out), "--quiet"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert LINE.match(lines[-1]), lines[-1]
    model = ExtendedModel.load(out)
    assert load_rig(out).friction.scale == pytest.approx(1.0, abs=0.08)  # declared 1.3; measured 0.944 (30 s record)
    assert model.rig.drive_motor.torque_constant == pytest.approx(RIG.drive_motor.torque_constant, rel=0.02)
    ranges = identification_ranges(out)
    assert ranges["speed_max"] > 330 and ranges["torque_min"] < -0.2 < 0.2 < ranges["torque_max"]
    section = yaml.safe_load(out.read_text())["identification"]
    assert section["rig_time_s"] == 30.0 and "friction.scale" in section["fitted"]
    # reported as residuals reports corrections, the declared value and its provenance kept in the file
    assert any(line.strip().startswith("parameter friction.scale: declared 1.3 -> ") for line in lines), lines
    scale = yaml.safe_load(out.read_text())["friction"]["scale"]
    assert "declared 1.3, source: catalogue value" in scale["source"], scale
    # the estimators load it without a calibration database
    est = ExtendedModelEstimator(None, model_file=str(out))
    assert est.ranges_from == "identification" and est.omega_max == ranges["speed_max"]
    assert ObserverEstimator(None, model_file=str(out)).rig.friction.scale == load_rig(out).friction.scale


def test_default_set_is_the_standard_set_whatever_the_provenance(tmp_path) -> None:
    """mu, K_t and the drags vary from gearbox to gearbox: a measured or catalogue source: does not exempt them; nor
    does a datasheet give the output's inertia; the rig file's free: list adds to the set, --free replaces it; the
    geometry is never in the default set."""
    fitted, why = default_refit(None)
    assert fitted == [*STANDARD_REFIT, "gearbox.gear_inertia"] and "whatever the provenance" in why
    assert not any(name.startswith("gearbox.") and "inertia" not in name for name in fitted)
    document = yaml.safe_load(Path(load_rig().source).read_text())
    node = document["drive_motor"]["torque_constant"]
    node.pop("assumption")
    node["source"] = "measured on this rig"
    document["load_motor"] = dict(document["load_motor"]) if isinstance(document["load_motor"], dict) else None
    document["free"] = ["load_motor.viscous_drag"]
    (tmp_path / "measured.yaml").write_text(yaml.safe_dump(document))
    fitted, why = default_refit(tmp_path / "measured.yaml")
    assert fitted == [*STANDARD_REFIT, "gearbox.gear_inertia", "load_motor.viscous_drag"] and "free: list" in why
    assert default_refit(None, ["friction.scale"]) == (["friction.scale"], "--free")


def test_a_friction_parameter_the_model_does_not_read_is_refused(record, tmp_path, capsys) -> None:
    """Under the constant friction model friction.scale is dead: asking to fit it is one line and exit 2."""
    csv, _declared = record
    constant = write_rig_file(tmp_path / "constant.yaml", "nmrv030_constant", {})
    code = main(["--from", str(csv), "--rig", str(constant), "--out", str(tmp_path / "o.yaml"), "--quiet",
                 "--free", "friction.scale"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "friction.mu_constant" in err[0], err
    assert not (tmp_path / "o.yaml").exists()


@pytest.mark.parametrize("args, where", [
    (["--duration", "120"], "--duration"),
    (["--from", "/nonexistent.csv"], "--from"),
    (["--free", "gearbox.lead_angle"], "--free"),
    (["--rig", "/nonexistent.yaml"], "--rig"),
    (["--from", "x.csv", "--resume"], "--from"),
])
def test_bad_input_is_one_line_and_exit_2(args, where, tmp_path) -> None:
    done = subprocess.run([str(find_executable("identify")), "--out", str(tmp_path / "o.yaml"), "--quiet", *args],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"identify: {where}: "), lines
    assert not (tmp_path / "o.yaml").exists()


def test_help_explains_every_option() -> None:
    text = subprocess.run([str(find_executable("identify")), "--help"], capture_output=True, text=True).stdout
    for option in ("--out", "--rig", "--free", "--from", "--duration", "--record", "--resume", "--start-timeout",
                   "--quiet"):
        assert option in text
    assert np.all([len(line) < 130 for line in text.splitlines()])
