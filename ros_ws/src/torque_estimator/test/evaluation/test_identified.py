"""The fast road on the simulator: one identify run against the k-NN grid, every default effect on.

Pinned near what was measured (README, `make evaluate`): the identified extended model 0.68 % mean / 1.29 % max
of the range with this seed (seeds 1-3: 0.68-0.89 / 1.29-2.64 %), inside the issue's 1.0 / 3 %; the observer
with the identified parameters 3.16 / 8.37 %; the k-NN on the 544-point grid of the same rig 1.21 / 3.80 %;
the rig file as declared ~39 / ~140 %.  What got the identified model there: the gear ripple taken out with the
encoder angle (extended_model), the PWM ripple's sampled bias in the vocabulary (residual effect ``pwm``), the
fit on quasi-static samples with identify's own acceptance settings (identification.fit); before: 2.97 / 6.96 %.
"""
from __future__ import annotations

from worm_model.physics.parameters import load_rig

import pytest

from worm_model.residuals.effects import EFFECTS as VOCABULARY
from worm_model.residuals.extended import write_with_effects
from worm_model.rig_data.schema import write_rig_csv

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.extended_model import ExtendedModelEstimator
from torque_estimator.offline.estimate import main as estimate_main
from torque_estimator.evaluation.held_out import measure_held_out, score
from torque_estimator.evaluation.identified import effects_all, run_roads
from torque_estimator.evaluation.scenario import DEMO_SCENARIO
from torque_estimator.identification.excitation import Ramp
from torque_estimator.identification.simulated import record_on_simulator

RIG = load_rig()


@pytest.fixture(scope="module")
def roads(tmp_path_factory):
    grid = CalibrationGrid.paper(RIG)
    effects = effects_all()
    db = calibrate_simulated(RIG, grid, seed=0, effects=effects, batch_size=len(grid.speeds) * len(grid.torques))
    return run_roads(RIG, db, grid, effects=effects, out=tmp_path_factory.mktemp("identified")), grid, db


def test_identify_in_85_s_meets_the_target(roads) -> None:
    result, _grid, _db = roads
    ev = result.evaluations
    assert result.identification_rig_time <= 90.0
    assert ev["declared"].mae_pct > 20.0  # identification is what makes the model usable
    assert ev["identified"].mae_pct <= 1.0 and ev["identified"].max_pct <= 2.5, (ev["identified"].mae_pct,
                                                                               ev["identified"].max_pct)
    assert ev["observer"].mae_pct < 3.5 and ev["observer"].max_pct < 9.5, (ev["observer"].mae_pct,
                                                                         ev["observer"].max_pct)
    assert ev["knn"].mae_pct < 1.5 and ev["knn"].max_pct < 4.5
    assert "sensor_offset" in result.found  # the 0.05 A drive-current offset, the largest error of the file
    assert "gear_runout" in result.found and "speed_dependent_mu" in result.found
    mu = result.corrections["friction.scale"]
    # declared 1.3; 1.01 with this seed, 0.80 where the Stribeck law's low-speed rise took part of the scale
    assert 0.75 < mu[1] < 1.1


def test_the_true_model_bounds_what_identification_can_reach(roads, tmp_path) -> None:
    """The bundled parameters and every simulator effect at its true value (the residual vocabulary's
    reading of effects_all.yaml): 0.45 / 0.79 % on the same points (README). What is left is the load
    sensors' 2 % gain in the reference, the 26 mA current step and the window's noise."""
    result, grid, db = roads
    config = effects_all()
    path = write_with_effects(tmp_path / "true_model.yaml",
                              {name: values for name, values in config.effects.items() if name in VOCABULARY})
    ev = score(ExtendedModelEstimator(model_file=str(path)), measure_held_out(RIG, grid, 17, 1, effects=config),
               db.torque_range)
    assert ev.mae_pct < 0.6 and ev.max_pct < 1.1, (ev.mae_pct, ev.max_pct)


def test_estimate_on_a_log_of_the_effects_rig(roads, tmp_path, capsys) -> None:
    """`estimate` with the identified file over the demo's six segments recorded on the effects rig: 0.88 / 2.34 %
    on the 92.4 % of the moving samples it trusts (docs/residuals.md), the file as declared 9.87 / 27.45 % on 68.6 %;
    the streaming observer with the identified file 2.26 / 7.10 % on 39.5 % (open: its filter with backlash, PWM
    and ripples on flags most of the run)."""
    result, _grid, _db = roads
    timeline = [Ramp(s.duration, s.speed, s.speed, s.load, s.load, s.label) for s in DEMO_SCENARIO]
    log = tmp_path / "demo.csv"
    write_rig_csv(log, record_on_simulator(RIG, timeline, effects=effects_all(), seed=2))
    lines = {}
    for label, model in (("identified", result.model_file),
                         ("declared", result.model_file.parent / "declared_rig.yaml")):
        assert estimate_main([str(log), "--method", "extended_model", "--model-file", str(model),
                              "--out", str(tmp_path / f"{label}.csv"), "--quiet"]) == 0
        lines[label] = capsys.readouterr().out.strip().splitlines()[-1]
    figures = {k: dict(f.split("=") for f in v.split()[1:]) for k, v in lines.items()}
    assert float(figures["identified"]["mae_pct"]) < 1.2 and float(figures["identified"]["max_pct"]) < 3.0, lines
    # as declared, the model is off on the samples it still trusts and trusts far fewer (measured 9.87 % on 68.6 %)
    assert float(figures["declared"]["mae_pct"]) > 8.0 * float(figures["identified"]["mae_pct"]), lines
    assert float(figures["declared"]["trusted_pct"]) < float(figures["identified"]["trusted_pct"]) - 15.0, lines
    assert estimate_main([str(log), "--method", "observer", "--model-file", str(result.model_file),
                          "--out", str(tmp_path / "observer.csv"), "--quiet"]) == 0
    observer = dict(f.split("=") for f in capsys.readouterr().out.strip().splitlines()[-1].split()[1:])
    with capsys.disabled():  # the README's figures, with -s
        print("\n", lines, "\n observer", observer)
    assert float(observer["mae_pct"]) < 3.0 and float(observer["max_pct"]) < 9.0, observer
    assert 30.0 < float(observer["trusted_pct"]) < 50.0, observer
