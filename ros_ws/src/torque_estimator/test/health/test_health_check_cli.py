"""`health_check --from`: recorded runs of the simulated rig in, the trend appended, the verdict out; bad input is
one line and exit code 2, and loses nothing."""
from __future__ import annotations

import numpy as np
import pytest

from worm_model.health.record import read_trend
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.schema import write_rig_csv
from torque_estimator.health.health_check import build_parser, main
from torque_estimator.health.reference import reference_run
from torque_estimator.health.study import GEARBOX_EFFECTS
from torque_estimator.identification.excitation import Ramp
from torque_estimator.identification.simulated import record_on_simulator

RIG = load_rig()
SETTINGS = "format: worm_gearbox_health_settings\nversion: 1\nlimits: {baseline_checks: 1}\n"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two checks of one simulated gearbox at 35 degC: as new, then with mu 25 % up (the wear effect)."""
    folder = tmp_path_factory.mktemp("runs")
    out = []
    for name, hours in (("new", 0.0), ("worn", 2500.0)):
        effects = {**GEARBOX_EFFECTS, "oil_temperature": {**GEARBOX_EFFECTS["oil_temperature"], "initial": 35.0},
                   "wear": {**GEARBOX_EFFECTS["wear"], "hours": hours}}
        data = record_on_simulator(RIG, reference_run(RIG), effects=effects, seed=3)
        data.temperature = np.full(len(data), 35.0)
        write_rig_csv(folder / f"{name}.csv", data)
        out.append(folder / f"{name}.csv")
    settings = folder / "settings.yaml"
    settings.write_text(SETTINGS)
    return out + [settings]


def test_help_explains_every_option(capsys) -> None:
    with pytest.raises(SystemExit) as done:
        main(["--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    for action in build_parser()._actions:
        for option in action.option_strings:
            assert option in text
        assert action.help, action.option_strings


def test_two_checks_a_baseline_and_a_worn_gearbox(runs, tmp_path, capsys) -> None:
    new, worn, settings = runs
    trend = tmp_path / "gearbox.jsonl"
    assert main(["--trend", str(trend), "--from", str(new), "--settings", str(settings), "--hours", "100"]) == 0
    out = capsys.readouterr().out
    assert "baseline: check 1 of 1" in out and out.strip().splitlines()[-1].startswith(
        "health_check: level=OK mu_change=n/a (baseline)")
    assert "backlash" in out and "(measured)" in out
    plot = tmp_path / "trend.png"
    assert main(["--trend", str(trend), "--from", str(worn), "--settings", str(settings), "--hours", "2600",
                 "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    last = out.strip().splitlines()[-1]
    assert last.startswith("health_check: level=ERROR mu_change=+2"), last  # +25 %
    assert "[ERROR]" in out and plot.stat().st_size > 10_000
    records = read_trend(trend).records
    assert [r.hours for r in records] == [100.0, 2600.0] and records[1].level == "ERROR"
    # --dry-run: the verdict, nothing written
    before = trend.read_bytes()
    assert main(["--trend", str(trend), "--from", str(worn), "--settings", str(settings), "--dry-run"]) == 0
    assert "dry run: not written" in capsys.readouterr().out and trend.read_bytes() == before


def _bad(argv, capsys) -> str:
    try:
        code = main(argv)
    except SystemExit as done:
        code = done.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_bad_input_is_one_line_and_exit_2(runs, tmp_path, capsys) -> None:
    new, _worn, _settings = runs
    trend = tmp_path / "t.jsonl"
    assert "--trend" in _bad(["--from", str(new)], capsys)
    assert "no_such.csv" in _bad(["--trend", str(trend), "--from", str(tmp_path / "no_such.csv")], capsys)
    assert "--loads" in _bad(["--trend", str(trend), "--loads", "0.5,2"], capsys)
    assert "--record" in _bad(["--trend", str(trend), "--from", str(new), "--record", str(tmp_path / "r.csv")], capsys)
    picture = tmp_path / "mine.png"
    picture.write_bytes(b"a user's picture")
    assert "--plot" in _bad(["--trend", str(trend), "--from", str(new), "--plot", str(picture)], capsys)
    assert picture.read_bytes() == b"a user's picture"
    damaged = tmp_path / "damaged.jsonl"
    damaged.write_text('{"format": "worm_gearbox_health_trend", "version": 1, "gearbox": "g"}\n{"date": 3}\n')
    assert "damaged.jsonl: line 2" in _bad(["--trend", str(damaged), "--from", str(new)], capsys)
    assert damaged.read_text().endswith('{"date": 3}\n')  # nothing lost
    ramp = tmp_path / "ramp.csv"
    write_rig_csv(ramp, record_on_simulator(RIG, (Ramp(2.0, 0.0, 300.0, 0.0, 0.2),), seed=1))
    assert "steady constant-speed point" in _bad(["--trend", str(trend), "--from", str(ramp)], capsys)
    assert not trend.exists()
