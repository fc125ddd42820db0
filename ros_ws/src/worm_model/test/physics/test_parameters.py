"""Parameter file loader: the bundled file, unit conversion, and rejected files naming the field."""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from worm_model.physics.parameters import ADC_SEQUENCE, Sensors, default_rig_path, load_rig, rig_from_dict, rig_to_dict
from worm_model.errors import ParameterError


def test_bundled_file_loads() -> None:
    rig = load_rig()
    assert rig == load_rig(default_rig_path())
    gb = rig.gearbox
    assert (gb.worm_starts, gb.gear_teeth) == (1, 30)
    assert gb.ratio == pytest.approx(1 / 30)
    assert gb.geometric_ratio == pytest.approx(gb.ratio, rel=1e-4)
    assert gb.lead_angle == pytest.approx(math.atan(0.1), rel=1e-4)
    assert gb.worm_inertia == pytest.approx(2e-6)  # 20 g cm^2
    assert rig.drive_motor.inductance == pytest.approx(1.5e-3)
    assert rig.drive_motor.coulomb_drag == pytest.approx(4e-3)
    assert rig.sensors.encoder_pulses_per_rev == 500 and isinstance(rig.sensors.encoder_decoding, int)
    assert rig.total_worm_inertia == pytest.approx(gb.worm_inertia + rig.drive_motor.rotor_inertia)
    assert rig.total_gear_inertia == pytest.approx(gb.gear_inertia + 2 * rig.load_motor.rotor_inertia)
    assert rig.max_load_torque == pytest.approx(2 * 0.055 * 2.5)
    assert Path(rig.source) == default_rig_path()


def test_dict_round_trip_is_json() -> None:
    rig = load_rig()
    data = json.loads(json.dumps(rig_to_dict(rig)))
    assert rig_from_dict(data) == rig


def _document() -> dict[str, Any]:
    return yaml.safe_load(default_rig_path().read_text())


def _write(tmp_path: Path, doc: dict[str, Any]) -> Path:
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def test_unit_conversion(tmp_path: Path) -> None:
    doc = _document()
    doc["drive_motor"] = dict(doc["drive_motor"])
    doc["drive_motor"]["back_emf_constant"] = {"value": 5.759, "unit": "V/krpm", "source": "test"}
    doc["gearbox"]["lead_angle"] = {"value": 0.0996687, "unit": "rad", "source": "test"}
    doc["gearbox"]["worm_pitch_radius"] = {"value": 0.0075, "unit": "m", "source": "test"}
    rig = load_rig(_write(tmp_path, doc))
    assert rig.drive_motor.back_emf_constant == pytest.approx(0.055, rel=1e-3)
    assert rig.load_motor.back_emf_constant == pytest.approx(0.055)


def _set(section: str, name: str, **changes: Any) -> Callable[[dict[str, Any]], None]:
    def mutate(doc: dict[str, Any]) -> None:
        leaf = dict(doc[section][name])
        for key, value in changes.items():
            if value is None:
                leaf.pop(key, None)
            else:
                leaf[key] = value
        doc[section] = dict(doc[section])
        doc[section][name] = leaf

    return mutate


def _drop(section: str, name: str) -> Callable[[dict[str, Any]], None]:
    def mutate(doc: dict[str, Any]) -> None:
        del doc[section][name]

    return mutate


BAD = {
    "broken ratio": (_set("gearbox", "gear_teeth", value=40), "gearbox.gear_teeth", "0.02500"),
    "missing source": (_set("gearbox", "lead_angle", assumption=None), "gearbox.lead_angle", "source"),
    "source and assumption": (_set("gearbox", "lead_angle", source="x"), "gearbox.lead_angle", "exactly one"),
    "unknown unit": (_set("gearbox", "lead_angle", unit="furlong"), "gearbox.lead_angle", "unknown unit"),
    "wrong dimension": (_set("gearbox", "lead_angle", unit="mm"), "gearbox.lead_angle", "expected a angle"),
    "non-numeric": (_set("drive_motor", "resistance", value="abc"), "drive_motor.resistance", "not numeric"),
    "boolean": (_set("sensors", "tacho_ripple", value=True), "sensors.tacho_ripple", "not numeric"),
    "angle range": (_set("gearbox", "normal_pressure_angle", value=50), "gearbox.normal_pressure_angle", "45"),
    "negative": (_set("drive_motor", "inductance", value=-1), "drive_motor.inductance", "> 0"),
    "non-integer count": (_set("sensors", "encoder_pulses_per_rev", value=500.5), "sensors.encoder_pulses_per_rev",
                          "integer"),
    "missing field": (_drop("sensors", "sample_rate_hz"), "sensors.sample_rate_hz", "missing"),
    "unknown model": (lambda d: d["friction"].update(model="magic"), "friction.model", "unknown model"),
    "bare number": (lambda d: d.update(supply_voltage=24), "supply_voltage", "mapping"),
    "wrong format": (lambda d: d.update(format="other"), "format", "worm_rig_parameters"),
    # physically implausible numbers: a unit slip or a typo, refused with the plausible range
    "K_t 1e-12": (_set("drive_motor", "torque_constant", value=1e-12), "drive_motor.torque_constant",
                  "not a plausible torque_constant: expected 0.0001 .. 50 N m/A"),
    "1 MV supply": (lambda d: d.update(supply_voltage={**d["supply_voltage"], "value": 1e6}), "supply_voltage",
                    "not a plausible supply_voltage"),
    "48 V supply on 24 V motors x3": (lambda d: d.update(supply_voltage={**d["supply_voltage"], "value": 72}),
                                      "supply_voltage", "3 x the drive motor's max_voltage"),
    "K_e in V/krpm as V s/rad": (_set("drive_motor", "back_emf_constant", value=5.759), "back_emf_constant",
                                 "differ 105-fold"),
    "lead angle in rad written deg": (_set("gearbox", "lead_angle", value=0.0996687), "gearbox.lead_angle",
                                      "expected 0.5 .. 45 deg"),
    "encoder decoding 8": (_set("sensors", "encoder_decoding", value=8), "sensors.encoder_decoding",
                           "expected 1 .. 4"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_files_are_rejected_naming_the_field(tmp_path: Path, case: str) -> None:
    mutate, field, fragment = BAD[case]
    doc = _document()
    mutate(doc)
    path = _write(tmp_path, doc)
    with pytest.raises(ParameterError) as info:
        load_rig(path)
    message = str(info.value)
    assert str(path) in message and field in message and fragment in message, message
    assert isinstance(info.value, ValueError)


OPTIONAL_SENSORS = ("tacho_drive_lsb", "tacho_load_lsb", "tacho_ripple_order", "adc_clock_hz", "adc_conversion_cycles",
                    "adc_hold_cycles")


def test_the_sensor_chain_is_in_the_rig_file() -> None:
    """The numbers the simulator's sensors and the observer's noise model share: the tachos' resolutions (500 and
    20 rad/s over 512 codes), the ripple order, the ADC timing (13 clocks at 125 kHz per channel, held 1.5 clocks
    in): the current is sampled 12 us after the tick, the drive tacho 116 us."""
    s = load_rig().sensors
    assert (s.tacho_drive_lsb, s.tacho_load_lsb, s.tacho_ripple_order) == (500 / 512, 20 / 512, 7)
    assert isinstance(s.tacho_ripple_order, int) and isinstance(s.adc_conversion_cycles, int)
    times = s.sample_times()
    assert list(times) == list(ADC_SEQUENCE)
    assert times["current_drive"] == pytest.approx(12e-6, rel=1e-12)
    assert times["tacho_drive"] == pytest.approx(116e-6, rel=1e-12)
    assert s.sequence_time() == pytest.approx(6 * 104e-6, rel=1e-12)
    assert s.counts_per_rev == 2000


def test_a_file_without_the_optional_sensor_fields_takes_the_bundled_ones(tmp_path: Path) -> None:
    """A rig file (or a calibration's embedded rig) written without the sensor chain's optional fields reads as
    before they existed: the bundled rig's values; one that gives them has its own."""
    doc = _document()
    for name in OPTIONAL_SENSORS:
        del doc["sensors"][name]
    assert load_rig(_write(tmp_path, doc)).sensors == load_rig().sensors
    data = rig_to_dict(load_rig())
    for name in OPTIONAL_SENSORS:
        del data["sensors"][name]
    assert rig_from_dict(data).sensors == load_rig().sensors
    doc["sensors"]["tacho_ripple_order"] = {"value": 9, "unit": "1", "assumption": "a 9-segment tacho"}
    assert load_rig(_write(tmp_path, doc)).sensors.tacho_ripple_order == 9
    assert {f.name for f in dataclasses.fields(Sensors) if f.metadata.get("optional")} == set(OPTIONAL_SENSORS)


def test_the_bundled_file_gives_every_field() -> None:
    """The bundled file is what optional fields fall back to: it must have them all, each with its source."""
    doc = _document()
    for f in dataclasses.fields(Sensors):
        assert f.name in doc["sensors"], f.name
        assert doc["sensors"][f.name].get("source") or doc["sensors"][f.name].get("assumption"), f.name


def test_broken_ratio_names_all_fields_and_values(tmp_path: Path) -> None:
    doc = _document()
    _set("gearbox", "gear_teeth", value=40)(doc)
    with pytest.raises(ParameterError) as info:
        load_rig(_write(tmp_path, doc))
    msg = str(info.value)
    for name in ("worm_starts", "gear_teeth", "worm_pitch_radius", "gear_pitch_radius", "lead_angle"):
        assert f"gearbox.{name}" in msg
    assert "0.03333" in msg


def test_missing_file() -> None:
    with pytest.raises(ParameterError, match="no_such.yaml"):
        load_rig("/nonexistent/no_such.yaml")
