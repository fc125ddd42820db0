"""The excitation of an identification run: a timeline of worm-speed and load set-points (no ROS).

Unlike calibration, nothing waits for a point to settle: the set-points move all the time
and every sample is fitted (residuals' model has the inertia term, so transients are data,
not waste).  What the fit needs to see, and how the default timeline gives it:

* the static map i(omega, tau_d) over the whole range the estimators are used in: at each of
  ``speed_levels`` worm speeds per direction (20..340 rad/s, the calibration grid's span, with
  the low speeds denser: the Stribeck rise and the drags' share are largest there), the load
  goes across the load motors' range (+-``load_fraction`` x Rig.max_load_torque) up in a
  staircase of ``load_steps`` levels and back down in a ramp; both flanks and all three modes
  are crossed at every speed, both ways;
* inertia and the flank changes: every other speed change is a step, the rest are ramps; the
  change of direction is a slow ramp through zero (+20 -> -20 rad/s), and near the end a fast
  reversal (-340 -> +150 rad/s) under load;
* the end: a ramp to standstill with no load, so the rig is left stopped.

Each segment holds or ramps linearly from its start to its end values.  :func:`default_excitation`
scales every duration to fit ``duration`` seconds of rig time (85 s by default; the issue allows 90).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worm_model.physics.parameters import Rig

#: default rig time of the excitation [s] (at most MAX_DURATION)
DEFAULT_DURATION = 85.0
#: the longest excitation the identify CLI accepts [s]
MAX_DURATION = 90.0
#: worm speeds [rad/s] of the load sweeps, per direction (the calibration grid spans 20..340)
SPEED_LEVELS = (20.0, 60.0, 110.0, 170.0, 230.0, 290.0, 340.0)


@dataclass(frozen=True)
class Ramp:
    """Go linearly from (speed_start, load_start) to (speed_end, load_end) in ``duration`` [s].

    Speeds are worm speeds [rad/s]; loads are load torques on the gear [N m], positive opposing
    positive rotation.  A step is a ramp whose start values differ from the previous end values.
    """

    duration: float
    speed_start: float
    speed_end: float
    load_start: float
    load_end: float
    label: str = ""

    def at(self, t: float) -> tuple[float, float]:
        """(speed, load) set-points at ``t`` [s] from the segment's start (clamped to it)."""
        f = min(1.0, max(0.0, t / self.duration)) if self.duration > 0 else 1.0
        return (self.speed_start + f * (self.speed_end - self.speed_start),
                self.load_start + f * (self.load_end - self.load_start))

    def to_dict(self) -> dict:
        return {"duration": self.duration, "speed_start": self.speed_start, "speed_end": self.speed_end,
                "load_start": self.load_start, "load_end": self.load_end, "label": self.label}


def total_duration(timeline) -> float:
    """Rig time [s] of a timeline."""
    return float(sum(s.duration for s in timeline))


def _base_timeline(load: float, levels, load_steps: int, sweep: float, change: float) -> list[Ramp]:
    out: list[Ramp] = []
    previous = 0.0
    for direction in (1.0, -1.0):
        for k, level in enumerate(levels):
            speed = direction * level
            if k == 0 and direction < 0:  # the change of direction: a slow ramp through zero, unloaded
                out.append(Ramp(2 * change, previous, speed, 0.0, -load, "reversal ramp"))
            elif k % 2 == 0:
                out.append(Ramp(change, speed, speed, -load, -load, f"speed step to {speed:g}"))
            else:
                out.append(Ramp(change, previous, speed, -load, -load, f"speed ramp to {speed:g}"))
            step = sweep / 2 / load_steps
            for j in range(load_steps):
                value = -load + 2 * load * (j + 1) / load_steps
                out.append(Ramp(step, speed, speed, value, value, f"load level {value:+.3f} at {speed:g}"))
            out.append(Ramp(sweep / 2, speed, speed, load, -load, f"load ramp down at {speed:g}"))
            previous = speed
    out.append(Ramp(change, previous, 150.0, 0.5 * load, 0.5 * load, "fast reversal under load"))
    out.append(Ramp(change, 150.0, 150.0, 0.5 * load, -0.5 * load, "load reversal"))
    out.append(Ramp(change, 150.0, 0.0, 0.0, 0.0, "stop"))
    return out


def default_excitation(rig: Rig, duration: float = DEFAULT_DURATION, levels=SPEED_LEVELS, load_steps: int = 5,
                       load_fraction: float = 0.9) -> tuple[Ramp, ...]:
    """The default timeline (module docstring), its durations scaled to ``duration`` [s] of rig time.

    Raises:
        ValueError: duration <= 0, no speed level, a level <= 0, load_steps < 1, load_fraction outside (0, 1].
    """
    if not (duration > 0 and math.isfinite(duration)) or not levels or min(levels) <= 0 or load_steps < 1 \
            or not 0 < load_fraction <= 1:
        raise ValueError("need duration > 0, speed levels > 0, load_steps >= 1 and 0 < load_fraction <= 1")
    base = _base_timeline(load_fraction * rig.max_load_torque, levels, load_steps, sweep=5.5, change=0.4)
    scale = duration / total_duration(base)
    return tuple(Ramp(s.duration * scale, s.speed_start, s.speed_end, s.load_start, s.load_end, s.label)
                 for s in base)


def setpoints(timeline, t: float) -> tuple[float, float] | None:
    """(speed, load) set-points at ``t`` [s] from the timeline's start; None after its end."""
    start = 0.0
    for segment in timeline:
        if t < start + segment.duration:
            return segment.at(t - start)
        start += segment.duration
    return None


def sampled(timeline, period: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(segment index, speed, load) per sample of ``period`` [s]: the set-points in force during each
    sample period, as recording.ExcitationRun walks them (segment k starts at the sample
    round(start_k / period); its set-points are taken at whole periods from there)."""
    index, speed, load = [], [], []
    start = 0.0
    for k, segment in enumerate(timeline):
        first, last = int(round(start / period)), int(round((start + segment.duration) / period))
        t = np.arange(last - first) * period
        values = np.array([segment.at(x) for x in t]).reshape(-1, 2)
        index.append(np.full(len(t), k))
        speed.append(values[:, 0])
        load.append(values[:, 1])
        start += segment.duration
    return np.concatenate(index), np.concatenate(speed), np.concatenate(load)


__all__ = ["DEFAULT_DURATION", "MAX_DURATION", "Ramp", "SPEED_LEVELS", "default_excitation", "sampled",
           "setpoints", "total_duration"]
