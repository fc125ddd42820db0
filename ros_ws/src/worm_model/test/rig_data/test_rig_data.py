"""The worm_rig_data CSV schema (worm_model.rig_data.schema): reader, writer, errors naming file, line and column.

The bag side of the schema (bag export/import) is tested in worm_rig_driver's test_rig_csv.py
and worm_rig_driver's test_bag_cli.py; the residual tool's use of it in test_residuals.py.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from worm_model.rig_data.schema import MeasuredData, read_rig_csv, split_runs, write_rig_csv
from worm_model.errors import RigDataError

HEADER = "t,current_drive,omega_worm,theta_worm,tau_load\n"


def write(tmp_path: Path, text: str | bytes) -> Path:
    path = tmp_path / "data.csv"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def test_columns_in_any_order_unknown_ignored_empty_optional_cell_is_nan(tmp_path: Path) -> None:
    path = write(tmp_path, "tau_load,extra,t,omega_worm,current_drive,theta_worm,temperature,theta_gear\n"
                           "0.5,a,0.000,10,1.25,0.00,,\n0.5,b,0.001,10.5,1.5,0.01,41.5,\n0.5,c,0.002,10,1.5,0.02,42,\n")
    data = read_rig_csv(path)
    assert data.names == ["t", "current_drive", "omega_worm", "theta_worm", "tau_load", "temperature"]
    assert data.ignored_columns == ("extra",)
    assert data.omega_worm.tolist() == [10.0, 10.5, 10.0]
    np.testing.assert_array_equal(data.theta_worm, [0.0, 0.01, 0.02])
    assert math.isnan(data.temperature[0]) and data.temperature[1:].tolist() == [41.5, 42.0]
    assert data.theta_gear is None  # a column without a single value is an absent one
    assert data.source == str(path)


@pytest.mark.parametrize(("text", "line", "column", "words"), [
    ("t,current_drive,omega_worm,tau_load\n0,1,1,1\n", 1, "theta_worm", "missing required column"),
    ("t,t,current_drive,omega_worm,theta_worm,tau_load\n", 1, "t", "duplicate column"),
    ("", 1, "", "empty file"),
    (HEADER, 0, "", "no data rows"),
    (HEADER + "0,1,1,0,0.1\n0.001,1,abc,0,0.1\n", 3, "omega_worm", "'abc' is not a number"),
    (HEADER + "0,1,1,0,0.1\n0.001,,1,0,0.1\n", 3, "current_drive", "empty cell in a required column"),
    (HEADER + "0,1,1,0,0.1\n0.001,1,1,0,nan\n", 3, "tau_load", "'nan' is not finite"),
    (HEADER + "0,1,1,0,0.1\n0.001,1,1,0,inf\n", 3, "tau_load", "'inf' is not finite"),
    (HEADER + "0,1,1,0,0.1\n0.002,1,1,0,0.1\n0.001,1,1,0,0.1\n", 4, "t", "increase strictly"),
    (HEADER + "0,1,1,0,0.1\n0,1,1,0,0.1\n", 3, "t", "time 0.0 is not after"),
    (HEADER + "0,1,1,0,0.1\n0.001,1,1,0\n", 3, "", "4 cells, the header has 5"),
    (HEADER.encode() + b"0,1,1,0,0.1\n0.001,1,\xff,0,0.1\n", 0, "", "not UTF-8 text"),
])
def test_bad_csv_names_file_line_and_column(tmp_path: Path, text: str | bytes, line: int, column: str,
                                            words: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(RigDataError) as err:
        read_rig_csv(path)
    assert (err.value.line, err.value.column) == (line, column)
    assert str(err.value).startswith(f"{path}: ")
    assert words in str(err.value)
    if column:
        assert f"line {line}, column '{column}'" in str(err.value)


def test_unreadable_and_unwritable_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(RigDataError, match="cannot read"):
        read_rig_csv(tmp_path / "missing.csv")
    data = MeasuredData(t=[0.0, 1e-3], current_drive=[1.0, 1.0], omega_worm=[2.0, 2.0], theta_worm=[0.0, 0.002],
                        tau_load=[0.1, 0.1])
    with pytest.raises(RigDataError, match="cannot write") as err:
        write_rig_csv(tmp_path / "no_dir" / "out.csv", data)
    assert err.value.source == str(tmp_path / "no_dir" / "out.csv")


def test_write_read_is_bit_exact_and_read_write_gives_the_same_file(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    n = 200
    data = MeasuredData(t=np.arange(n) / 1000.0, current_drive=rng.normal(size=n),
                        omega_worm=rng.normal(size=n) * 100, theta_worm=np.cumsum(rng.random(n)),
                        tau_load=rng.normal(size=n), theta_gear=rng.normal(size=n) * 1e-7)
    data.theta_gear[5] = math.nan
    path = tmp_path / "out.csv"
    write_rig_csv(path, data)
    back = read_rig_csv(path)
    assert back.names == data.names
    for name in data.names:
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name))  # bit-exact, NaN where NaN
    assert path.read_text().splitlines()[6].split(",")[-1] == ""  # NaN as an empty cell
    again = tmp_path / "again.csv"
    write_rig_csv(again, back)
    assert again.read_text() == path.read_text()


def test_runs_split_at_gaps_and_survive_subset() -> None:
    t = np.concatenate([np.arange(10) * 1e-3, 1.0 + np.arange(10) * 1e-3])
    assert split_runs(t).tolist() == [0] * 10 + [1] * 10
    data = MeasuredData(t=t, current_drive=np.ones(20), omega_worm=np.ones(20), theta_worm=t, tau_load=np.zeros(20))
    assert data.run.tolist() == split_runs(t).tolist()
    assert data.subset(np.arange(5, 15)).run.tolist() == [0] * 5 + [1] * 5
    with pytest.raises(RigDataError, match=r"column 'tau_load': has shape \(3,\), expected \(20,\)"):
        MeasuredData(t=t, current_drive=np.ones(20), omega_worm=np.ones(20), theta_worm=t, tau_load=np.zeros(3))
