"""The resume rule both journals keep: the first differing setting, by its dotted path, with both values."""
from __future__ import annotations

import numpy as np
import pytest

from torque_estimator.calibration.journal import CalibrationJournal
from torque_estimator.errors import JournalError
from torque_estimator.session.resume import normalised, settings_problem

SETTINGS = {"grid": {"speeds": (50.0, 100.0), "torques": np.array([0.0, 0.1])}, "source": "simulator", "seed": 1}


def test_equal_settings_resume_whatever_their_python_types() -> None:
    stored = normalised(SETTINGS)
    assert stored["grid"]["speeds"] == [50.0, 100.0] and stored["grid"]["torques"] == [0.0, 0.1]
    assert settings_problem(stored, normalised({**SETTINGS, "grid": {"speeds": [50.0, 100.0],
                                                                        "torques": [np.float64(0.0), 0.1]}})) is None


@pytest.mark.parametrize(("change", "named"), [
    ({"seed": 2}, "settings.seed is 1 there, 2 now"),
    ({"grid": {"speeds": (50.0, 120.0), "torques": (0.0, 0.1)}}, "settings.grid.speeds is [50.0, 100.0] there, "
                                                                 "[50.0, 120.0] now"),
    ({"extra": True}, "settings.extra is '(absent)' there, True now"),
])
def test_the_first_difference_is_named_with_both_values(change: dict, named: str) -> None:
    assert settings_problem(normalised(SETTINGS), normalised({**SETTINGS, **change})) == named


def test_the_calibration_journal_refuses_other_settings_in_the_same_words(tmp_path) -> None:
    path = tmp_path / "db.json.partial"
    journal = CalibrationJournal.open(path, SETTINGS, 4, resume=False)
    journal.save()
    with pytest.raises(JournalError, match="--resume"):
        CalibrationJournal.open(path, SETTINGS, 4, resume=False)
    with pytest.raises(JournalError, match="other settings: settings.seed is 1 there, 2 now"):
        CalibrationJournal.open(path, {**SETTINGS, "seed": 2}, 4, resume=True)
    assert CalibrationJournal.open(path, SETTINGS, 4, resume=True).resumed == 1
