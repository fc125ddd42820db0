"""`estimate`: an estimator over a log as estimator_node runs it; figures only from the log and the files given."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData, write_rig_csv
from worm_model.ros.ament import find_executable

from torque_estimator.offline.estimate import LogEstimate, figures, main
from torque_estimator.evaluation.scenario import DEMO_SCENARIO
from torque_estimator.identification.excitation import Ramp
from torque_estimator.identification.simulated import record_on_simulator

RIG = load_rig()
LINE = re.compile(r"^estimate: method=(\w+) mae_pct=([\d.]+) max_pct=([\d.]+) steady_points=(\d+) "
                  r"transient_rms_pct=([\d.]+) trusted_pct=([\d.]+)$")


@pytest.fixture(scope="module")
def log(tmp_path_factory) -> Path:
    """The demo's six segments (load steps into every mode, both directions) on the simulated rig."""
    timeline = [Ramp(s.duration, s.speed, s.speed, s.load, s.load, s.label) for s in DEMO_SCENARIO]
    path = tmp_path_factory.mktemp("estimate") / "demo.csv"
    write_rig_csv(path, record_on_simulator(RIG, timeline, seed=2))
    return path


@pytest.mark.parametrize("method", ["extended_model", "observer"])
def test_model_based_methods_need_no_calibration(method, log, tmp_path, capsys) -> None:
    out = tmp_path / "est.csv"
    assert main([str(log), "--method", method, "--out", str(out), "--quiet"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    match = LINE.match(last)
    assert match and match.group(1) == method, last
    mae, worst, steady = float(match.group(2)), float(match.group(3)), int(match.group(4))
    assert steady >= 15 and mae < 1.5 and worst < 5.0, last  # the model is the simulator's (measured 0.42 / 1.74 %)
    written = read_rig_data(out)  # still rig data: the estimate columns are extra
    assert set(written.ignored_columns) == {"tau_estimate", "tau_estimate_uncertainty", "estimate_flags"}


def test_momentum_needs_no_voltage(log, tmp_path, capsys) -> None:
    """The momentum observer reads current and speed (and the angle): a log without a voltage_drive column is
    enough for it, with the figures of the same log with the column (measured on the demo's log: 0.37 / 1.30 %,
    19 steady points with a trusted estimate), while the observer refuses it."""
    data = read_rig_data(log)
    bare = MeasuredData(**{c: getattr(data, c) for c in data.names if c != "voltage_drive"})
    path = tmp_path / "no_voltage.csv"
    write_rig_csv(path, bare)
    assert "voltage_drive" not in path.read_text(encoding="utf-8").splitlines()[0] and bare.voltage_drive is None
    assert main([str(path), "--method", "momentum", "--out", str(tmp_path / "m.csv"), "--quiet"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    match = LINE.match(last)
    assert match and match.group(1) == "momentum"
    assert main([str(log), "--method", "momentum", "--out", str(tmp_path / "v.csv"), "--quiet"]) == 0
    assert capsys.readouterr().out.strip().splitlines()[-1] == last
    assert int(match.group(4)) >= 15 and float(match.group(2)) < 1.5 and float(match.group(3)) < 5.0, match.group(0)
    assert main([str(path), "--method", "observer", "--out", str(tmp_path / "o.csv"), "--quiet"]) == 2
    assert "needs the voltage_drive column" in capsys.readouterr().err


def test_figures_come_from_the_log_alone(log, tmp_path, capsys) -> None:
    """Recomputed from the written CSV alone, the figures are the printed ones; a log whose tau_load is off
    by 0.02 N m scores worse by that much: the reference is the log's, not the simulator's truth."""
    out = tmp_path / "est.csv"
    main([str(log), "--method", "extended_model", "--out", str(out), "--quiet"])
    printed = LINE.match(capsys.readouterr().out.strip().splitlines()[-1])
    table = np.genfromtxt(out, delimiter=",", names=True)
    data = read_rig_data(out)
    again = figures(data, LogEstimate(table["tau_estimate"], table["tau_estimate_uncertainty"],
                                      table["estimate_flags"].astype(int)), RIG)
    assert f"{again.mae_pct:.2f}" == printed.group(2) and f"{again.max_pct:.2f}" == printed.group(3)
    shifted = read_rig_data(log)
    shifted = MeasuredData(**{c: getattr(shifted, c) for c in shifted.names if c != "tau_load"},
                           tau_load=shifted.tau_load + 0.02)
    write_rig_csv(tmp_path / "shifted.csv", shifted)
    main([str(tmp_path / "shifted.csv"), "--method", "extended_model", "--out", str(tmp_path / "s.csv"), "--quiet"])
    worse = LINE.match(capsys.readouterr().out.strip().splitlines()[-1])
    assert float(worse.group(2)) > float(printed.group(2)) + 2.0


@pytest.mark.parametrize("args, where", [
    (["--method", "knn"], "--calibration"),
    (["--method", "extended_model", "--model-file", "/nonexistent.yaml"], "--model-file"),
    (["--method", "extended_model", "--out", "/nonexistent/x.csv"], "--out"),
])
def test_bad_input_is_one_line_and_exit_2(args, where, log) -> None:
    done = subprocess.run([str(find_executable("estimate")), str(log), "--quiet", *args], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"estimate: {where}"), lines


def test_a_missing_log_is_named(tmp_path) -> None:
    done = subprocess.run([str(find_executable("estimate")), str(tmp_path / "none.csv"), "--method", "observer"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and done.stderr.startswith("estimate: log: ") and "none.csv" in done.stderr
