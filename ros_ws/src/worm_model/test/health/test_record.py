"""The trend file: what is written is read back the same; a damaged file is refused naming its line."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from fixtures.health_runs import check_segments, steady_run

from worm_model.health.blocks import blocks_from_data
from worm_model.health.fit import Temperature, fit_points
from worm_model.health.model import HealthParameters
from worm_model.health.points import steady_points
from worm_model.health.record import CheckRecord, Trend, read_trend, write_trend
from worm_model.errors import TrendError
from worm_model.physics.parameters import load_rig

RIG = load_rig()


@pytest.fixture(scope="module")
def record() -> CheckRecord:
    data = steady_run(RIG, HealthParameters.from_rig(RIG), check_segments(RIG), gap=0.004)
    points = steady_points(blocks_from_data(data, RIG.gearbox.ratio), RIG)
    fit = fit_points(points, RIG, HealthParameters.from_rig(RIG))
    return CheckRecord.from_fit(fit, Temperature(41.0, 0.5, "measured"), "2026-03-01T08:00:00+00:00", None, "test",
                                points)


def test_a_trend_round_trips(tmp_path, record) -> None:
    path = tmp_path / "t.jsonl"
    write_trend(path, Trend("gearbox 7", [record, record]))
    back = read_trend(path)
    assert back.gearbox == "gearbox 7" and len(back) == 2
    again = back.records[1]
    assert again.parameters == record.parameters and again.sigma == record.sigma
    np.testing.assert_array_equal(again.covariance, record.covariance)
    assert math.isnan(again.hours) and again.temperature == record.temperature
    assert again.backlash == record.backlash and again.speeds == record.speeds
    np.testing.assert_array_equal(again.steady_points.torque, record.steady_points.torque)
    assert np.all(np.isnan(again.steady_points.temperature))  # NaN kept (as null)
    assert path.read_text() == back.to_text()


@pytest.mark.parametrize("damage, line, what", [
    (lambda lines: ["not json"] + lines[1:], 1, "not JSON"),
    (lambda lines: [json.dumps({"format": "other"})] + lines[1:], 1, "header"),
    (lambda lines: lines[:1] + [lines[1][:40]], 2, "not JSON"),
    (lambda lines: lines[:1] + [lines[1].replace('{"mu_scale": ', '{"mu_scale": "x", "was": ', 1)], 2,
     "parameters.mu_scale"),
    (lambda lines: lines[:1] + [lines[1].replace('"measured"', '"guessed"')], 2, "temperature"),
])
def test_a_damaged_trend_is_refused_naming_its_line(tmp_path, record, damage, line, what) -> None:
    path = tmp_path / "t.jsonl"
    write_trend(path, Trend("g", [record]))
    path.write_text("\n".join(damage(path.read_text().splitlines())) + "\n")
    with pytest.raises(TrendError) as err:
        read_trend(path)
    assert f"{path}: line {line}" in str(err.value) and what in str(err.value), str(err.value)


def test_a_missing_trend_file_is_one_line(tmp_path) -> None:
    with pytest.raises(TrendError, match="no_such.jsonl"):
        read_trend(tmp_path / "no_such.jsonl")
