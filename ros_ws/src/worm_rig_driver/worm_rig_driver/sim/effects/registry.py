"""The registry: every effect the simulator knows, by name (as rosbags finds its storage plug-ins)."""
from __future__ import annotations

from worm_rig_driver.sim.effects.aging import LubricantLoss, SealDrag, Wear
from worm_rig_driver.sim.effects.drags import BearingCoulomb, ViscousDrag
from worm_rig_driver.sim.effects.hooks import EffectBase
from worm_rig_driver.sim.effects.mesh import Backlash, InertiaError, LoadDependentMu, OilTemperature, SpeedDependentMu
from worm_rig_driver.sim.effects.ripples import GearRunout, MotorCogging, ToothPass, WormRunout
from worm_rig_driver.sim.effects.sensing import Pwm, SensorGain, SensorOffset

#: effect name -> class; the names are those of physics.md section 9 (plus the PWM), then the aging effects
EFFECTS: dict[str, type[EffectBase]] = {cls.name: cls for cls in (
    BearingCoulomb, ViscousDrag, SpeedDependentMu, LoadDependentMu, OilTemperature, WormRunout, ToothPass,
    GearRunout, MotorCogging, Backlash, SensorGain, SensorOffset, InertiaError, Pwm, Wear, LubricantLoss, SealDrag)}
