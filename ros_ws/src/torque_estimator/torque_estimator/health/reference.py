"""The health check's reference run: a few constant speeds per direction, each at a few held loads (no ROS).

A timeline of identification.excitation.Ramp segments, walked by the same machinery as ``identify``
(session.recording on the rig's sample clock; session.recording_node over the graph;
identification.simulated in this process). At each of ``speeds`` worm speeds per direction the
load goes through ``loads`` (fractions of what the load motors can make, Rig.max_load_torque),
snaking up at one speed and down at the next so that no load step is larger than one level;
each level is held ``hold`` seconds (the points' settle blocks cover the dip after a step, the
rest is averaged). Between speeds the speed ramps in ``change`` seconds under the load in force;
the change of direction ramps through zero unloaded; the run ends stopped and unloaded.

Both flanks are engaged at every speed when the loads span both signs (resistive and
assistive: mu and the drive- and gear-side drags separate, physics.md section 5, and the
transmission error shows the backlash). A robot without load motors runs it with
``loads=(0.0,)`` (no load: the drags and mu's speed law are watched, mu's scale and load slope
stay at the baseline's) or with its known load.

The default takes 27.5 s of rig time.
"""
from __future__ import annotations

from worm_model.physics.parameters import Rig

from torque_estimator.identification.excitation import Ramp, total_duration

#: worm speeds per direction [rad/s]
SPEEDS = (60.0, 160.0, 300.0)
#: load levels, fractions of Rig.max_load_torque
LOADS = (-0.9, -0.5, -0.1, 0.3, 0.9)
#: seconds each load level is held
HOLD = 0.8
#: seconds of a speed change
CHANGE = 0.5
#: the longest run a check may take [s] (the issue's "under ~30 s")
MAX_DURATION = 30.0


def reference_run(rig: Rig, speeds=SPEEDS, loads=LOADS, hold: float = HOLD, change: float = CHANGE,
                  load_scale: float = 1.0) -> tuple[Ramp, ...]:
    """The check's timeline (module docstring).

    Args:
        speeds: worm speeds per direction [rad/s], > 0.
        loads: load levels as fractions of Rig.max_load_torque, each in [-1, 1].
        load_scale: multiplies every load level (e.g. a rig whose load motors are weaker today).

    Raises:
        ValueError: no speed, a speed <= 0, no load, a load fraction outside [-1, 1], hold or change <= 0.
    """
    if not speeds or min(speeds) <= 0 or not loads or max(abs(f) for f in loads) > 1.0 or hold <= 0 or change <= 0:
        raise ValueError("need speeds > 0, load fractions in [-1, 1], hold > 0 and change > 0")
    top = rig.max_load_torque * load_scale
    levels = [f * top for f in loads]
    out: list[Ramp] = []
    speed, load = 0.0, 0.0
    k = 0
    for direction in (1.0, -1.0):
        for level_speed in speeds:
            target = direction * level_speed
            order = levels if k % 2 == 0 else levels[::-1]
            if speed * target <= 0.0:  # from rest or through zero: unloaded
                out.append(Ramp(2 * change, speed, target, 0.0, 0.0, f"to {target:g} rad/s, unloaded"))
                load = 0.0
            else:
                out.append(Ramp(change, speed, target, load, load, f"to {target:g} rad/s"))
            for value in order:
                out.append(Ramp(hold, target, target, value, value, f"load {value:+.3f} N m at {target:g} rad/s"))
            speed, load = target, order[-1]
            k += 1
    out.append(Ramp(change, speed, 0.0, 0.0, 0.0, "stop"))
    return tuple(out)


__all__ = ["CHANGE", "HOLD", "LOADS", "MAX_DURATION", "SPEEDS", "reference_run", "total_duration"]
