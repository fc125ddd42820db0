"""What a rig's sensors resolve (worm_model.physics.resolution): the speed and current sigmas and the standstill
and kinetic thresholds, from the rig file's sensors section and nothing else."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from worm_model.physics.parameters import default_rig_path, load_rig
from worm_model.physics.resolution import (KINETIC_SIGMAS, STILL_SIGMAS, current_sigma, kinetic_speed, speed_sigma,
                                           standstill_speed)

DATA = default_rig_path().parent
NMRV030 = load_rig(DATA / "nmrv030_rig.yaml")
TRO2021 = load_rig(DATA / "tro2021_worm_rig.yaml")


@pytest.mark.parametrize("rig", [NMRV030, TRO2021], ids=["nmrv030", "tro2021"])
def test_sigmas_are_noise_and_quantisation(rig) -> None:
    """speed: sqrt(tacho_noise_std^2 + tacho_drive_lsb^2 / 12); current: sqrt(current_noise_std^2 +
    current_lsb^2 / 12); the thresholds STILL_SIGMAS = 2 and KINETIC_SIGMAS = 5 of the speed sigma."""
    s = rig.sensors
    assert speed_sigma(rig) == pytest.approx(math.sqrt(s.tacho_noise_std ** 2 + s.tacho_drive_lsb ** 2 / 12), rel=1e-15)
    assert current_sigma(rig) == pytest.approx(math.sqrt(s.current_noise_std ** 2 + s.current_lsb ** 2 / 12),
                                               rel=1e-15)
    assert (STILL_SIGMAS, KINETIC_SIGMAS) == (2.0, 5.0)
    assert standstill_speed(rig) == pytest.approx(2.0 * speed_sigma(rig), rel=1e-15)
    assert kinetic_speed(rig) == pytest.approx(5.0 * speed_sigma(rig), rel=1e-15)


def test_the_figures_the_docstring_states() -> None:
    """The NMRV030 rig's tacho: 0.57 rad/s, standing below 1.1 rad/s, kinetic above 2.9 rad/s (to the digits
    stated); a drive with a 0.13 rad/s speed noise (no quantisation): kinetic 0.65 rad/s, and at 10 rpm it moves."""
    assert round(speed_sigma(NMRV030), 2) == 0.57
    assert round(standstill_speed(NMRV030), 1) == 1.1
    assert round(kinetic_speed(NMRV030), 1) == 2.9
    quiet = replace(NMRV030, sensors=replace(NMRV030.sensors, tacho_noise_std=0.13, tacho_drive_lsb=0.0))
    assert kinetic_speed(quiet) == pytest.approx(0.65)
    assert 10 * 2 * math.pi / 60 > standstill_speed(quiet)


def test_thresholds_follow_the_sensors() -> None:
    """Change one sensor figure and only its threshold moves, by the formula: the tacho noise and the drive
    tacho's step set the speeds (the load tacho's step does not), the current noise and step the current."""
    s = NMRV030.sensors
    noisier = replace(NMRV030, sensors=replace(s, tacho_noise_std=2.0 * s.tacho_noise_std))
    expected = math.sqrt((2.0 * s.tacho_noise_std) ** 2 + s.tacho_drive_lsb ** 2 / 12)
    assert speed_sigma(noisier) == pytest.approx(expected) and speed_sigma(noisier) > 1.7 * speed_sigma(NMRV030)
    assert standstill_speed(noisier) == pytest.approx(2.0 * expected)
    assert kinetic_speed(noisier) == pytest.approx(5.0 * expected)
    assert current_sigma(noisier) == current_sigma(NMRV030)

    coarse = replace(NMRV030, sensors=replace(s, tacho_noise_std=0.0, tacho_drive_lsb=1.2))
    assert speed_sigma(coarse) == pytest.approx(1.2 / math.sqrt(12))
    other_shaft = replace(NMRV030, sensors=replace(s, tacho_load_lsb=100.0 * s.tacho_load_lsb))
    assert speed_sigma(other_shaft) == speed_sigma(NMRV030)

    current = replace(NMRV030, sensors=replace(s, current_noise_std=0.1, current_lsb=0.0))
    assert current_sigma(current) == pytest.approx(0.1) and speed_sigma(current) == speed_sigma(NMRV030)
    stepped = replace(NMRV030, sensors=replace(s, current_noise_std=0.0))
    assert current_sigma(stepped) == pytest.approx(s.current_lsb / math.sqrt(12))
    silent = replace(NMRV030, sensors=replace(s, tacho_noise_std=0.0, tacho_drive_lsb=0.0))
    assert standstill_speed(silent) == 0.0 and kinetic_speed(silent) == 0.0
