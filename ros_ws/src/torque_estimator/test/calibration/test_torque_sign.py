"""A calibration whose torques contradict its currents is refused on load (worm_model.rig_data.plausibility
torque_sign_problem), before any tool runs on it."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from worm_model.physics.parameters import load_rig

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.errors import CalibrationError
from torque_estimator.estimation.database import load_database, save_database
from torque_estimator.evaluation.observer_study import perturbed_rig

RIG = load_rig()


def test_a_flipped_load_cell_is_refused_and_a_wrong_model_is_not(tmp_path: Path) -> None:
    """Made on the simulated rig: accepted as made, refused with every tau_load negated (a load cell wired the
    other way); made on a rig whose mu or K_t is far off the file's: still accepted (a wrong model scales the
    fit, it does not turn it over)."""
    for k, truth in enumerate((RIG, perturbed_rig(RIG, mu=1.6), perturbed_rig(RIG, kt=0.6))):
        db = calibrate_simulated(truth, CalibrationGrid.paper(truth), seed=0)
        save_database(db, tmp_path / f"cal{k}.json")
        assert len(load_database(tmp_path / f"cal{k}.json", RIG)) == len(db)
    db = calibrate_simulated(RIG, CalibrationGrid.paper(RIG), seed=0)
    save_database(dataclasses.replace(db, tau_load=-db.tau_load), tmp_path / "flipped.json")
    with pytest.raises(CalibrationError, match="the torques have the sign opposite to the currents"):
        load_database(tmp_path / "flipped.json", RIG)
