"""Profiles for the foreign drives, recordings made from them, and the ``worm_rig_data`` CSV writer.

Each profile function returns a simulated :class:`~.plant.Recording` (the CSV's columns plus the truth behind
them); ``write_csv`` writes it. The profiles are seeded: the same arguments give the same recording, sample for
sample.

- ``excitation(drive, seconds, seed)``: for identification. Speed set-points stepping among +-(w_min..w_max)
  (w_max = 65 % of the no-load speed supply / K_e, w_min = w_max 40 / 300: 40..300 rad/s for foreign30), with
  ramps (accelerations 25-100 % of what half the rated torque gives) and reversals (half of the steps change
  sign), held 1-3 s each; the load, independently, stepping among levels in -0.5..1.5 x the drive's load_scale
  (-0.5..1.5 N m for foreign30), held 1-3 s each.
- ``validation(drive, seconds, seed)``: the same kind, from another random stream (the same seed gives a
  different profile than ``excitation``'s).
- ``start_stop(drive, load, speed)``: rest, lower at -speed, stop, rest, lift at +speed, stop, rest, under a
  constant hanging load (+ opposes + rotation), like an EPOS start-stop run in velocity mode.
- ``steady(drive, speed, load, seconds)``: ramp to a speed and hold it under a constant load.
- ``released(drive, load, seconds)``: at rest, motor open circuit (no current), a constant load on the output.

CLI::

    python -m torque_estimator.evaluation.foreign.recordings --drive foreign30 --kind excitation --seconds 240 \
        --seed 1 --out f.csv
"""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from torque_estimator.evaluation.foreign.drives import DRIVES, ForeignDrive
from torque_estimator.evaluation.foreign.plant import OPEN, Profile, Recording, driving_inertia, simulate

HEADER = ("t", "current_drive", "omega_worm", "theta_worm", "tau_load", "voltage_drive")
"""The CSV's columns, in order (the ``worm_rig_data`` schema's required ones plus voltage_drive)."""
START_REST = 0.2
"""[s] at rest at the start of an excitation or validation profile."""


def speed_range(drive: ForeignDrive) -> tuple[float, float]:
    """(w_min, w_max) [rad/s] of the excitation's set-points."""
    w_max = 0.65 * drive.no_load_speed
    return w_max * 40.0 / 300.0, w_max


def max_acceleration(drive: ForeignDrive) -> float:
    """[rad/s^2] the fastest set-point ramp: half the rated motor torque on the driving-flank inertia."""
    return 0.5 * drive.torque_constant * drive.rated_current / driving_inertia(drive)


def _samples(drive: ForeignDrive, seconds: float) -> tuple[int, np.ndarray]:
    n = int(round(seconds * drive.sample_rate)) + 1
    return n, np.arange(n) / drive.sample_rate


def _steps(drive: ForeignDrive, seconds: float, rng: np.random.Generator, name: str) -> Profile:
    n, t = _samples(drive, seconds)
    w_min, w_max = speed_range(drive)
    a_max = max_acceleration(drive)
    # speed: piecewise linear through knots (ramp, hold, ramp, hold, ...)
    times, values = [0.0, START_REST], [0.0, 0.0]
    now, level = START_REST, 0.0
    while now < seconds:
        sign = (1.0 if rng.random() < 0.5 else -1.0) if level == 0.0 else \
            (-np.sign(level) if rng.random() < 0.5 else np.sign(level))
        new = float(sign * rng.uniform(w_min, w_max))
        ramp = abs(new - level) / (rng.uniform(0.25, 1.0) * a_max)
        hold = rng.uniform(1.0, 3.0)
        times += [now + ramp, now + ramp + hold]
        values += [new, new]
        now, level = now + ramp + hold, new
    speed_ref = np.interp(t, times, values)
    # load: steps, independently
    starts, levels = [], []
    now = 0.0
    while now <= seconds:
        starts.append(now)
        levels.append(float(rng.uniform(-0.5, 1.5) * drive.load_scale))
        now += rng.uniform(1.0, 3.0)
    load = np.asarray(levels)[np.searchsorted(np.asarray(starts), t, side="right") - 1]
    return Profile.speed(speed_ref, load, name)


def excitation(drive: ForeignDrive, seconds: float, seed: int) -> Recording:
    """An identification recording: speed and load steps in random order (module docstring)."""
    profile = _steps(drive, seconds, np.random.default_rng([seed, 1]), f"excitation seed {seed}")
    return simulate(drive, profile, (seed, 101))


def validation(drive: ForeignDrive, seconds: float, seed: int) -> Recording:
    """A recording of the same kind as ``excitation`` from another random stream, to estimate on."""
    profile = _steps(drive, seconds, np.random.default_rng([seed, 2]), f"validation seed {seed}")
    return simulate(drive, profile, (seed, 102))


def _knots(drive: ForeignDrive, knots: list[tuple[float, float]]) -> tuple[int, np.ndarray, np.ndarray]:
    """(n, t, speed_ref) through (duration, speed) knots: each duration is the linear move to that speed."""
    times, values, now = [0.0], [0.0], 0.0
    for duration, value in knots:
        now += duration
        times.append(now)
        values.append(value)
    n, t = _samples(drive, now)
    return n, t, np.interp(t, times, values)


def start_stop(drive: ForeignDrive, load: float, speed: float, rest: float = 1.0, hold: float = 3.0,
               ramp: float = 0.25, seed: int = 0) -> Recording:
    """Rest, lower at -speed, stop, rest, lift at +speed, stop, rest; a constant hanging load [N m]."""
    speed = abs(speed)
    n, _, ref = _knots(drive, [(rest, 0.0), (ramp, -speed), (hold, -speed), (ramp, 0.0), (rest, 0.0),
                               (ramp, speed), (hold, speed), (ramp, 0.0), (rest, 0.0)])
    profile = Profile.speed(ref, np.full(n, float(load)), f"start-stop {speed:g} rad/s, load {load:g} N m")
    return simulate(drive, profile, (seed, 103))


def steady(drive: ForeignDrive, speed: float, load: float, seconds: float, ramp: float = 0.3,
           seed: int = 0) -> Recording:
    """Ramp from rest to ``speed`` in ``ramp`` s, then hold it for ``seconds``; a constant load [N m]."""
    n, _, ref = _knots(drive, [(ramp, speed), (seconds, speed)])
    profile = Profile.speed(ref, np.full(n, float(load)), f"steady {speed:g} rad/s, load {load:g} N m")
    return simulate(drive, profile, (seed, 104))


def released(drive: ForeignDrive, load: float, seconds: float, seed: int = 0) -> Recording:
    """From rest, the motor open circuit (no current), a constant load on the output [N m]."""
    n, _ = _samples(drive, seconds)
    profile = Profile(np.zeros(n), np.full(n, float(load)), np.full(n, OPEN), np.zeros(n),
                      f"released, load {load:g} N m")
    return simulate(drive, profile, (seed, 105))


def write_csv(path: str | Path, samples: Recording | Mapping[str, Any]) -> None:
    """Write the samples as a ``worm_rig_data`` CSV: header ``t,current_drive,omega_worm,theta_worm,tau_load,
    voltage_drive``, one row per sample, floats as repr().

    ``samples``: a Recording, or a mapping of those six column names to equal-length sequences.
    """
    get = samples.__getitem__ if isinstance(samples, Mapping) else lambda name: getattr(samples, name)
    columns = [np.asarray(get(name), dtype=float).tolist() for name in HEADER]
    if len({len(c) for c in columns}) != 1:
        raise ValueError("columns of different lengths")
    with Path(path).open("w", newline="", encoding="utf-8") as handle:
        handle.write(",".join(HEADER) + "\n")
        for row in zip(*columns):
            handle.write(",".join(repr(v) for v in row) + "\n")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m torque_estimator.evaluation.foreign.recordings",
                                description="Write a recording of a foreign worm drive as a worm_rig_data CSV.")
    p.add_argument("--drive", choices=sorted(DRIVES), required=True)
    p.add_argument("--kind", choices=("excitation", "validation", "start_stop", "steady", "released"),
                   default="excitation")
    p.add_argument("--seconds", type=float, default=60.0, help="length (excitation, validation, steady, released)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--load", type=float, default=None, help="[N m] (start_stop, steady, released; default "
                                                            "the drive's load_scale)")
    p.add_argument("--speed", type=float, default=None, help="[rad/s] (start_stop, steady; default a third of "
                                                             "the excitation's top speed)")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    drive = DRIVES[args.drive]
    load = drive.load_scale if args.load is None else args.load
    speed = speed_range(drive)[1] / 3.0 if args.speed is None else args.speed
    began = time.perf_counter()
    if args.kind in ("excitation", "validation"):
        rec = (excitation if args.kind == "excitation" else validation)(drive, args.seconds, args.seed)
    elif args.kind == "start_stop":
        rec = start_stop(drive, load, speed, seed=args.seed)
    elif args.kind == "steady":
        rec = steady(drive, speed, load, args.seconds, seed=args.seed)
    else:
        rec = released(drive, load, args.seconds, seed=args.seed)
    write_csv(args.out, rec)
    print(f"{args.out}: {drive.name} {rec.profile}, {len(rec)} samples at {drive.sample_rate:g} Hz, "
          f"{time.perf_counter() - began:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
