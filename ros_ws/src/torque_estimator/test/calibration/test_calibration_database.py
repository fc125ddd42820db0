"""Calibration database: validation, subset, and the versioned JSON file."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

from torque_estimator.estimation.database import (FORMAT, POINT_COLUMNS, UNITS, VERSION, CalibrationDatabase,
    load_database, save_database)
from torque_estimator.errors import CalibrationError


def small_database() -> CalibrationDatabase:
    """2 speeds × 3 torques × 2 directions; one point without a spread (NaN)."""
    speeds, torques = np.array([10.0, 20.0]), np.array([-0.5, 0.0, 1.5])
    sigma, speed_i, torque_i = (a.ravel() for a in np.meshgrid([1, -1], [0, 1], [0, 1, 2], indexing="ij"))
    omega, tau = sigma * speeds[speed_i], sigma * torques[torque_i]
    n = len(omega)
    tau_std = np.full(n, 0.01)
    tau_std[3] = np.nan
    return CalibrationDatabase(
        omega_worm=omega + 0.1, current_drive=0.3 * sigma + tau / 3, tau_load=tau,
        omega_std=np.full(n, 0.2), current_std=np.full(n, 1 / 3), tau_std=tau_std,
        samples=np.arange(n) + 50, speed_setpoints=speeds, torque_setpoints=torques,
        setpoint_index=np.column_stack((speed_i, torque_i)),
        rig={"name": "paper", "ratio": [1, 30], "K_t": 0.05}, created="2024-05-01T12:00:00+00:00",
        steady_state={"window_s": 2.0, "max_speed_std": 0.5}, notes="synthetic")


def assert_same(a: CalibrationDatabase, b: CalibrationDatabase) -> None:
    for name in [*POINT_COLUMNS, "speed_setpoints", "torque_setpoints"]:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert getattr(a, name).dtype == getattr(b, name).dtype, name
    assert (a.rig, a.created, a.steady_state, a.notes) == (b.rig, b.created, b.steady_state, b.notes)


def test_round_trip_is_exact_including_nan(tmp_path: Path) -> None:
    db = small_database()
    path = tmp_path / "calibration.json"
    save_database(db, path)
    loaded = load_database(path)
    assert_same(loaded, db)
    assert np.isnan(loaded.tau_std[3])
    assert loaded.samples.dtype.kind == "i" and loaded.setpoint_index.shape == (12, 2)


def test_file_is_the_documented_json(tmp_path: Path) -> None:
    path = tmp_path / "calibration.json"
    save_database(small_database(), path)
    text = path.read_text(encoding="utf-8")
    assert "NaN" not in text
    doc = json.loads(text)
    assert (doc["format"], doc["version"]) == (FORMAT, VERSION)
    assert doc["units"] == UNITS and doc["units"]["tau_load"] == "N·m"
    assert set(doc["points"]) == set(POINT_COLUMNS) and doc["points"]["tau_std"][3] is None
    assert doc["grid"]["torque_setpoints"] == [-0.5, 0.0, 1.5]
    assert {"created", "rig", "steady_state", "notes"} <= set(doc)


def test_interrupted_write_keeps_the_old_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "calibration.json"
    save_database(small_database(), path)
    before = path.read_bytes()

    def crash(fd: int) -> None:
        raise OSError("disk gone")

    monkeypatch.setattr(os, "fsync", crash)
    smaller = small_database().subset(np.arange(4))
    with pytest.raises(OSError, match="disk gone"):
        save_database(smaller, path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["calibration.json"]


DELETE = object()


def edit(doc: dict[str, Any], where: str, value: Any) -> None:
    """Set (or with value DELETE, remove) doc[a][b] for where = 'a.b'."""
    *parents, key = where.split(".")
    for parent in parents:
        doc = doc[parent]
    if value is DELETE:
        del doc[key]
    else:
        doc[key] = value


def _with_point(column: str, index: int, value: Any) -> Callable[[dict[str, Any]], None]:
    def change(doc: dict[str, Any]) -> None:
        doc["points"][column][index] = value
    return change


BROKEN: dict[str, tuple[Callable[[dict[str, Any]], None], str]] = {
    "wrong format": (lambda d: edit(d, "format", "rosbag"), r"'format' is 'rosbag'"),
    "future version": (lambda d: edit(d, "version", 2), r"unsupported version 2"),
    "missing point column": (lambda d: edit(d, "points.tau_std", DELETE), r"missing field 'points\.tau_std'"),
    "missing grid": (lambda d: edit(d, "grid.torque_setpoints", DELETE), r"'grid\.torque_setpoints'"),
    "missing rig": (lambda d: edit(d, "rig", DELETE), r"missing field 'rig'"),
    "missing created": (lambda d: edit(d, "created", DELETE), r"missing field 'created'"),
    "bad created": (lambda d: edit(d, "created", "yesterday"), r"'created'"),
    "wrong unit": (lambda d: edit(d, "units.current_drive", "mA"), r"'units\.current_drive' is 'mA'"),
    "short column": (lambda d: d["points"]["current_drive"].pop(), r"'points\.current_drive' has 11 values"),
    "nan mean": (_with_point("tau_load", 5, None), r"'points\.tau_load' is not finite at point 5"),
    "text in column": (_with_point("omega_worm", 0, "fast"), r"'points\.omega_worm'"),
    "negative spread": (_with_point("current_std", 7, -1.0), r"'points\.current_std' .* at point 7"),
    "fractional count": (_with_point("samples", 2, 2.5), r"'points\.samples'"),
    "index off grid": (_with_point("setpoint_index", 9, [0, 3]), r"'points\.setpoint_index' .* at point 9"),
}


@pytest.mark.parametrize("case", BROKEN, ids=list(BROKEN))
def test_broken_file_is_rejected_naming_file_and_field(tmp_path: Path, case: str) -> None:
    path = tmp_path / "calibration.json"
    save_database(small_database(), path)
    doc = json.loads(path.read_text(encoding="utf-8"))
    change, message = BROKEN[case]
    change(doc)
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(CalibrationError, match=message) as error:
        load_database(path)
    assert str(path) in str(error.value)


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.json"
    with pytest.raises(CalibrationError, match=f"calibration file {path}: cannot read: no such file"):
        load_database(path)


def test_not_json_gives_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "calibration.json"
    path.write_text('{"format": "worm_torque_calibration",\n "version": 1,,\n}', encoding="utf-8")
    with pytest.raises(CalibrationError, match="line 2, column 15: not valid JSON"):
        load_database(path)


def test_construction_validates_and_freezes() -> None:
    db = small_database()
    with pytest.raises(CalibrationError, match=r"'points\.tau_load' has 11 values, expected 12"):
        CalibrationDatabase(**{**vars(db), "tau_load": db.tau_load[:-1]})
    with pytest.raises(ValueError):
        db.tau_load[0] = 1.0


def test_subset_len_and_torque_range() -> None:
    db = small_database()
    assert len(db) == 12 and db.torque_range == pytest.approx(3.0)
    positive = db.subset(db.omega_worm > 0)
    assert len(positive) == 6 and positive.torque_range == pytest.approx(2.0)
    assert_same(db.subset(np.arange(12)), db)
    np.testing.assert_array_equal(db.subset([0, 5]).tau_load, db.tau_load[[0, 5]])
    assert positive.rig == db.rig
    np.testing.assert_array_equal(positive.speed_setpoints, db.speed_setpoints)
