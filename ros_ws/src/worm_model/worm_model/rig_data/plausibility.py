"""Rig data and calibration points checked against the rig they claim to come from, in one place.

A log exported in the wrong unit (t in ms, current in mA, speed in rpm, angles in degrees) is still
numbers, and every tool downstream would turn it into a result: an inertia error, a K_t 1000 times off,
a calibration at speeds the rig cannot reach. These checks refuse it first, naming the column and the
likely cause. :func:`check_rig_data` is applied by the one rig-data reader
(:func:`worm_model.rig_data.reader.read_rig_data`), so ``residuals``, ``identify --from``, ``estimate``,
``bag import`` and ``replay`` check alike; :func:`calibration_problem` by every reader of a calibration
database (``evaluate``, ``estimate``, ``report``, estimator_node, the rig's feedforward).

What is checked, against the rig file:

* the sample rate: the median step of ``t`` against the rig's ``sensors.sample_rate_hz``; a log may be
  decimated (up to :data:`MAX_DECIMATION` times slower) or faster (down to :data:`MIN_RATE_RATIO`), not
  1000 times off ("t looks like milliseconds: median step 1 at a 1 kHz rig");
* every channel against what the rig can do (worm_model.physics.envelope.Envelope: the no-load speed, the
  stall current, the supply), with the unit that would bring it inside named (mA, rpm, mN m, ...);
* the worm angle against the integral of the worm speed: ``theta_worm`` must advance as
  ``omega_worm`` integrates, within :data:`ANGLE_TOLERANCE` (degrees give 57.3 times, revolutions 1/6.28,
  a speed in rpm with the angle in rad 1/9.55);
* a calibration: two loads at least (a torque range to speak of), not every point the same, every point
  inside the envelope (speeds in rpm leave it).
"""
from __future__ import annotations

import math
from typing import Any, Final

import numpy as np

from worm_model.physics.envelope import MARGIN, Envelope
from worm_model.physics.motor import coulomb_friction
from worm_model.physics.steady_state import balancing_torque
from worm_model.rig_data.schema import MeasuredData
from worm_model.errors import RigDataError

#: a log whose median step of t is up to this many rig sample periods is a decimated log, not a unit slip
MAX_DECIMATION: Final = 100.0
#: a log may sample faster than the rig file says, down to this fraction of its period
MIN_RATE_RATIO: Final = 0.2
#: theta_worm's advance over the integral of omega_worm may differ from 1 by this fraction (tacho gain,
#: encoder quantisation, noise)
ANGLE_TOLERANCE: Final = 0.25
#: the angle check needs this much motion [rad] of the worm in the log (a few turns)
MIN_TRAVEL: Final = 4 * math.pi

#: unit slips per column: (unit the numbers would be in, factor to SI), tried in order
UNIT_SLIPS: Final[dict[str, tuple[tuple[str, float], ...]]] = {
    "omega_worm": (("rpm", 2 * math.pi / 60), ("deg/s", math.pi / 180)),
    "omega_gear": (("rpm", 2 * math.pi / 60), ("deg/s", math.pi / 180)),
    "current_drive": (("mA", 1e-3),),
    "current_load": (("mA", 1e-3),),
    "voltage_drive": (("mV", 1e-3),),
    "tau_load": (("mN m or N mm", 1e-3),),
}
#: units of t tried when its step does not fit the rig: name, seconds per unit
TIME_UNITS: Final = (("milliseconds", 1e-3), ("microseconds", 1e-6), ("nanoseconds", 1e-9))
#: what a ratio of theta's advance to omega's integral near these values means
ANGLE_SLIPS: Final = ((180 / math.pi, "theta_worm looks like degrees"),
                      (1 / (2 * math.pi), "theta_worm looks like revolutions"),
                      (2 * math.pi / 60, "omega_worm looks like rpm (theta_worm advances 9.55x slower "
                                         "than it integrates)"),
                      (180 / math.pi * 2 * math.pi / 60, "omega_worm looks like rpm and theta_worm like "
                                                         "degrees"),
                      (math.pi / 180, "omega_worm looks like deg/s"),
                      (-1.0, "theta_worm runs against omega_worm: their signs disagree"))


def _rate(hz: float) -> str:
    return f"{hz / 1000:g} kHz" if hz >= 1000 else f"{hz:g} Hz"


def sample_rate_problem(t: np.ndarray, rate_hz: float, rig_source: str = "") -> str | None:
    """Why the median step of ``t`` [s] does not fit a rig sampling at ``rate_hz``, or None."""
    steps = np.diff(np.asarray(t, dtype=float))
    steps = steps[np.isfinite(steps) & (steps > 0)]
    if not steps.size:
        return None
    step = float(np.median(steps))
    period = 1.0 / rate_hz
    ratio = step / period
    if MIN_RATE_RATIO <= ratio <= MAX_DECIMATION:
        return None
    rig = f" ({rig_source})" if rig_source else ""
    for name, seconds in TIME_UNITS:
        if MIN_RATE_RATIO <= step * seconds / period <= MAX_DECIMATION:
            return (f"t looks like {name}: median step {step:g} at a {_rate(rate_hz)} rig{rig} (a step of "
                    f"{period:g} s expected); convert t to seconds")
    return (f"median step of t {step:g} s is {ratio:.3g} x the rig's sample period {period:g} s "
            f"({_rate(rate_hz)}{rig}): t is not in seconds, or the rig file's sensors.sample_rate_hz is wrong")


def unit_slip(column: str, values: np.ndarray, envelope: Envelope) -> str:
    """`` (looks like mA: ...)`` when the values, converted from a likely wrong unit, fit the rig; else ""."""
    if column not in envelope.limits:
        return ""
    finite = np.abs(np.asarray(values, dtype=float))
    finite = finite[np.isfinite(finite)]
    if not finite.size:
        return ""
    largest = float(np.max(finite))
    limit, unit = envelope.limits[column]
    for name, factor in UNIT_SLIPS.get(column, ()):
        if largest * factor <= limit / MARGIN:
            return f"; {column} looks like {name} ({largest:g} {name} = {largest * factor:.4g} {unit})"
    return ""


def envelope_problem(data: MeasuredData, envelope: Envelope) -> RigDataError | None:
    """The first sample far outside what the rig can do (with the likely unit slip), or None."""
    for name in data.names:
        values = getattr(data, name)
        k = envelope.first_outside(name, values)
        if k is None:
            continue
        problem = envelope.problem(name, float(values[k])) + unit_slip(name, values, envelope)
        if data.lines is not None:  # a folder of files: the file of the sample's run
            source = data.run_sources[int(data.run[k])] if data.run_sources else data.source
            return RigDataError(source, problem, int(data.lines[k]), name)
        return RigDataError(data.source, f"sample {k}: {problem}", column=name)
    return None


def angle_problem(data: MeasuredData, min_speed: float) -> str | None:
    """Why ``theta_worm`` does not advance as ``omega_worm`` integrates, or None (also when too little motion)."""
    t, omega, theta = data.t, data.omega_worm, data.theta_worm
    same_run = data.run[1:] == data.run[:-1]
    dt = np.diff(t)
    mean_omega = 0.5 * (omega[1:] + omega[:-1])
    step = np.diff(theta)
    with np.errstate(divide="ignore", invalid="ignore"):
        fast = (np.abs(mean_omega) >= min_speed) | (np.abs(step / dt) >= min_speed)  # moving by either
    moving = same_run & np.isfinite(mean_omega) & np.isfinite(step) & fast
    travel = (mean_omega * dt)[moving]
    advance = step[moving]
    if max(float(np.sum(np.abs(travel))), float(np.sum(np.abs(advance)))) < MIN_TRAVEL:
        return None
    power = float(np.dot(travel, travel))
    ratio = float(np.dot(advance, travel) / power) if power > 0 else math.inf
    if abs(ratio - 1.0) <= ANGLE_TOLERANCE:
        return None
    cause = next((text for value, text in ANGLE_SLIPS if abs(ratio / value - 1.0) <= ANGLE_TOLERANCE), "")
    return (f"theta_worm advances {ratio:.3g} x as far as omega_worm integrates (1 expected: theta in rad, "
            f"omega in rad/s)" + (f"; {cause}" if cause else ""))


def check_rig_data(data: MeasuredData, rig: Any) -> None:
    """Refuse rig data whose units do not fit ``rig`` (a worm_model.physics.parameters.Rig); see the module.

    Raises:
        RigDataError: fewer than 2 samples, a sample rate far from the rig's, a value far outside what the
            rig can do, or an angle that does not follow the speed; the message names the column and the
            likely cause.
    """
    if len(data) < 2:
        raise RigDataError(data.source, f"{len(data)} sample(s): a log needs 2 at least (one sample has no "
                                        "sample period)")
    rig_source = getattr(rig, "name", "")
    problem = sample_rate_problem(data.t, rig.sensors.sample_rate_hz, rig_source)
    if problem:
        raise RigDataError(data.source, problem, column="t")
    envelope = Envelope.of(rig)
    error = envelope_problem(data, envelope)
    if error is not None:
        raise error
    no_load = rig.supply_voltage / rig.drive_motor.back_emf_constant
    problem = angle_problem(data, 0.02 * no_load)
    if problem:
        raise RigDataError(data.source, problem, column="theta_worm")


def calibration_problem(omega: Any, current: Any, tau: Any, rig: Any | None = None) -> str | None:
    """Why calibration points (omega_worm [rad/s], current_drive [A], tau_load [N m]) are unusable, or None.

    Refused: no point; every point the same operating point; no torque range (every point at one load:
    errors are in % of that range and the k-NN map has nothing to interpolate); with ``rig``, a point far
    outside what it can do (speeds in rpm, currents in mA, with the unit named), and torques whose sign
    contradicts the currents (:func:`torque_sign_problem`).
    """
    columns = {"omega_worm": np.asarray(omega, dtype=float), "current_drive": np.asarray(current, dtype=float),
               "tau_load": np.asarray(tau, dtype=float)}
    n = len(columns["tau_load"])
    if n == 0:
        return "no calibration points"
    if rig is not None:
        envelope = Envelope.of(rig)
        for name, values in columns.items():
            k = envelope.first_outside(name, values)
            if k is not None:
                return (f"field 'points.{name}' at point {k}: {envelope.problem(name, float(values[k]))}"
                        + unit_slip(name, values, envelope))
    points = np.column_stack(list(columns.values()))
    if n > 1 and np.all(points == points[0]):
        return f"all {n} points are the same operating point ({', '.join(f'{v:g}' for v in points[0])})"
    span = float(np.max(columns["tau_load"]) - np.min(columns["tau_load"]))
    if not span > 0:
        return (f"its {n} point(s) span no torque range (every tau_load {columns['tau_load'][0]:g} N m): errors "
                "are in % of that range and the map has no load to interpolate; calibrate at two loads at least")
    if rig is not None:
        return torque_sign_problem(rig, columns["omega_worm"], columns["current_drive"], columns["tau_load"])
    return None


#: the rig's steady current must fit the points this many times better with their torques negated to refuse them
SIGN_FLIP_FACTOR: Final = 2.0


def torque_sign_problem(rig: Any, omega: np.ndarray, current: np.ndarray, tau: np.ndarray) -> str | None:
    """Why points' tau_load [N m] cannot be the load their currents [A] carried at their speeds [rad/s] on
    ``rig``, or None: the rig's steady current (Eq. 28 at a_w = 0 and the motor's drags, over K_t) fits them
    SIGN_FLIP_FACTOR times better with every torque negated (the sign convention: tau_load positive opposes
    positive worm rotation). A model error shifts or scales the fit; it does not turn it over."""
    motor = rig.drive_motor
    drag = coulomb_friction(motor, omega) + motor.viscous_drag * omega

    def rms(load: np.ndarray) -> float:
        return float(np.sqrt(np.mean(((balancing_torque(rig, load, omega) + drag) / motor.torque_constant
                                      - current) ** 2)))

    as_given, negated = rms(tau), rms(-tau)
    if negated * SIGN_FLIP_FACTOR < as_given:
        return (f"field 'points.tau_load': the torques have the sign opposite to the currents for this rig: the "
                f"rig's steady current fits them {as_given / negated:.1f} x better with every tau_load negated "
                f"(rms {as_given:.3g} A as given, {negated:.3g} A negated); tau_load is positive when the load "
                "opposes positive worm rotation (is the load cell's sign reversed?)")
    return None
