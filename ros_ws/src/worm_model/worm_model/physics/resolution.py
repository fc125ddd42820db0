"""What a rig's own sensors resolve: the thresholds every tool takes from the rig file, not from one rig's size.

A speed, a current or a torque is "small" only against what the drive's sensors can tell from
nothing: the rig file's ``sensors:`` section (measured on a recording by ``identify``, or declared).

* :func:`speed_sigma` [rad/s]: one speed sample's spread, sqrt(tacho_noise_std^2 + tacho_drive_lsb^2 / 12)
  (noise and the ADC's or encoder's step as uniform quantisation);
* :func:`standstill_speed` [rad/s]: below STILL_SIGMAS of it a worm counts as standing: its speed is
  no different from 0 by more than the sensor's own noise (a drive at 10 rpm with a 0.13 rad/s
  speed noise moves; the NMRV030 rig's tacho, 0.57 rad/s, stands below 1.1 rad/s);
* :func:`kinetic_speed` [rad/s]: above KINETIC_SIGMAS of it a worm slides for the kinetic model (Eq. 28:
  friction in motion) to hold sample by sample: its speed is clear of 0 and known to about a fifth
  (the NMRV030 rig: 2.9 rad/s; a drive with a 0.13 rad/s speed noise: 0.65 rad/s);
* :func:`current_sigma` [A]: one current sample's spread, sqrt(current_noise_std^2 + current_lsb^2 / 12).

Units SI. No ROS.
"""
from __future__ import annotations

import math

from worm_model.physics.parameters import Rig

#: a worm stands when its speed is within this many speed sigmas of 0 (the momentum observer's STILL_SIGMAS)
STILL_SIGMAS = 2.0
#: a worm's samples are kinetic (the model of friction in motion holds for each) beyond this many speed sigmas
KINETIC_SIGMAS = 5.0


def speed_sigma(rig: Rig) -> float:
    """One speed sample's standard deviation [rad/s] (module docstring)."""
    s = rig.sensors
    return math.sqrt(s.tacho_noise_std ** 2 + s.tacho_drive_lsb ** 2 / 12.0)


def standstill_speed(rig: Rig) -> float:
    """[rad/s] below which the worm counts as standing (module docstring)."""
    return STILL_SIGMAS * speed_sigma(rig)


def kinetic_speed(rig: Rig) -> float:
    """[rad/s] above which a worm's samples are kinetic (module docstring)."""
    return KINETIC_SIGMAS * speed_sigma(rig)


def current_sigma(rig: Rig) -> float:
    """One drive-current sample's standard deviation [A] (module docstring)."""
    s = rig.sensors
    return math.sqrt(s.current_noise_std ** 2 + s.current_lsb ** 2 / 12.0)


__all__ = ["KINETIC_SIGMAS", "STILL_SIGMAS", "current_sigma", "kinetic_speed", "speed_sigma", "standstill_speed"]
