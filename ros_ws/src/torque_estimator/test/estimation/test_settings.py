"""EstimatorSettings and build_estimator: the one way estimator_node, replay, ``estimate`` and the rig feedforward
build an estimator; the registry's options; the streaming contract as protocols."""
from __future__ import annotations

import inspect
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from worm_model.physics.parameters import default_rig_path, load_rig
from worm_model.errors import ParameterError

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.base import AngleEstimator, StreamingEstimator
from torque_estimator.estimation.database import save_database
from torque_estimator.errors import CalibrationError
from torque_estimator.estimation.extended_model import ExtendedModelEstimator
from torque_estimator.estimation.knn import KnnEstimator
from torque_estimator.estimation.live import LiveEstimator
from torque_estimator.estimation.observer import LoadObserver, LoadProcess, ObserverEstimator
from torque_estimator.estimation.registry import MAP_OPTIONS, METHODS, PRIOR_OPTIONS
from torque_estimator.estimation.settings import ALL_OPTIONS, EstimatorSettings, build_estimator

RIG = load_rig()


@pytest.fixture(scope="module")
def calibration(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("settings") / "calibration.json"
    save_database(calibrate_simulated(RIG, CalibrationGrid.paper(RIG, 5, 4), seed=0), path)
    return path


@pytest.fixture(scope="module")
def heavier_rig(tmp_path_factory) -> Path:
    """The bundled rig with 1.5x the drive motor's rotor inertia: which rig a core got shows in its J_eff."""
    doc = yaml.safe_load(default_rig_path().read_text(encoding="utf-8"))
    doc["drive_motor"] = dict(doc["drive_motor"], rotor_inertia={"value": 180, "unit": "g cm^2",
                                                                 "assumption": "test: 1.5x the bundled rotor"})
    path = tmp_path_factory.mktemp("rig") / "heavier.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return path


def test_every_option_default_is_its_class_default() -> None:
    """The node's defaults (registry options) are what LiveEstimator and the k-NN map take when not told: a
    method built without parameters and one built from the node's defaults are the same."""
    live = inspect.signature(LiveEstimator).parameters
    knn = inspect.signature(KnnEstimator).parameters
    for option in MAP_OPTIONS:
        assert live[option.name].default == option.default, option.name
    for name in ("k", "weighting"):
        assert knn[name].default == ALL_OPTIONS[name].default, name


def test_each_method_reads_only_its_options() -> None:
    """The map's filters are read by the quasi-static maps, not by the observer, which follows the rig itself."""
    assert {o.name for o in METHODS["knn"].options} == {"k", "weighting", *(o.name for o in MAP_OPTIONS)}
    assert {o.name for o in METHODS["extended_model"].options} == {o.name for o in MAP_OPTIONS + PRIOR_OPTIONS}
    assert METHODS["observer"].options == PRIOR_OPTIONS  # the load prior only
    parameters = {"method": "observer", "k": 9, "input_filter": 0.1, "calibration_file": ""}
    assert EstimatorSettings.from_parameters(parameters).options == {"load_min": 0.0, "load_max": 0.0}
    knn = EstimatorSettings.from_parameters(parameters, "knn")
    assert knn.estimator_options == {"k": 9, "weighting": "inverse_distance"}
    assert knn.live_options["input_filter"] == 0.1 and knn.live_options["change_threshold"] == 4.0
    with pytest.raises(ValueError, match="does not read input_filter"):
        EstimatorSettings("observer", options={"input_filter": 0.1})
    with pytest.raises(ValueError, match="unknown estimator 'kalman'"):
        EstimatorSettings("kalman")


def test_the_streaming_contract_is_a_protocol() -> None:
    """LiveEstimator tells a stream from a map by the protocols, not by attribute names."""
    observer = ObserverEstimator(None)
    assert isinstance(observer, StreamingEstimator) and not isinstance(observer, AngleEstimator)
    assert isinstance(ExtendedModelEstimator(None, speed_points=3, torque_points=3), AngleEstimator)
    live = LiveEstimator(RIG, observer, 1e-3)
    assert isinstance(live.stream, LoadObserver)
    assert not isinstance(ExtendedModelEstimator(None, speed_points=3, torque_points=3), StreamingEstimator)


def test_one_builder_for_the_node_replay_estimate_and_the_feedforward(calibration, heavier_rig) -> None:
    """The builder's rules: the calibration read and checked; LiveEstimator's rig is rig_file, else the model
    file of a method that reads one; the observer's model is the model file, else the rig file."""
    built = build_estimator(EstimatorSettings("knn", calibration_file=str(calibration), options={"k": 2}))
    assert isinstance(built.estimator, KnnEstimator) and built.estimator.k == 2 and len(built.database) == 40
    live = built.live(1e-3)
    assert live.stream is None and live.rig == RIG and live.inertia_compensation is True
    assert built.live(1e-3) is not live  # each call a fresh front end
    # the model file of a method that reads one is LiveEstimator's rig when no rig_file is given
    model = build_estimator(EstimatorSettings("observer", model_file=str(heavier_rig)))
    assert model.rig.drive_motor.rotor_inertia == pytest.approx(1.8e-5)
    assert model.estimator.rig == model.rig and model.database is None
    knn_with_model = build_estimator(EstimatorSettings("knn", calibration_file=str(calibration),
                                                       model_file=str(heavier_rig)))
    assert knn_with_model.rig == RIG  # knn reads no model file
    both = build_estimator(EstimatorSettings("extended_model", rig_file=str(default_rig_path()),
                                             model_file=str(heavier_rig)))
    assert both.rig == RIG and both.estimator.model.rig.drive_motor.rotor_inertia == pytest.approx(1.8e-5)
    # a Rig object instead of the files (the rig feedforward), with estimator options no node parameter has
    given = build_estimator(EstimatorSettings("observer"), rig=load_rig(heavier_rig),
                            estimator_options={"load": LoadProcess(false_alarm=1e-3)})
    assert given.rig == given.estimator.rig == load_rig(heavier_rig)
    assert given.live(1e-3).stream.load.false_alarm == 1e-3
    extended = build_estimator(EstimatorSettings("extended_model"), rig=load_rig(heavier_rig))
    assert extended.estimator.model.rig == load_rig(heavier_rig) == extended.rig


def test_what_cannot_be_built_names_the_file(calibration, tmp_path) -> None:
    with pytest.raises(CalibrationError, match="needs a calibration file"):
        build_estimator(EstimatorSettings("knn"))
    with pytest.raises(CalibrationError, match="no_such.json"):
        build_estimator(EstimatorSettings("observer", calibration_file=str(tmp_path / "no_such.json")))
    with pytest.raises(ParameterError, match="no_such.yaml"):
        build_estimator(EstimatorSettings("observer", model_file=str(tmp_path / "no_such.yaml")))
    # a calibration far outside the rig's envelope is refused, by every caller alike
    doc = json.loads(calibration.read_text(encoding="utf-8"))
    doc["points"]["omega_worm"][3] = 1e5
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(CalibrationError, match="points.omega_worm"):
        build_estimator(EstimatorSettings("observer", calibration_file=str(bad)))
    with pytest.raises(ValueError, match="one or the other"):
        build_estimator(EstimatorSettings("observer", model_file=str(default_rig_path())), rig=RIG)


def test_built_as_before_the_settings_existed(calibration) -> None:
    """The builder makes what the callers made by hand: the same estimates, sample for sample."""
    from torque_estimator.estimation.database import load_database
    rows = [(150.0 + np.sin(k / 50), 0.4 + 0.01 * np.cos(k / 7), 8.0, 0.15 * k) for k in range(400)]
    db = load_database(calibration, RIG)
    for method, by_hand in (("knn", KnnEstimator(db, k=4)), ("observer", ObserverEstimator(db))):
        built = build_estimator(EstimatorSettings(method, calibration_file=str(calibration))).live(1e-3)
        hand = LiveEstimator(RIG, by_hand, 1e-3)
        assert ([built.update(w, i, voltage_drive=v, theta_worm=th) for w, i, v, th in rows]
                == [hand.update(w, i, voltage_drive=v, theta_worm=th) for w, i, v, th in rows])
