"""Units checked against the rig (worm_model.rig_data.plausibility), applied by the one rig-data reader: a
log in ms, mA, rpm or degrees is refused naming the column and the likely unit; a calibration likewise."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_model.rig_data.plausibility import calibration_problem, check_rig_data
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData, write_rig_csv
from worm_model.errors import RigDataError

RIG = load_rig()


def log(n: int = 2000, rate: float = 1000.0, **changes) -> MeasuredData:
    """A steady run at 150 rad/s on the bundled rig (1 kHz), angle the integral of the speed."""
    t = np.arange(n) / rate
    omega = 150.0 + 0.5 * np.sin(7 * t)
    columns = {"t": t, "current_drive": np.full(n, 0.2), "omega_worm": omega,
               "theta_worm": np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * np.diff(t))]),
               "tau_load": np.full(n, 0.1), "voltage_drive": np.full(n, 12.0)}
    columns.update(changes)
    return MeasuredData(**columns, source="run.csv")


def refused(data: MeasuredData, *fragments: str) -> str:
    with pytest.raises(RigDataError) as info:
        check_rig_data(data, RIG)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)
    return str(info.value)


def test_a_plausible_log_passes_also_decimated() -> None:
    check_rig_data(log(), RIG)
    check_rig_data(log(rate=100.0), RIG)  # every 10th sample of the 1 kHz rig


def test_time_in_the_wrong_unit_is_named() -> None:
    good = log()
    refused(log(t=good.t * 1e3), "t looks like milliseconds: median step 1 at a 1 kHz rig", "column 't'")
    refused(log(t=good.t * 1e6), "microseconds")
    refused(log(t=good.t * 1e9), "nanoseconds")
    refused(log(t=good.t * 1e-2), "not in seconds, or the rig file's sensors.sample_rate_hz is wrong")


def test_channels_in_the_wrong_unit_are_named() -> None:
    good = log()
    refused(log(current_drive=good.current_drive * 1e3), "column 'current_drive'", "looks like mA")
    refused(log(omega_worm=good.omega_worm * 60 / (2 * math.pi)), "column 'omega_worm'", "looks like rpm")
    refused(log(voltage_drive=good.voltage_drive * 1e3), "looks like mV")
    refused(log(tau_load=np.full(len(good), 100.0)), "column 'tau_load'", "mN m")


def test_the_angle_must_follow_the_speed() -> None:
    good = log()
    refused(log(theta_worm=np.degrees(good.theta_worm)), "column 'theta_worm'", "57.3 x", "looks like degrees")
    refused(log(theta_worm=good.theta_worm / (2 * math.pi)), "looks like revolutions")
    refused(log(theta_worm=-good.theta_worm), "signs disagree")
    slow = good.omega_worm * 20 / 150  # 191 rpm is within the rig's no-load speed: only the angle tells
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (slow[1:] + slow[:-1]) * np.diff(good.t))])
    refused(log(omega_worm=slow * 60 / (2 * math.pi), theta_worm=theta), "omega_worm looks like rpm")
    check_rig_data(log(theta_worm=good.theta_worm * 1.1), RIG)  # a tacho gain 10 % off is not a unit slip
    standstill = log(omega_worm=np.zeros(len(good)), theta_worm=np.zeros(len(good)))
    check_rig_data(standstill, RIG)  # nothing to compare


def test_one_sample_is_no_log() -> None:
    refused(log(n=1), "2 at least")


def test_the_reader_checks_every_file_it_reads(tmp_path: Path) -> None:
    good = log()
    write_rig_csv(tmp_path / "ms.csv", log(t=good.t * 1e3))
    with pytest.raises(RigDataError, match="milliseconds"):
        read_rig_data(tmp_path / "ms.csv")
    assert len(read_rig_data(tmp_path / "ms.csv", check=False)) == len(good)  # a converter may take it as is
    fast = load_rig()  # against the rig the data comes from: a 1 kHz log is 'decimated' for a 10 kHz rig
    import dataclasses
    fast = dataclasses.replace(fast, sensors=dataclasses.replace(fast.sensors, sample_rate_hz=10_000.0))
    write_rig_csv(tmp_path / "ok.csv", good)
    assert len(read_rig_data(tmp_path / "ok.csv", rig=fast)) == len(good)
    (tmp_path / "bom.csv").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "ok.csv").read_bytes())
    assert np.array_equal(read_rig_data(tmp_path / "bom.csv").t, good.t)  # a byte-order mark is no column name


def test_calibrations_every_reader_refuses() -> None:
    omega = np.repeat([50.0, 150.0], 3)
    current = np.tile([0.1, 0.2, 0.3], 2)
    tau = np.tile([-0.5, 0.0, 0.5], 2)
    assert calibration_problem(omega, current, tau, RIG) is None
    assert "span no torque range" in calibration_problem(omega, current, np.full(6, 0.1), RIG)
    assert "same operating point" in calibration_problem(np.full(6, 50.0), np.full(6, 0.1), np.full(6, 0.2))
    assert "looks like rpm" in calibration_problem(omega * 60 / (2 * math.pi), current, tau, RIG)
    assert calibration_problem([], [], []) == "no calibration points"


def test_the_users_page_states_the_thresholds_in_force() -> None:
    from worm_model.physics import parameters
    from worm_model.rig_data import plausibility
    page = (Path(__file__).resolve().parents[5] / "docs" / "files-and-inputs.md").read_text(encoding="utf-8")
    for figure in (f"more than {plausibility.MAX_DECIMATION:g} or less than {plausibility.MIN_RATE_RATIO:g} rig "
                   "sample periods", f"more than {plausibility.ANGLE_TOLERANCE:.0%} off",
                   f"at least {plausibility.MIN_TRAVEL / (2 * math.pi):.0f} turns".replace("2 turns", "two turns"),
                   f"within a factor {parameters.MOTOR_CONSTANT_RATIO:g}",
                   f"at most {parameters.SUPPLY_OVER_MOTOR:g} x the drive motor's",
                   "constant 1e-4 .. 50 N m/A", "a voltage 0.1 .. 1000 V", "a sample rate 1 Hz ..\n10 MHz"):
        assert figure in page, figure
    assert parameters.PLAUSIBLE["torque_constant"] == (1e-4, 50.0) and parameters.PLAUSIBLE["voltage"] == (0.1, 1e3)
    assert parameters.PLAUSIBLE["frequency"] == (1.0, 1e7)

