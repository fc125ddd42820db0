"""The fast road on the simulator (issue 18): one identify run against the k-NN grid, every default effect on.

Pinned near what was measured (README, `make evaluate`): identified extended model 2.84-2.97 % mean /
6.96-7.61 % max of the range, the observer with the identified parameters 2.86 / 7.82 %, the k-NN on the
544-point grid of the same rig 1.21 / 3.80 %, the rig file as declared ~39 / ~140 %.  The issue's target
(1.0 / 3 %) is not reached: with the true model and every true effect given, the same held-out points
score 2.51 / 6.97 % (gear runout read over part of a gear turn, the PWM ripple's bias in the sampled current,
the load sensor's errors: what a model of (omega, i) window means cannot know), see README.
"""
from __future__ import annotations

from worm_model.physics.parameters import load_rig

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.experiment.identified import effects_all, run_roads

RIG = load_rig()


def test_identify_in_85_s_gets_within_3_x_of_the_grid(tmp_path) -> None:
    grid = CalibrationGrid.paper(RIG)
    effects = effects_all()
    db = calibrate_simulated(RIG, grid, seed=0, effects=effects, batch_size=len(grid.speeds) * len(grid.torques))
    result = run_roads(RIG, db, grid, effects=effects, out=tmp_path)
    ev = result.evaluations
    assert result.identification_rig_time <= 90.0
    assert ev["declared"].mae_pct > 20.0  # identification is what makes the model usable
    assert ev["identified"].mae_pct < 3.5 and ev["identified"].max_pct < 9.0, (ev["identified"].mae_pct,
                                                                             ev["identified"].max_pct)
    assert ev["observer"].mae_pct < 3.5 and ev["observer"].max_pct < 9.5, (ev["observer"].mae_pct,
                                                                         ev["observer"].max_pct)
    assert ev["knn"].mae_pct < 1.5 and ev["knn"].max_pct < 4.5
    assert "sensor_offset" in result.found  # the 0.05 A drive-current offset, the largest error of the file
    mu = result.corrections["friction.scale"]
    assert abs(mu[1] - 1.0) < 0.08  # declared 1.3
