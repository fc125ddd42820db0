"""The T-RO 2021 paper's model (evaluation.tro2021_model) against numbers worked by hand from their scripts,
and against this project's model with the rig file's numbers (two implementations of one model)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import worm_model
from worm_model.physics.parameters import load_rig
from worm_model.residuals.extended import ExtendedModel

from torque_estimator.evaluation.tro2021_model import TroDrive, friction_coefficient, motor_torque, payload, \
    their_torque

RIG_FILE = Path(worm_model.__file__).resolve().parent / "data" / "tro2021_worm_rig.yaml"


def test_geometry_as_their_transmission_class_derives_it() -> None:
    drive = TroDrive()
    assert drive.gear_diameter == pytest.approx(0.0300010, abs=1e-7)  # tan(2.8625 deg) x 10 mm x 60
    assert drive.gamma == pytest.approx(0.3333223, abs=1e-7)  # 10 mm / 30.001 mm
    assert math.degrees(drive.pressure_angle) == pytest.approx(19.977020, abs=1e-6)  # atan(tan 20 deg cos lambda)
    assert payload() == pytest.approx(0.01883904, abs=1e-8)  # 9.812 x 0.096 x 0.02


def test_worked_by_hand_at_10_rpm_both_ways() -> None:
    """Their frame, v = 10 rpm = 1.047198 rad/s of the worm, P = 0.01883904 N m (aids + motion):
    mu = 0.12 + 0.06 exp(-1.047198/0.688)^2 = 0.122858; rho = atan(mu / cos 19.97702 deg) = 7.44769 deg;
    downhill tan(2.8625 - 7.44769 deg) = -0.080198, uphill tan(2.8625 + 7.44769 deg) = 0.181915.
    v > 0: Dvar = P - 4e-3 > 0 -> psi* = downhill; support = 5.5e-4 + 1.15e-5 v + gamma psi* 4e-3 = 4.551157e-4;
    torque = -gamma psi* P + support = 9.587165e-4 N m (the motor still drives: the drive self-locks).
    v < 0: Dvar = -(P + 4e-3) < 0 -> psi* = uphill; support = -8.045874e-4; torque = -1.946915e-3 N m."""
    drive = TroDrive()
    v = 10 * math.pi / 30
    assert float(friction_coefficient(drive, v)) == pytest.approx(0.122858, abs=1e-6)
    np.testing.assert_allclose(their_torque(drive, np.array([v, -v]), payload()), [9.587165e-4, -1.946915e-3],
                               rtol=2e-6)
    # 1 rpm: mu = 0.164253 (the Stribeck rise), psi* = -0.123687, torque 1.162980e-3 N m
    assert float(their_torque(drive, math.pi / 30, payload())) == pytest.approx(1.162980e-3, rel=2e-6)


def test_our_frame_keeps_the_epos_signs() -> None:
    """The EPOS recorded lifting as + rotation with + torque; their reader negated both."""
    w = 10 * math.pi / 30
    lifting, lowering = motor_torque(TroDrive(), np.array([w, -w]), payload())
    assert lifting == pytest.approx(1.946915e-3, rel=2e-6) and lowering == pytest.approx(-9.587165e-4, rel=2e-6)


def test_our_model_with_their_numbers_is_their_model() -> None:
    """Eq. 28 with the drags (ExtendedModel, the estimators' model) and the rig file's numbers against their
    uphill/downhill form, 0.05-200 rpm both ways: the same to 1e-10 N m (the file rounds their derived values
    to 7-8 digits)."""
    rig = load_rig(RIG_FILE)
    model = ExtendedModel(rig)
    w = np.geomspace(0.005, 21.0, 200)
    w = np.concatenate([w, -w])
    ours = model.drive_torque(model.signals(w, 0.0, payload(), 0.0))
    theirs = motor_torque(TroDrive(), w, payload())
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-10)
    assert np.max(np.abs(theirs)) > 1e-3
