"""The rig file of the T-RO 2021 worm drive (worm_model/data/tro2021_worm_rig.yaml): it loads, its numbers
are the authors' (sd_1dof.m, Transmission.m), and the optional leaves it needs leave the older files alone."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

import worm_model
from worm_model.physics.parameters import default_rig_path, load_rig, rig_from_dict, rig_to_dict

RIG_FILE = Path(worm_model.__file__).resolve().parent / "data" / "tro2021_worm_rig.yaml"


def test_loads_with_their_geometry_and_frictions() -> None:
    rig = load_rig(RIG_FILE)
    gb = rig.gearbox
    assert gb.ratio == pytest.approx(1 / 60) and gb.geometric_ratio == pytest.approx(1 / 60, rel=1e-6)
    assert math.degrees(gb.lead_angle) == pytest.approx(2.8625)
    # their pressure angle: atan(tan(40 deg / 2) cos(lambda)) = 19.97702 deg
    assert math.degrees(gb.normal_pressure_angle) == pytest.approx(
        math.degrees(math.atan(math.tan(math.radians(20)) * math.cos(gb.lead_angle))), abs=1e-5)
    assert gb.self_locking_mu == pytest.approx(0.04699, abs=1e-5)
    assert gb.self_locking_mu < rig.friction.mu_constant  # their mu: the drive self-locks
    f = rig.friction
    assert (f.model, f.mu_constant, f.stribeck_rise) == ("stribeck", 0.12, 0.06)
    # 0.688 rad/s of the worm as a sliding speed: x r_w / cos(lambda)
    assert f.stribeck_speed == pytest.approx(0.688 * 0.005 / math.cos(gb.lead_angle), rel=1e-7)
    assert rig.drive_motor.coulomb_drag == pytest.approx(5.5e-4) and rig.drive_motor.viscous_drag == 1.15e-5
    assert rig.load_motor.coulomb_drag == pytest.approx(4e-3) and rig.load_motor_count == 1
    # 100 % EPOS torque = nominal current x K_t = 9.84 mN m
    assert rig.drive_motor.rated_current * rig.drive_motor.torque_constant == pytest.approx(9.84e-3)


def test_every_leaf_says_where_its_number_comes_from() -> None:
    document = yaml.safe_load(RIG_FILE.read_text())
    leaves = [(section, name, node) for section, body in document.items() if isinstance(body, dict)
              for name, node in body.items() if isinstance(node, dict)]
    leaves += [("", name, node) for name, node in document.items() if isinstance(node, dict) and "value" in node]
    assert len(leaves) == 40  # 9 gearbox, 4 friction, 9 + 9 motor, 7 sensor leaves, load_motor_count, supply_voltage
    for section, name, node in leaves:
        kinds = [k for k in ("source", "assumption") if node.get(k)]
        assert len(kinds) == 1, f"{section}.{name}"
        assert len(node[kinds[0]]) > 20, f"{section}.{name}: say why"


def test_files_without_the_optional_friction_leaves_still_load() -> None:
    rig = load_rig(default_rig_path())
    assert (rig.friction.stribeck_rise, rig.friction.stribeck_speed) == (0.0, 0.01)
    plain = rig_to_dict(load_rig(RIG_FILE))
    del plain["friction"]["stribeck_rise"], plain["friction"]["stribeck_speed"]  # a calibration file's older rig
    assert rig_from_dict(plain).friction.stribeck_rise == 0.0
