"""Model-based τ_d estimator: invert the extended model's quasi-static current.

Units and signs as :mod:`torque_estimator.estimation.database`: ω_w [rad/s], i [A]
(the inertia-compensated drive current, as LiveEstimator hands it over), τ_d [N·m]
positive opposing positive worm rotation.

The model is a worm_model ``ExtendedModel`` read from a parameter file written by
``residuals`` (rig sections + ``effects:``); without a file it is the rig with no
effects, i.e. the paper's model (Eqs 28–30).

The load prior (``load_min``, ``load_max`` [N·m], branches.LoadPrior): declared, the table spans
it, so no candidate outside it is ever found (a current it cannot explain is extrapolated and
flagged OUT_OF_CALIBRATION); not declared (both 0), the table's range below stands in.

Construction (once): the model's drive current i(ω, τ_d) at α = 0 is tabulated on a
uniform grid per rotation direction: |ω| in [0, ω_max] (``speed_points`` at least; −|ω| on the
negative side, −1e−9 at 0), τ_d over [τ_min, τ_max] (``torque_points``).  The ranges
(:func:`model_ranges`) come from the model file's ``identification:`` section when it
has one (what ``identify`` recorded), else from the calibration database (largest |ω|,
[min τ_load, max τ_load]), else from the rig (the no-load speed at the supply voltage,
± the load motors' torque): no calibration database is needed.
Periodic effects (runout, tooth-pass, cogging ripple) are averaged out: when the model
has any, every entry is the mean current over A worm angles spread evenly over one gear
turn, A ≥ ``angles`` (7) the smallest count that no harmonic of the model aliases onto the
mean or the first gear harmonic (:func:`angle_count`: a harmonic of order q per gear turn
sampled at A even phases shows as order q mod A; the NMRV030's are 1 (gear runout), 30
(worm runout, tooth-pass) and 14 · 30 = 420 (the motor's cogging), and 420 = 7 · 60 would
have put the cogging ripple's value at θ = 0 into every entry with A = 7: A = 8); without
periodic effects θ = 0 is used. The thermal effect is evaluated at its reference oil temperature
(every table entry is its own run, so the first-order warming is 0).

Ripple slower than the averaging: the first harmonic per gear turn (gear runout) is not averaged
out by a live estimate or a 0.5 s window at low speed (at 20 rad/s the gear turns 0.33 rad in
0.5 s), so when the worm angle is given (``estimate(..., theta_worm=)``, the encoder), its
current is taken out: the A table angles are A gear phases 2πj/A, and their discrete Fourier
coefficients give c₁(ω, τ_d), s₁(ω, τ_d) [A], the current's first gear harmonic (no other
harmonic of the model aliases onto it, by the choice of A). The measured current
is corrected by −(c₁ cos φ + s₁ sin φ), φ = θ_worm × ratio the gear angle, at a first estimate,
and inverted again. θ given as an extra trailing axis (a window's samples) uses the window's
mean cos φ and sin φ, i.e. the window's mean ripple. The phase is the identification's: the
encoder's origin must be the one ``identify`` recorded from (the simulated rig, which starts
at 0; on a real rig without an index pulse, the same power cycle), else pass no angle.

Per sample (ω, i):

1. Direction σ = sign(ω), or sign(i) at ω = 0 (as the k-NN).
2. Column: the table's current along τ_d at |ω|, linear between the two bracketing
   speed rows (bilinear overall). The rows are spaced no wider than a quarter of the model's
   own smallest speed scale (:func:`speed_scale`: a low-speed rise) and go on past ω_max at the same
   spacing to SPEED_EXTRAPOLATION × ω_max: |ω| > ω_max is the model extrapolated, OUT_OF_CALIBRATION
   (beyond the table's end, its edge row).
3. Crossings of i along the column, each solved linearly inside its τ_d cell.
   One: that τ_d. Several (self-locking V, physics.md §8: two loads draw the same
   current): AMBIGUOUS; the estimate is the crossing with the largest σ·τ_d (the load
   opposing the motion most, the driving flank), the other candidate (``other``) the crossing
   farthest from it, and the uncertainty reaches it. Which of the two is the load is the
   caller's to tell (LiveEstimator's branches.BranchTracker: the motion, the prior).
   None: OUT_OF_CALIBRATION; i beyond an end of the column is extrapolated along
   the end cell's slope, i below the V's minimum (no load explains it) gives the
   τ_d of the minimum.
4. Uncertainty (1 sigma): u² = (σ_i / |∂i/∂τ_d|)² + (Δτ_table / √12)², σ_i =
   ``current_noise`` (default the rig's current_noise_std: a conservative figure for a
   smoothed live current) through the local slope, plus the table's τ_d step as a
   uniform quantisation: the chosen candidate's own; AMBIGUOUS, the other is ``other``, and a
   caller that reports the estimate as ambiguous widens u to reach it (LiveEstimator).
5. NaN/inf input: τ̂ = u = NaN, INVALID_INPUT; never raises. TRANSIENT is the caller's.
6. The load on the gear, not the load sensor's reading of it: a model fitted to logged data
   maps the current to the ``tau_load`` the rig's load-current sensors read.  When the model
   has identified their errors (``sensor_gain``/``sensor_offset`` effects, load_current parts),
   the estimate is taken back to the true load: τ = τ_read − (g_l τ_read + offset K_t,load count)
   (:class:`SensorCorrection`; the same first-order relation the residual model fits).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

import yaml

from worm_model.physics.envelope import Envelope
from worm_model.physics.parameters import Rig, load_rig
from worm_model.errors import ParameterError
from worm_model.residuals.extended import ExtendedModel

from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.base import EstimateFlags, TorqueEstimates
from torque_estimator.estimation.branches import LoadPrior

#: Fewest worm angles averaged per table entry when the model has periodic effects (angle_count).
ANGLES = 7
#: Table rows per the model's smallest speed scale (speed_scale), at least.
ROWS_PER_SPEED_SCALE = 4
#: Rows of the table at most up to the identified speed.
MAX_SPEED_ROWS = 4000
#: The table reaches this multiple of the identified speed (extrapolated there, flagged OUT_OF_CALIBRATION).
SPEED_EXTRAPOLATION = 1.5
#: Samples per batch of the vectorised inversion (bounds memory: batch × torque_points floats).
_BATCH = 4096
#: |ω| [rad/s] used for the ω = 0 row of the negative-direction table (the model reads ω < 0).
_NEGATIVE_ZERO = 1e-9


def speed_scale(model: ExtendedModel) -> float:
    """[rad/s of the worm] the smallest speed over which the model's friction changes: a support's low-speed rise
    (worm_model.physics.motor.coulomb_friction; the gear shaft's at the worm's speed) or the Stribeck tooth law's
    (its sliding speed at the worm); inf where it has none."""
    rig = model.rig
    gb = rig.gearbox
    scales = [math.inf]
    if rig.drive_motor.stribeck_rise > 0:
        scales.append(rig.drive_motor.stribeck_speed)
    if rig.load_motor.stribeck_rise > 0:
        scales.append(rig.load_motor.stribeck_speed / gb.ratio)
    if rig.friction.model == "stribeck" and rig.friction.stribeck_rise > 0:
        scales.append(rig.friction.stribeck_speed * math.cos(gb.lead_angle) / gb.worm_pitch_radius)
    return min(scales)


def gear_orders(model: ExtendedModel) -> list[float]:
    """Harmonic orders per gear turn of the model's periodic effects (a worm-shaft order q is q / ratio)."""
    ratio = model.rig.gearbox.ratio
    out = []
    for effect, _values, grid in model.effects:
        if effect.family == "periodic" and "order" in grid:
            q = float(grid["order"])
            out.append(q if getattr(effect, "angle", "theta_worm") == "theta_gear" else q / ratio)
    return out


def angle_count(orders: list[float], minimum: int = ANGLES, limit: int = 64) -> int:
    """Smallest A >= ``minimum`` such that no integer order q > 1 of ``orders`` shows at A even gear phases as
    the mean (q mod A = 0) or the first harmonic (q mod A = ±1); ``limit`` if none below it does."""
    whole = [round(q) for q in orders if abs(q - round(q)) < 1e-6 and round(q) > 1]
    for a in range(max(minimum, 3), limit):
        if all(q % a not in (0, 1, a - 1) for q in whole):
            return a
    return limit


def load_model(model_file: str | Path | None, rig_file: str | Path | None = None) -> ExtendedModel:
    """The ExtendedModel of ``model_file``; empty/None → ``rig_file`` (or the bundled rig), no effects."""
    if model_file:
        return ExtendedModel.load(model_file)
    return ExtendedModel(load_rig(rig_file or None))


@dataclass(frozen=True)
class SensorCorrection:
    """The identified sensor errors of a model (sensor_gain / sensor_offset effects; zero without them).

    ``drive_gain`` g and ``drive_offset`` [A]: the drive current reads (1 + g) i + offset;
    ``load_gain`` g_l and ``load_offset`` [N m]: tau_load reads (1 + g_l) tau + offset (the
    load-current offset through the load motors' K_t and count).
    """

    drive_gain: float = 0.0
    drive_offset: float = 0.0
    load_gain: float = 0.0
    load_offset: float = 0.0

    @classmethod
    def of(cls, model: ExtendedModel) -> "SensorCorrection":
        values = {effect.name: v for effect, v, _g in model.effects}
        gain, offset = values.get("sensor_gain", {}), values.get("sensor_offset", {})
        rig = model.rig
        return cls(float(gain.get("drive_current", 0.0)), float(offset.get("drive_current", 0.0)),
                   float(gain.get("load_current", 0.0)),
                   float(offset.get("load_current", 0.0)) * rig.load_motor.torque_constant * rig.load_motor_count)

    def current(self, measured):
        """The drive current [A] behind a reading."""
        return (np.asarray(measured, dtype=float) - self.drive_offset) / (1.0 + self.drive_gain)

    def load(self, read):
        """The load torque [N m] behind a tau_load reading, to first order (as the residual model fits it)."""
        read = np.asarray(read, dtype=float)
        return read - (self.load_gain * read + self.load_offset)


def identification_ranges(model_file: str | Path) -> dict[str, float] | None:
    """{speed_max [rad/s], torque_min, torque_max [N m]} of the ``identification:`` section of a file written
    by ``identify`` (torque_estimator.identification.writing.write_identified); None: no such section.

    Raises:
        ParameterError: the section is there but malformed.
    """
    try:
        document = yaml.safe_load(Path(model_file).read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as err:
        raise ParameterError(str(model_file), "", f"cannot read: {err}") from None
    section = document.get("identification") if isinstance(document, dict) else None
    if section is None:
        return None
    try:
        out = {k: float(section[k]["value"]) for k in ("speed_max", "torque_min", "torque_max")}
    except (KeyError, TypeError, ValueError):
        raise ParameterError(str(model_file), "identification",
                             "needs speed_max, torque_min and torque_max as {value, unit}") from None
    if not (out["speed_max"] > 0 and out["torque_max"] > out["torque_min"]):
        raise ParameterError(str(model_file), "identification", f"empty range {out}")
    return out


def model_ranges(model_file: str | Path | None, database: CalibrationDatabase | None, rig: Rig
                 ) -> tuple[float, float, float, str]:
    """(ω_max [rad/s], τ_min, τ_max [N m], where from): the identification's, else the database's, else the rig's."""
    ranges = identification_ranges(model_file) if model_file else None
    if ranges is not None:
        return ranges["speed_max"], ranges["torque_min"], ranges["torque_max"], "identification"
    if database is not None:
        if len(database) == 0:
            raise ValueError("calibration database has no points")
        lo, hi = float(np.min(database.tau_load)), float(np.max(database.tau_load))
        if not hi > lo:
            raise ValueError("calibration database spans no torque range")
        return float(np.max(np.abs(database.omega_worm))) or 1.0, lo, hi, "calibration"
    no_load = rig.supply_voltage / rig.drive_motor.back_emf_constant
    return no_load, -rig.max_load_torque, rig.max_load_torque, "rig"


def checked_prior(load_min: float, load_max: float, fallback: tuple[float, float] | None, rig: Rig) -> LoadPrior:
    """The load prior of estimator options ``load_min``/``load_max`` [N·m] (branches.LoadPrior.of, ``fallback``
    standing in when none is declared), checked against what ``rig`` can do (worm_model.physics.envelope).

    Raises:
        ValueError: load_min not below load_max, a bound far outside the rig's envelope (naming it), or a prior
            that shares no load with ``fallback`` (the model's range; None: the model has none, any load goes).
    """
    prior = LoadPrior.of(float(load_min), float(load_max), fallback)
    if prior.declared:
        envelope = Envelope.of(rig)
        for name, value in (("load_min", prior.low), ("load_max", prior.high)):
            if (problem := envelope.problem("tau_load", value)) is not None:
                raise ValueError(f"{name}: {problem}")
        low, high = fallback if fallback is not None else (-np.inf, np.inf)
        if prior.high < low or prior.low > high:  # no load the model knows: every candidate would be excluded
            raise ValueError(f"load_min / load_max: the prior load_min..load_max [{prior.low:g}, {prior.high:g}] N m "
                             f"shares no load with the "
                             f"[{low:g}, {high:g}] N m the model was identified or calibrated over: every candidate "
                             "would be excluded (identify the drive at those loads, or declare the loads it carries)")
    return prior


class ExtendedModelEstimator:
    """τ_d by inverting the extended model's tabulated current; method in the module docstring.

    Args:
        database: a calibration map or None; its speed and torque range are the table's when the model
            file has no ``identification:`` section (:func:`model_ranges`).
        model_file: parameter file with an optional ``effects:`` section (ExtendedModel.load);
            empty/None → ``rig_file`` with no effects (the paper's model).
        rig_file: rig YAML used when ``model_file`` is empty; empty/None → bundled rig.
        rig: a Rig instead of ``rig_file`` (no effects: the paper's model of that rig).
        model: an ExtendedModel to use instead of reading a file (tests, benches).
        speed_points, torque_points: table size per direction (≥ 2 each).
        angles: fewest worm angles averaged when the model has periodic effects (≥ 1; :func:`angle_count`).
        current_noise: σ_i [A] for the uncertainty; None → rig.sensors.current_noise_std.
        ranges: (ω_max, τ_min, τ_max) of the table instead of :func:`model_ranges`' (tests, in-memory models).
        load_min, load_max: the load prior [N·m] (module docstring); both 0: none declared.

    Raises:
        ValueError: bad option, empty database or zero torque range, a prior with load_min >= load_max or far
            outside what the rig can do.
        worm_model.errors.ParameterError: a bad model or rig file.
    """

    name = "extended_model"

    def __init__(self, database: CalibrationDatabase | None = None, model_file: str | Path | None = None,
                 rig_file: str | Path | None = None, *, rig: Rig | None = None, model: ExtendedModel | None = None,
                 speed_points: int = 121, torque_points: int = 161, angles: int = ANGLES,
                 current_noise: float | None = None, ranges: tuple[float, float, float] | None = None,
                 load_min: float = 0.0, load_max: float = 0.0) -> None:
        if speed_points < 2 or torque_points < 2 or angles < 1:
            raise ValueError(f"need speed_points, torque_points >= 2 and angles >= 1, got "
                             f"{speed_points}, {torque_points}, {angles}")
        if model is None and rig is not None:
            if model_file:
                raise ValueError("a rig and a model_file: the model is one or the other")
            model = ExtendedModel(rig)
        self.model = model if model is not None else load_model(model_file, rig_file)
        rig = self.model.rig
        if ranges is not None:
            (omega_max, tau_lo, tau_hi), self.ranges_from = ranges, "given"
        else:
            omega_max, tau_lo, tau_hi, self.ranges_from = model_ranges(model_file if model is None else None,
                                                                       database, rig)
        if not (omega_max > 0 and tau_hi > tau_lo):
            raise ValueError(f"empty table range: omega_max {omega_max}, torque [{tau_lo}, {tau_hi}]")
        #: the loads the estimate may be (branches.LoadPrior): the declared prior, else the table's range
        self.prior = checked_prior(load_min, load_max, (tau_lo, tau_hi), rig)
        if self.prior.declared:
            tau_lo, tau_hi = self.prior.low, self.prior.high
        self.current_noise = float(rig.sensors.current_noise_std if current_noise is None else current_noise)
        if not (math.isfinite(self.current_noise) and self.current_noise >= 0):
            raise ValueError(f"current_noise must be finite and >= 0, got {current_noise!r}")
        #: ω_max [rad/s] the model was identified or calibrated to (OUT_OF_CALIBRATION beyond it)
        self.omega_max = float(omega_max)
        # rows fine enough for the model's own speed scales (a support's or the tooth law's low-speed rise), and the
        # table on to SPEED_EXTRAPOLATION x omega_max at the same spacing: beyond the identified speeds the model
        # is extrapolated (flagged), not held at its edge row
        step = min(self.omega_max / (speed_points - 1), speed_scale(self.model) / ROWS_PER_SPEED_SCALE)
        rows = min(int(math.ceil(self.omega_max / step)), MAX_SPEED_ROWS)
        step = self.omega_max / rows
        self.speeds = np.arange(int(math.ceil(rows * SPEED_EXTRAPOLATION)) + 1) * step
        self.torques = np.linspace(tau_lo, tau_hi, torque_points)
        self.speed_step = float(self.speeds[1])
        self.torque_step = float(self.torques[1] - self.torques[0])
        periodic = any(effect.family == "periodic" for effect, _v, _g in self.model.effects)
        self.angles = angle_count(gear_orders(self.model), int(angles)) if periodic else 1
        #: the identified load-sensor errors the estimate is corrected for (step 6)
        self.correction = SensorCorrection.of(self.model)
        tabulated = {negative: self._tabulate(negative) for negative in (False, True)}
        #: direction (False: +, True: −) → current table [A], shape (speed_points, torque_points)
        self.tables = {negative: mean for negative, (mean, _c, _s) in tabulated.items()}
        #: direction → (c₁, s₁) [A]: the current's first harmonic per gear turn (module docstring); None
        #: when the model has no periodic effect or too few angles to resolve it
        self.gear_harmonic = ({negative: (c, s) for negative, (_m, c, s) in tabulated.items()}
                              if self.angles >= 3 else None)

    @property
    def uses_angle(self) -> bool:
        """Whether :meth:`estimate` takes the gear ripple out given the worm angle (``theta_worm``)."""
        return self.gear_harmonic is not None

    def _tabulate(self, negative: bool) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Mean model current over the angles, α = 0, on the (|ω|, τ_d) grid of one direction, and the
        first gear harmonic's cos and sin coefficients [A] (zero with one angle)."""
        rig = self.model.rig
        speed = -np.maximum(self.speeds, _NEGATIVE_ZERO) if negative else self.speeds
        gear_turn = 2.0 * math.pi / rig.gearbox.ratio  # worm angle [rad] of one gear turn
        theta = np.arange(self.angles) * gear_turn / self.angles
        w, tau, th = (a.ravel() for a in np.meshgrid(speed, self.torques, theta, indexing="ij"))
        signals = self.model.signals(w, 0.0, tau, th, run=np.arange(len(w)))
        current = np.asarray(self.model.current(signals), dtype=float)
        current = current.reshape(len(speed), len(self.torques), self.angles)
        phase = 2.0 * np.pi * np.arange(self.angles) / self.angles  # gear angle of each table angle
        scale = 2.0 / self.angles if self.angles >= 3 else 0.0
        return current.mean(axis=2), scale * (current @ np.cos(phase)), scale * (current @ np.sin(phase))

    # ------------------------------------------------------------------ estimation
    def estimate(self, omega_worm: ArrayLike, current_drive: ArrayLike,
                 theta_worm: ArrayLike | None = None) -> TorqueEstimates:
        """Estimate τ_d [N·m] from ω_w [rad/s] and the inertia-free drive current i [A].

        ``theta_worm`` [rad]: the encoder's worm angle of each sample, or with one more trailing axis the
        angles of the samples a mean (ω, i) was taken over; given, the gear ripple is taken out (module
        docstring; ignored when :attr:`uses_angle` is False). Inputs broadcast; outputs have the
        broadcast shape (scalars → 0-d arrays). Never raises for NaN/inf samples.
        """
        omega, current = np.broadcast_arrays(np.asarray(omega_worm, dtype=np.float64),
                                             np.asarray(current_drive, dtype=np.float64))
        w, i = omega.ravel(), current.ravel()
        harmonics = None
        if theta_worm is not None and self.gear_harmonic is not None:
            theta = np.asarray(theta_worm, dtype=np.float64)
            phase = theta * self.model.rig.gearbox.ratio  # gear angle [rad]
            mean_cos, mean_sin = np.cos(phase), np.sin(phase)
            if theta.ndim > omega.ndim:  # a window of angles per (ω, i): its mean ripple
                mean_cos, mean_sin = mean_cos.mean(axis=-1), mean_sin.mean(axis=-1)
            harmonics = [np.broadcast_to(x, omega.shape).ravel() for x in (mean_cos, mean_sin)]
        torque = np.full(len(w), np.nan)
        spread = np.full(len(w), np.nan)
        other = np.full(len(w), np.nan)
        flags = np.zeros(len(w), dtype=np.int64)
        for start in range(0, len(w), _BATCH):
            part = slice(start, start + _BATCH)
            torque[part], spread[part], flags[part], other[part] = self._invert(w[part], i[part])
            if harmonics is not None:  # take the gear ripple at the first estimate out, invert again
                ripple = self._gear_ripple(w[part], i[part], torque[part], harmonics[0][part], harmonics[1][part])
                torque[part], spread[part], flags[part], other[part] = self._invert(w[part], i[part] - ripple)
        shape = omega.shape
        torque, other = self.correction.load(torque), self.correction.load(other)
        return TorqueEstimates(torque.reshape(shape), spread.reshape(shape), flags.reshape(shape),
                               other.reshape(shape))

    def _speed_cells(self, w: NDArray[np.float64], i: NDArray[np.float64]
                     ) -> tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.float64]]:
        """(direction: True = the − table, speed row, fraction towards the next row) of finite samples (step 1-2)."""
        negative = np.where(w != 0, w, i) < 0
        position = np.minimum(np.abs(w), self.speeds[-1]) / self.speed_step
        row = np.minimum(position.astype(np.int64), len(self.speeds) - 2)
        return negative, row, position - row

    def _gear_ripple(self, w: NDArray[np.float64], i: NDArray[np.float64], tau: NDArray[np.float64],
                     mean_cos: NDArray[np.float64], mean_sin: NDArray[np.float64]) -> NDArray[np.float64]:
        """c₁ cos φ + s₁ sin φ [A] at (ω, τ), in the tables of the direction the inversion of (ω, i) used
        (bilinear; 0 where τ is NaN)."""
        ok = np.isfinite(w) & np.isfinite(i) & np.isfinite(tau) & np.isfinite(mean_cos) & np.isfinite(mean_sin)
        w, i, tau = np.where(ok, w, 0.0), np.where(ok, i, 0.0), np.where(ok, tau, 0.0)
        negative, row, fr = self._speed_cells(w, i)
        where_tau = np.clip((tau - self.torques[0]) / self.torque_step, 0.0, len(self.torques) - 1.0)
        col = np.minimum(where_tau.astype(np.int64), len(self.torques) - 2)
        fc = where_tau - col
        out = np.zeros(len(w))
        for side in (False, True):
            rows = negative == side
            if not rows.any():
                continue
            r, c, a, b = row[rows], col[rows], fr[rows], fc[rows]
            for table, weight in zip(self.gear_harmonic[side], (mean_cos[rows], mean_sin[rows])):
                value = ((1 - a) * ((1 - b) * table[r, c] + b * table[r, c + 1])
                         + a * ((1 - b) * table[r + 1, c] + b * table[r + 1, c + 1]))
                out[rows] += value * weight
        return np.where(ok, out, 0.0)

    def _invert(self, w: NDArray[np.float64], i: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """Steps 1–5 of the module docstring for one batch."""
        m = len(w)
        valid = np.isfinite(w) & np.isfinite(i)
        flags = np.where(valid, 0, int(EstimateFlags.INVALID_INPUT)).astype(np.int64)
        w, i = np.where(valid, w, 0.0), np.where(valid, i, 0.0)
        flags |= np.where(np.abs(w) > self.omega_max, int(EstimateFlags.OUT_OF_CALIBRATION), 0)
        negative, row, frac = self._speed_cells(w, i)
        frac = frac[:, None]
        column = np.empty((m, len(self.torques)))
        for side in (False, True):
            rows = negative == side
            if rows.any():
                table = self.tables[side]
                column[rows] = (1.0 - frac[rows]) * table[row[rows]] + frac[rows] * table[row[rows] + 1]
        excess = column - i[:, None]  # (m, n_tau): model current minus measured
        left, right = excess[:, :-1], excess[:, 1:]
        crossing = (left == 0) | (np.sign(left) != np.sign(right)) & (right != 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            cell = np.clip(left / (left - right), 0.0, 1.0)
        cell = np.where(np.isfinite(cell), cell, 0.0)
        tau_at = self.torques[:-1] + cell * self.torque_step  # (m, n_tau - 1) candidate solutions
        sigma = np.where(negative, -1.0, 1.0)[:, None]
        count = crossing.sum(axis=1)

        # step 3: the crossing with the largest σ·τ (driving flank); the farthest other for AMBIGUOUS
        ranked = np.where(crossing, sigma * tau_at, -np.inf)
        best = ranked.argmax(axis=1)
        torque = np.take_along_axis(tau_at, best[:, None], axis=1)[:, 0]
        distance = np.where(crossing, np.abs(tau_at - torque[:, None]), 0.0)
        farthest = distance.max(axis=1)
        other = np.take_along_axis(tau_at, distance.argmax(axis=1)[:, None], axis=1)[:, 0]

        # no crossing: extrapolate beyond an end, or the V's minimum
        none = count == 0
        if none.any():
            flags[none] |= EstimateFlags.OUT_OF_CALIBRATION
            col, cur = column[none], i[none]
            nearest = np.abs(col - cur[:, None]).argmin(axis=1)
            low_end, high_end = nearest == 0, nearest == len(self.torques) - 1
            slope_lo = (col[:, 1] - col[:, 0]) / self.torque_step
            slope_hi = (col[:, -1] - col[:, -2]) / self.torque_step
            with np.errstate(divide="ignore", invalid="ignore"):
                extrapolated = np.where(low_end, self.torques[0] + (cur - col[:, 0]) / slope_lo,
                                        self.torques[-1] + (cur - col[:, -1]) / slope_hi)
            fallback = self.torques[nearest]
            torque[none] = np.where((low_end | high_end) & np.isfinite(extrapolated), extrapolated, fallback)

        # step 4: slope of the cell the estimate lies in
        cell_index = np.clip(((torque - self.torques[0]) / self.torque_step).astype(np.int64), 0,
                             len(self.torques) - 2)
        slope = np.abs(np.take_along_axis(column, cell_index[:, None] + 1, axis=1)[:, 0]
                       - np.take_along_axis(column, cell_index[:, None], axis=1)[:, 0]) / self.torque_step
        with np.errstate(divide="ignore"):
            noise = np.where(slope > 0, self.current_noise / slope, np.inf if self.current_noise else 0.0)
        spread = np.hypot(noise, self.torque_step / math.sqrt(12.0))
        ambiguous = (count > 1) & (farthest > 0.0)
        flags[ambiguous] |= EstimateFlags.AMBIGUOUS
        other = np.where(ambiguous & valid, other, np.nan)
        torque[~valid] = np.nan
        spread[~valid] = np.nan
        flags[~valid] = int(EstimateFlags.INVALID_INPUT)
        return torque, spread, flags, other


__all__ = ["ANGLES", "ExtendedModelEstimator", "SensorCorrection", "angle_count", "checked_prior", "gear_orders",
           "identification_ranges", "load_model", "model_ranges", "speed_scale"]
