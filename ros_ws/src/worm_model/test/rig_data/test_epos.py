"""EPOS Studio exports (worm_model.rig_data.epos): the shipped T-RO files as they come, dirty rows, bad files.

The real files are the 48 exports of worm_model/data/tro2021 (SOURCE.md); the made-up ones below
are each one of them with one thing broken.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import worm_model
from worm_model.rig_data.epos import (EposSettings, epos_files, hanging_load, is_epos_export, read_epos,
    read_epos_folder, steady_point, to_measured)
from worm_model.errors import DirtyRowsError, RigDataError
from worm_model.rig_data.reader import read_rig_data
from worm_model.physics.parameters import load_rig

DRIVE = Path(worm_model.__file__).resolve().parent / "data" / "tro2021" / "driveNo3"
STEADY = DRIVE / "steady_state" / "0.096kg"
RIG = Path(worm_model.__file__).resolve().parent / "data" / "tro2021_worm_rig.yaml"
#: 18.84 mN m, what the T-RO scripts hang on the gear (9.812 m/s^2 x 0.096 kg x 0.02 m)
LOAD = 9.812 * 0.096 * 0.02
NOMINAL_CURRENT = 9.84 / 4.78


def test_the_shipped_data_is_there_with_its_licence_and_source() -> None:
    assert len(epos_files(STEADY)) == 46 and len(epos_files(DRIVE / "start_stop")) == 2
    assert "MIT License" in (DRIVE.parent / "LICENSE").read_text()
    source = (DRIVE.parent / "SOURCE.md").read_text()
    assert "c3b758b4343db54f1020e59961e07c5425b5eea2" in source and "RViMLab/TRO2021-Dynamic-Modelling" in source
    names = [p.name for p in epos_files(STEADY)]
    assert names[:4] == ["1.csv", "2.csv", "4.csv", "6.csv"]  # natural order, 2 before 10


def test_header_and_units_of_a_real_export() -> None:
    export = read_epos(STEADY / "10.csv")
    header = export.header
    assert header.recorded_samples == 500 and header.date == "2020-07-06 15:47:42"
    assert header.sampling_period == pytest.approx(0.0512)
    assert header.channels == (("Velocity actual value averaged", "rpm"), ("Torque actual value averaged", "%"))
    assert len(export) == 500 and export.dirty == () and export.notes == ()
    # first row of the file: 0.000;-15;-10.6
    assert export.t[0] == 0.0 and export.t[1] == pytest.approx(0.0512)
    assert export.values["velocity"][0] == pytest.approx(-15 * 2 * math.pi / 60)
    assert export.values["torque"][0] == pytest.approx(-0.106)
    point = steady_point(export)
    assert point.speed * 30 / math.pi == pytest.approx(-10.02, abs=0.005)
    assert 100 * point.torque == pytest.approx(-9.690, abs=0.0005)
    assert 100 * point.torque_sd == pytest.approx(1.75, abs=0.005)


def test_the_dirty_rows_are_refused_naming_file_and_line() -> None:
    with pytest.raises(DirtyRowsError) as err:
        read_epos(STEADY / "1.csv")
    text = str(err.value)
    assert text.startswith(f"{STEADY / '1.csv'}: line 15: stray text 'was -8.9' after the values; ")
    assert "-1200 % is a spike" in text and "1 dirty row(s) in this file: refused" in text
    assert "\n" not in text
    with pytest.raises(DirtyRowsError) as err:
        read_epos_folder(STEADY)
    assert len(err.value.rows) == 3 and "3 dirty row(s) in 3 of the folder's 46 files" in str(err.value)


def test_skipping_dirty_rows_reports_each_and_counts_them() -> None:
    export = read_epos(STEADY / "n1.csv", skip_bad_rows=True)
    assert len(export) == 499 and [str(r) for r in export.dirty] == [
        f"{STEADY / 'n1.csv'}: line 15: stray text 'was 22.1' after the values; Torque actual value averaged -400 % "
        "is a spike: 950 x the row-to-row spread (0.445 %) away from its neighbour(s) 22.4"]
    assert export.lines[0] == 16  # the first row kept is line 16
    assert "re-saved by a spreadsheet" in export.notes[0]
    data = read_rig_data(STEADY, epos=EposSettings(load_torque=LOAD, nominal_current=NOMINAL_CURRENT,
                                                   skip_bad_rows=True))
    assert data.skipped == {"dirty rows": 3} and len(data) == 46 * 500 - 3
    assert sum(note.startswith("skipped: ") for note in data.notes) == 3


def test_the_spike_threshold_against_the_real_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    """The largest excursion of a real row of the 48 files is 7 row-to-row spreads (between 6.5 and 7.5); the
    edited values are 950-2008 spreads; the sampling periods run from 6.4 to 256 ms."""
    import worm_model.rig_data.epos as epos

    files = epos_files(STEADY) + epos_files(DRIVE / "start_stop")
    periods = [read_epos(p, skip_bad_rows=True).header.sampling_period for p in files]
    assert (min(periods), max(periods)) == pytest.approx((0.0064, 0.256))
    edited = sorted(int(str(r).split(" is a spike: ")[1].split(" x")[0]) for p in files
                    for r in read_epos(p, skip_bad_rows=True).dirty)
    assert edited == [950, 1775, 2008]
    monkeypatch.setattr(epos, "SPIKE_FACTOR", 7.5)
    assert sum(len(read_epos(p, skip_bad_rows=True).dirty) for p in files) == 3
    monkeypatch.setattr(epos, "SPIKE_FACTOR", 6.5)
    assert sum(len(read_epos(p, skip_bad_rows=True).dirty) for p in files) > 3


def test_real_transients_are_not_spikes() -> None:
    """The start-stop runs jump from 0 to +-200 rpm in two samples: steps, not spikes; and a quoted trigger line."""
    for name in ("10.csv", "200.csv"):
        export = read_epos(DRIVE / "start_stop" / name)
        assert export.dirty == () and len(export) == 500
    for path in epos_files(STEADY):  # every real row of the 46 files but the three edited ones is clean
        assert len(read_epos(path, skip_bad_rows=True).dirty) == (path.name in ("1.csv", "2.csv", "n1.csv"))


def test_as_rig_data_one_run_per_file_si_units_and_the_given_load() -> None:
    exports = [read_epos(STEADY / "10.csv"), read_epos(STEADY / "n10.csv")]
    data = to_measured(exports, EposSettings(load_torque=LOAD, nominal_current=NOMINAL_CURRENT), "two")
    assert len(data) == 1000 and data.run.tolist() == [0] * 500 + [1] * 500
    assert data.run_sources == (str(STEADY / "10.csv"), str(STEADY / "n10.csv"))
    np.testing.assert_allclose(data.tau_load, LOAD)
    assert data.current_drive[0] == pytest.approx(-0.106 * NOMINAL_CURRENT)
    assert data.t[500] == pytest.approx(data.t[499] + 1.0)  # runs 1 s apart
    assert np.all(np.diff(data.t) > 0)
    # no position channel: theta is the velocity integrated, and the data says so
    assert data.theta_worm[1] == pytest.approx(0.5 * (data.omega_worm[0] + data.omega_worm[1]) * 0.0512)
    assert any("theta_worm: the velocity integrated" in note for note in data.notes)
    with pytest.raises(RigDataError, match="does not carry the load"):
        read_rig_data(STEADY / "10.csv")
    with pytest.raises(RigDataError, match="what 100 % is"):
        read_rig_data(STEADY / "10.csv", epos=EposSettings(load_torque=LOAD))


def test_the_envelope_check_names_the_file_of_the_run(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text(_good())
    (tmp_path / "b.csv").write_text(_good().replace(";-1", ";-20000", 8))  # -200000 rpm: the motor cannot
    with pytest.raises(RigDataError) as err:  # the one reader checks the magnitudes against the rig
        read_rig_data(tmp_path, rig=load_rig(RIG), epos=EposSettings(load_torque=LOAD, nominal_current=NOMINAL_CURRENT))
    assert str(err.value).startswith(f"{tmp_path / 'b.csv'}: line 11, column 'omega_worm': ")


def test_hanging_load_and_the_position_channel(tmp_path: Path) -> None:
    assert hanging_load(0.096, 0.02, 9.812) == pytest.approx(0.018839, abs=1e-6)
    rows = "".join(f"{k * 10.0:.3f};{60 + k};{k * 10};{250 + k}\n" for k in range(5))
    path = tmp_path / "pos.csv"
    path.write_text(_header(5, 10.0, "Velocity actual value;Position actual value;Current actual value", "rpm;qc;mA")
                    + rows)
    data = read_rig_data(path, epos=EposSettings(load_torque=0.0, counts_per_turn=4096.0))
    assert data.theta_worm.tolist() == pytest.approx([2 * math.pi * k * 10 / 4096 for k in range(5)])
    assert data.current_drive.tolist() == pytest.approx([0.25 + 0.001 * k for k in range(5)])  # mA -> A


def _header(samples: int, period_ms: float, names: str, units: str) -> str:
    return (f"Date:;2020-07-06 15:47:42\nFirmware Version:;0x0120;0x6150;0x0000;0x0000\nEPOS Studio Version:;3.6.1.0\n"
            f"Index:;0x30D3;0x30D2;0x0000;0x0000\nSubindex:;0x01;0x01;0x00;0x00\nMax. samples:;{samples}\n"
            f"Recorded samples:;{samples}\nSampling period:;{period_ms:.3f}\n;{names}\nms;{units}\n")


def _good(n: int = 8) -> str:
    rows = "".join(f"{k * 51.2:.3f};{-10 - k % 3};{-9.6 - 0.1 * (k % 4):.1f}\n" for k in range(n))
    return _header(n, 51.2, "Velocity actual value averaged;Torque actual value averaged", "rpm;%") + rows


@pytest.mark.parametrize(("change", "line", "words"), [
    (lambda t: t.replace("\n102.400;-12;-9.8\n", "\n102.400;-12;-9.8;\n"), 13, "trailing separator ';'"),
    (lambda t: t.replace("\n102.400;-12;-9.8\n", "\n102.400;-12;-9.8 was -9.6\n"), 13,
     "'-9.8 was -9.6' is not a number (%)"),
    (lambda t: t.replace("\n102.400;-12;-9.8\n", "\n102.400;-12\n"), 13, "2 cells, the header has 3"),
    (lambda t: t.replace("\n102.400;-12;-9.8\n", "\n51.200;-12;-9.8\n"), 13, "time 51.2 ms is not after"),
    (lambda t: t.replace("\n153.600;-10;-9.9\n", "\n153.600;-10;-1200\n"), 14, "-1200 % is a spike"),
    (lambda t: t.replace("\n153.600;-10;-9.9\n", "\n153.600;900;-9.9\n"), 14, "900 rpm is a spike"),
])
def test_made_up_dirty_rows(tmp_path: Path, change, line: int, words: str) -> None:
    path = tmp_path / "x.csv"
    text = _good()
    changed = change(text)
    assert changed != text
    path.write_text(changed)
    with pytest.raises(DirtyRowsError) as err:
        read_epos(path)
    assert str(err.value).startswith(f"{path}: line {line}: ") and words in str(err.value)
    export = read_epos(path, skip_bad_rows=True)
    assert len(export) == 7 and [r.line for r in export.dirty] == [line]


@pytest.mark.parametrize(("content", "words"), [
    (lambda t: "\n".join(t.split("\n")[:14]).encode(), "truncated: the header says 8 recorded samples"),
    (lambda t: t.replace(";", ",").encode(), "separated by ',', not ';'"),
    (lambda t: t.replace(";", "\t").encode(), "separated by tabs, not ';'"),
    (lambda t: b"Date:\x00\x01\x02\xff" * 40, "binary data"),
    (lambda t: t.replace("Velocity actual value averaged", "Following error").encode(), "no velocity channel"),
    (lambda t: t.replace("Torque actual value averaged", "Following error").encode(), "no torque or current channel"),
    (lambda t: t.replace("rpm;%", "rpm;Nm").encode(), "in 'Nm': known units"),
    (lambda t: t.replace("Sampling period:;51.200", "Sampling period:;40.000").encode(), "steps by 51.2 ms"),
    (lambda t: t.replace("Recorded samples:;8\n", "").encode(), "'Recorded samples:' missing"),
    (lambda t: t.replace("ms;rpm;%\n", "").encode(), "no unit row"),
])
def test_bad_files_are_one_line_naming_the_file(tmp_path: Path, content, words: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(content(_good()))
    assert is_epos_export(path)  # they start like an export: the EPOS reader refuses them with the reason
    with pytest.raises(RigDataError) as err:
        read_rig_data(path, epos=EposSettings(load_torque=LOAD, nominal_current=1.0))
    assert str(err.value).startswith(str(path)) and words in str(err.value) and "\n" not in str(err.value)


def test_the_load_options_of_the_tools() -> None:
    import argparse

    from worm_model.errors import InputError
    from worm_model.rig_data.epos_options import add_epos_arguments, epos_settings

    parser = argparse.ArgumentParser()
    add_epos_arguments(parser)
    rig = load_rig(RIG)
    hanging = epos_settings(parser.parse_args(["--load-mass", "0.096", "--pulley-radius", "0.02", "--gravity", "9.812",
                                               "--lifting", "negative", "--skip-bad-rows"]), rig)
    assert hanging.load_torque == pytest.approx(-LOAD) and hanging.skip_bad_rows
    assert hanging.nominal_current == pytest.approx(NOMINAL_CURRENT) and hanging.counts_per_turn == 4096
    assert epos_settings(parser.parse_args(["--load-torque", "0.01"]), rig).load_torque == 0.01
    with pytest.raises(InputError, match="not both"):
        epos_settings(parser.parse_args(["--load-torque", "0.01", "--load-mass", "1", "--pulley-radius", "0.1"]), rig)
    with pytest.raises(InputError, match="needs both"):
        epos_settings(parser.parse_args(["--pulley-radius", "0.1"]), rig)
