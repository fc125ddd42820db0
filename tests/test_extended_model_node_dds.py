"""System test: estimator_node with method extended_model reads its model file and estimates
through it over DDS (the residual tool's correction reaching live estimation).

The probe publishes a steady RigSample stream whose current is the extended model's own
current at a known load (bearing and viscous drag the paper's model lacks); estimator_node
started with that model file must report that load, and started without it (the paper's
model) must not.
"""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from worm_msgs.msg import RigSamples, TorqueEstimate

from worm_model.ros.testing import probe_node, rig_samples, spin_until
from worm_model.physics.parameters import default_rig_path
from worm_model.residuals.extended import ExtendedModel

EFFECTS = {"bearing_coulomb": {"worm_torque": 0.004, "gear_torque": 0.03},
           "viscous_drag": {"worm_torque": 0.004, "gear_torque": 0.0, "reference_speed": 300.0, "exponent": 1.0}}
OMEGA, LOAD = 150.0, 0.1  # [rad/s], [N m]
QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500, reliability=ReliabilityPolicy.BEST_EFFORT)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("extended_node")
    document = yaml.safe_load(default_rig_path().read_text(encoding="utf-8"))
    document["effects"] = EFFECTS
    model = folder / "extended_rig.yaml"
    model.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    calibration = folder / "calibration.json"
    done = subprocess.run([sys.executable, "-m", "torque_estimator.calibration.calibrate", "--out", str(calibration),
                           "--quiet"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return model, calibration


def steady_current(model_file: Path) -> float:
    model = ExtendedModel.load(model_file)
    signals = model.signals(np.array([OMEGA]), np.array([0.0]), np.array([LOAD]), np.array([0.0]))
    return float(model.current(signals)[0])


def estimates_for(start_graph, files: tuple[Path, Path], model_file: str, name: str) -> list[TorqueEstimate]:
    model, calibration = files
    graph = start_graph(f"""estimator_node:
  ros__parameters:
    method: extended_model
    model_file: "{model_file}"
    calibration_file: "{calibration}"
""", name)
    current = steady_current(model)
    got: list[TorqueEstimate] = []
    with probe_node(f"probe_{name}") as (node, executor):
        pub = node.create_publisher(RigSamples, "/rig/samples", QOS)
        node.create_subscription(TorqueEstimate, "/torque_estimate", got.append, QOS)
        assert spin_until(executor, lambda: pub.get_subscription_count() > 0, 30.0), (
            "estimator_node did not subscribe to /rig/samples")
        for first in range(0, 1500, 5):  # 1.5 s of a steady operating point, in the rig's batches
            pub.publish(rig_samples(first, 5, node.get_clock().now().to_msg(), omega_worm=OMEGA,
                                    current_drive=current, tau_load=LOAD))
            executor.spin_once(timeout_sec=0.005)
        spin_until(executor, lambda: False, 0.5)
    # stop it now: the next run's probe must hear only its own estimator_node
    assert graph.stop() == {"estimator_node": 0}
    return [m for m in got if m.seq >= 1000]


def test_model_file_reaches_live_estimation(start_graph, files: tuple[Path, Path]) -> None:
    extended = estimates_for(start_graph, files, str(files[0]), "extended")
    plain = estimates_for(start_graph, files, "", "plain")
    assert len(extended) > 50 and len(plain) > 50, (len(extended), len(plain))  # of 100 batches
    err_extended = np.mean([m.torque for m in extended]) - LOAD
    err_plain = np.mean([m.torque for m in plain]) - LOAD
    assert all(m.method == "extended_model" and math.isfinite(m.torque) for m in extended)
    assert abs(err_extended) < 0.005, f"extended model: tau_d error {err_extended:+.4f} N m"
    assert abs(err_plain) > 0.03, f"paper's model: tau_d error {err_plain:+.4f} N m (the drag should bias it)"
