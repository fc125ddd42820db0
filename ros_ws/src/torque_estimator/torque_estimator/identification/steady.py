"""Identification from steady operating points: a drive held at speeds against known loads.

A record is a set of *steady points* when every run of it is held at one speed against one load
(:func:`steady_points`: an EPOS export per held speed, a robot joint held at a few speeds): its
dynamics show nothing, so no inertia is fitted, and each run is one point, the mean worm speed
omega [rad/s], the mean drive current i [A] with its standard error (from 10 consecutive blocks:
a drive's averaging correlates neighbouring samples) and the load tau_load [N m] (+ opposes +
rotation).

The model is the project's: :class:`~worm_model.residuals.extended.ExtendedModel` at zero
acceleration (Eq. 28 with the rig's friction law, the drive motor's drags on the worm shaft, the
gear shaft's drags), so the estimators invert exactly what is fitted here. A *structure* is the
base (:func:`base_knobs`: the tooth-thread mu under a constant law, the worm shaft's Coulomb and
viscous drag, the gear shaft's Coulomb drag, and K_t where the record measured a current) plus named
*terms* (:data:`TERMS`), each of them rig leaves of the file it writes:

==========================  ========================================================================
``gear_support_stribeck``   the gear shaft supports' Coulomb drag rises at low speed
                            (``load_motor.stribeck_rise``/``stribeck_speed``, worm_model.physics.motor)
``worm_support_stribeck``   the worm shaft's (``drive_motor.stribeck_rise``/``stribeck_speed``)
``tooth_stribeck``          the tooth mu law is Stribeck's: mu_k + mu_s exp(-V_s / V_st)^2
                            (``friction.model: stribeck``)
``agma_law``                the tooth mu law is the AGMA curve's shape, scaled (``friction.model: agma``)
``viscous_drag``            the residual analysis' viscous / churning drag with a free exponent (effect)
==========================  ========================================================================

The two law terms replace the base's constant mu (they exclude each other). Every fitted number
stays in its physical range (no negative drag; mu below Remark 4's engagement limit; a speed scale
of a rise below :data:`LOW_SPEED_FRACTION` of the fastest point's speed), and its starting value and
bounds scale with the drive (its motor's rated torque, the record's speeds), not with one rig.

Which terms (:func:`select`): the points are split in two halves, alternate speeds in each direction
and load (:func:`halves`); a structure is scored by its *cross-fitted* held-out RMS (fit on one half,
predict the other, both ways). From the base, the term whose addition lowers that RMS most is
accepted if it lowers it by at least :data:`MIN_IMPROVEMENT` (relative) while the RMS is above
:data:`AT_FLOOR` x the noise floor (the RMS of the points' standard errors); the loop stops when no
term qualifies. On one load, mu and the supports' friction are tied only through how they change with
speed: a support's rise moves lifting and lowering in opposite senses (reflected through the engaged
flanks), a tooth mu's rise both alike, so a speed law is what separates them (docs/real-data.md).

A term that fits only by trading the base away is no candidate: fitted to all the points, a base
parameter's 95 % band would be :data:`TRADED_RATIO` times its tolerance or more (on one load, the tooth
law's Stribeck rise fits the T-RO drive's points with the gear supports' friction equal to the load and
a mu of 0.02 that does not self-lock; a band 400 times its tolerance). What the base knobs' values are
worth is decided afterwards, at the selected structure (identification.identifiability); a knob held
there is refitted out.

No ROS; numpy + scipy.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from worm_model.physics.friction import friction_coefficient, sliding_velocity
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray
from worm_model.residuals.effects import EFFECTS
from worm_model.residuals.extended import ExtendedModel
from worm_model.residuals.free import get_value, set_values
from worm_model.rig_data.schema import MeasuredData

from torque_estimator.identification.identifiability import Assessment, assess

#: a term is accepted when it lowers the cross-fitted held-out RMS by at least this fraction
MIN_IMPROVEMENT = 0.10
#: no term is added once the held-out RMS is within this multiple of the noise floor
AT_FLOOR = 1.1
#: a rise's speed scale is started at these fractions of the fastest point's speed (the best fit is kept)
SPEED_STARTS = (0.005, 0.015, 0.05)
#: a rise's speed scale stays below this fraction of the fastest point's speed: a rise that decays over the
#: whole range is not a low-speed effect (the viscous drag's exponent is that)
LOW_SPEED_FRACTION = 0.1
#: blocks a run is cut into for the standard error of its mean current (neighbouring samples correlate)
BLOCKS = 10
#: fewest samples of a held run
MIN_RUN_SAMPLES = 2 * BLOCKS
#: a run is held when the means of its quarters are within this fraction of its mean speed of each other
HELD_SPREAD = 0.05
#: fewest points a fit needs beyond its knobs (each half of the cross-fit too)
SPARE_POINTS = 2
#: a term is not a candidate when, fitted to all the points, a base parameter's 95 % band is this many times its
#: tolerance band or more (identification.identifiability): it fits by trading the base away
TRADED_RATIO = 5.0
#: the rig's sections: a knob path starting with one is a rig leaf, any other an effect's parameter
RIG_SECTIONS = frozenset(f.name for f in dataclasses.fields(Rig))


# --------------------------------------------------------------------------- points
@dataclass(frozen=True)
class SteadyPoints:
    """Steady operating points, arrays of shape (n,): omega [rad/s], current and current_sem [A], tau_load [N m];
    ``run`` the record's run each point is, ``speed_sd`` [rad/s] the sample spread of the speed in it."""

    omega: FloatArray
    current: FloatArray
    current_sem: FloatArray
    tau_load: FloatArray
    run: np.ndarray
    speed_sd: FloatArray

    def __len__(self) -> int:
        return len(self.omega)

    def subset(self, mask: np.ndarray) -> "SteadyPoints":
        return SteadyPoints(*(np.asarray(getattr(self, f.name))[mask] for f in dataclasses.fields(self)))

    @property
    def noise_floor(self) -> float:
        """[A] the RMS of the points' standard errors: no model can predict held-out points better."""
        return float(np.sqrt(np.mean(self.current_sem ** 2)))

    @property
    def loads(self) -> FloatArray:
        """The distinct loads [N m] (to 1e-9 of the largest)."""
        return np.unique(self.load_keys()) * self._load_scale()

    def _load_scale(self) -> float:
        return max(float(np.max(np.abs(self.tau_load))), 1e-12)

    def load_keys(self) -> FloatArray:
        """Every point's load, rounded to 1e-9 of the largest [1]: equal keys, one load (:attr:`loads`)."""
        return np.round(self.tau_load / self._load_scale(), 9)


def _held(w: FloatArray) -> bool:
    """A run held at one speed (module docstring): its quarters' mean speeds agree within HELD_SPREAD of its mean
    plus 4 standard errors of a quarter's mean (the speed's noise: a drive that sticks and slips at 1 rpm is
    held there too), and the mean is clear of zero by 3 standard errors."""
    quarters = np.array([np.mean(q) for q in np.array_split(w, 4)])
    mean, sd = float(np.mean(w)), float(np.std(w))
    return bool(np.ptp(quarters) <= HELD_SPREAD * abs(mean) + 4.0 * sd / math.sqrt(len(w) / 4.0)
                and abs(mean) > 3.0 * sd / math.sqrt(len(w)))


def steady_points(data: MeasuredData) -> SteadyPoints | None:
    """The record as steady points (module docstring), None when it is not one: a run too short, moving through
    speeds or loads, or with a non-finite sample."""
    omega, current, tau, sem, runs, spread = [], [], [], [], [], []
    for r in np.unique(data.run):
        idx = np.flatnonzero(data.run == r)
        w, i, load = data.omega_worm[idx], data.current_drive[idx], data.tau_load[idx]
        if len(idx) < MIN_RUN_SAMPLES or not (np.all(np.isfinite(w)) and np.all(np.isfinite(i))
                                               and np.all(np.isfinite(load))):
            return None
        if not _held(w) or np.ptp(load) > 1e-9 * max(float(np.max(np.abs(load))), 1e-12):
            return None
        blocks = np.array([np.mean(b) for b in np.array_split(i, BLOCKS)])
        omega.append(float(np.mean(w)))
        current.append(float(np.mean(i)))
        tau.append(float(np.mean(load)))
        sem.append(float(np.std(blocks, ddof=1) / math.sqrt(BLOCKS)))
        runs.append(int(r))
        spread.append(float(np.std(w, ddof=1)))
    if len(omega) < 2:
        return None
    return SteadyPoints(np.array(omega), np.array(current), np.array(sem), np.array(tau), np.array(runs),
                        np.array(spread))


def halves(points: SteadyPoints) -> np.ndarray:
    """Half (0 or 1) of every point: alternate speeds in each direction and load, counted from the slowest (half 0)."""
    out = np.zeros(len(points), dtype=int)
    keys = points.load_keys()
    for key in np.unique(keys):
        same_load = keys == key
        for side in (points.omega > 0, points.omega < 0):
            idx = np.flatnonzero(side & same_load)
            out[idx[np.argsort(np.abs(points.omega[idx]))]] = np.arange(len(idx)) % 2
    return out


# --------------------------------------------------------------------------- knobs and terms
@dataclass(frozen=True)
class Knob:
    """One fitted number: a rig leaf (``path``: dotted) or an effect's value or grid (``path``: effect.parameter),
    with its start and bounds [SI]; ``speed``: a rise's speed scale (started at SPEED_STARTS, capped at
    LOW_SPEED_FRACTION of the fastest point's speed on its shaft)."""

    path: str
    start: float
    low: float
    high: float
    speed: bool = False


@dataclass(frozen=True)
class Term:
    """A named addition to the base: its knobs (from :func:`term_knobs`), the friction law it sets (None: the
    base's), the vocabulary effect it adds (None: none)."""

    name: str
    description: str
    law: str | None = None
    effect: str | None = None


#: the terms :func:`select` tries (module docstring)
TERMS: dict[str, Term] = {t.name: t for t in (
    Term("gear_support_stribeck", "a Stribeck rise of the gear shaft supports' friction at low speed"),
    Term("worm_support_stribeck", "a Stribeck rise of the worm shaft's support friction at low speed"),
    Term("tooth_stribeck", "Stribeck's tooth mu law: mu_k + mu_s exp(-V_s / V_st)^2", law="stribeck"),
    Term("agma_law", "the AGMA curve's shape of the tooth mu, scaled", law="agma"),
    Term("viscous_drag", EFFECTS["viscous_drag"].description, effect="viscous_drag"),
)}
#: terms that set the friction law exclude each other
LAW_TERMS = frozenset(name for name, t in TERMS.items() if t.law is not None)


@dataclass(frozen=True)
class Scales:
    """What a drive's knobs are bounded and started by: the drive motor's rated torque [N m] on the worm shaft,
    the same on the gear shaft [N m], the fastest point's worm speed [rad/s], the declared mu at the median speed."""

    worm_torque: float
    gear_torque: float
    fastest: float
    mu: float

    @classmethod
    def of(cls, rig: Rig, points: SteadyPoints) -> "Scales":
        motor = rig.drive_motor
        worm = motor.torque_constant * motor.rated_current
        fastest = float(np.max(np.abs(points.omega)))
        median = float(np.median(np.abs(points.omega)))
        mu = float(friction_coefficient(rig.friction, rig.gearbox, median))
        return cls(worm, worm / rig.gearbox.ratio, fastest, mu)


def base_knobs(rig: Rig, scales: Scales, current_measured: bool) -> tuple[Knob, ...]:
    """The unknowns without a speed law (module docstring), started at the rig file's values (mu: its law at the
    points' median speed) within physical bounds."""
    mu_max = 0.9 * rig.gearbox.mu_engagement_max
    motor, load = rig.drive_motor, rig.load_motor
    knobs = [Knob("friction.mu_constant", min(scales.mu, 0.5 * mu_max), 0.0, mu_max),
             Knob("drive_motor.coulomb_drag", motor.coulomb_drag, 0.0, scales.worm_torque),
             Knob("drive_motor.viscous_drag", motor.viscous_drag, 0.0, scales.worm_torque / scales.fastest),
             Knob("load_motor.coulomb_drag", load.coulomb_drag, 0.0, scales.gear_torque / rig.load_motor_count)]
    if current_measured:
        kt = motor.torque_constant
        knobs.append(Knob("drive_motor.torque_constant", kt, 0.5 * kt, 2.0 * kt))
    return tuple(knobs)


def term_knobs(name: str, rig: Rig, scales: Scales) -> tuple[Knob, ...]:
    """The knobs of term ``name`` (:data:`TERMS`)."""
    gb = rig.gearbox
    if name == "gear_support_stribeck":
        return (Knob("load_motor.stribeck_rise", 0.01 * scales.gear_torque / rig.load_motor_count, 0.0,
                     scales.gear_torque / rig.load_motor_count),
                Knob("load_motor.stribeck_speed", SPEED_STARTS[1] * scales.fastest * gb.ratio, 1e-6, math.inf, True))
    if name == "worm_support_stribeck":
        return (Knob("drive_motor.stribeck_rise", 0.01 * scales.worm_torque, 0.0, scales.worm_torque),
                Knob("drive_motor.stribeck_speed", SPEED_STARTS[1] * scales.fastest, 1e-6, math.inf, True))
    if name == "tooth_stribeck":
        return (Knob("friction.stribeck_rise", 0.5 * scales.mu, 0.0, 1.0),
                Knob("friction.stribeck_speed", SPEED_STARTS[1] * float(sliding_velocity(gb, scales.fastest)), 1e-6,
                     math.inf, True))
    if name == "agma_law":
        mu_max = 0.9 * gb.mu_engagement_max
        return (Knob("friction.scale", 1.0, 0.01, max(mu_max / 0.15, 0.02)),)
    if name == "viscous_drag":
        return (Knob("viscous_drag.worm_torque", 0.01 * scales.worm_torque, 0.0, scales.worm_torque),
                Knob("viscous_drag.gear_torque", 0.01 * scales.gear_torque, 0.0, scales.gear_torque),
                Knob("viscous_drag.exponent", 1.0, 0.25, 2.0))
    raise KeyError(name)


def structure_knobs(rig: Rig, scales: Scales, structure: Sequence[str], current_measured: bool,
                    held: Mapping[str, float] | None = None) -> tuple[Knob, ...]:
    """Every knob of a structure, the base's first; a law term takes the constant mu's place (agma: its scale
    instead; stribeck: its kinetic mu stays). ``held``: base knobs not fitted (path -> value)."""
    knobs = list(base_knobs(rig, scales, current_measured))
    if "agma_law" in structure:
        knobs = [k for k in knobs if k.path != "friction.mu_constant"]
    for name in structure:
        knobs += term_knobs(name, rig, scales)
    return tuple(k for k in knobs if k.path not in (held or {}))


def _speed_cap(knob: Knob, rig: Rig, scales: Scales) -> float:
    """The largest speed scale of a rise, on its own shaft (module docstring)."""
    if knob.path.startswith("load_motor."):
        return LOW_SPEED_FRACTION * scales.fastest * rig.gearbox.ratio
    if knob.path.startswith("friction."):
        return LOW_SPEED_FRACTION * float(sliding_velocity(rig.gearbox, scales.fastest))
    return LOW_SPEED_FRACTION * scales.fastest


def base_rig(rig: Rig, structure: Sequence[str]) -> Rig:
    """The rig a structure's knobs are set into: the law of its law term (else constant), scale 1 unless fitted,
    no rises unless fitted."""
    law = next((TERMS[n].law for n in structure if TERMS[n].law), "constant")
    friction = dataclasses.replace(rig.friction, model=law, scale=1.0, stribeck_rise=0.0)
    return dataclasses.replace(rig, friction=friction,
                               drive_motor=dataclasses.replace(rig.drive_motor, stribeck_rise=0.0),
                               load_motor=dataclasses.replace(rig.load_motor, stribeck_rise=0.0))


def build(rig: Rig, structure: Sequence[str], values: Mapping[str, float]) -> ExtendedModel:
    """The model of a structure with ``values`` (knob path -> SI value) set into :func:`base_rig`."""
    leaves = {p: v for p, v in values.items() if p.split(".")[0] in RIG_SECTIONS}
    model_rig = set_values(base_rig(rig, structure), list(leaves), list(leaves.values()))
    effects = []
    for name in structure:
        term = TERMS[name]
        if term.effect is None:
            continue
        effect = EFFECTS[term.effect]
        params = {p.name: values[f"{name}.{p.name}"] for p in effect.parameters}
        grid = {g.name: values[f"{name}.{g.name}"] for g in effect.grid_parameters}
        effects.append((effect, params, grid))
    return ExtendedModel(model_rig, effects)


def model_current(model: ExtendedModel, omega: FloatArray, tau_load: FloatArray) -> FloatArray:
    """Drive current [A] the model expects at steady speed omega [rad/s] against tau_load [N m]: zero
    acceleration, worm angle 0 (no periodic effect is fitted), each point its own run."""
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    signals = model.signals(omega, 0.0, np.broadcast_to(np.asarray(tau_load, dtype=float), omega.shape), 0.0,
                            run=np.arange(len(omega)))
    return model.current(signals)


def knob_values(model_rig: Rig, knobs: Sequence[Knob], effects: Mapping[str, Mapping[str, float]]) -> dict:
    """The knobs' values read back from a rig and effect values (path -> SI)."""
    out = {}
    for k in knobs:
        section, name = k.path.split(".")
        out[k.path] = get_value(model_rig, k.path) if section in RIG_SECTIONS else effects[section][name]
    return out


# --------------------------------------------------------------------------- fits
@dataclass
class FittedModel:
    """A fitted structure: the model, its values by knob path, its RMS over the points it was fitted to [A]."""

    structure: tuple[str, ...]
    model: ExtendedModel
    values: dict[str, float]
    rms: float
    knobs: tuple[Knob, ...] = ()
    held: dict[str, float] = field(default_factory=dict)
    rig: Rig | None = None  # the rig it was fitted from (build's base)

    def with_values(self, values: Mapping[str, float]) -> ExtendedModel:
        """The structure's model with other knob values (held ones as they are)."""
        return build(self.rig, self.structure, {**self.held, **self.values, **values})

    def current(self, omega: FloatArray, tau_load: FloatArray) -> FloatArray:
        return model_current(self.model, omega, tau_load)

    def jacobian(self, points: SteadyPoints) -> tuple[np.ndarray, np.ndarray]:
        """(d current / d knob [A per SI] for every knob, residual [A]) at the fit, by central differences."""
        def current(values: Mapping[str, float]) -> np.ndarray:
            return model_current(self.with_values(values), points.omega, points.tau_load)

        residual = current({}) - points.current
        cols = []
        for k in self.knobs:
            x = self.values[k.path]
            # a step of the knob's own size (its start's where the fit left it at ~0: a step of 1e-4 x 1e-28 is
            # below rounding), one-sided where a central one would cross the knob's lower bound
            h = 1e-4 * max(abs(x), abs(k.start)) or 1e-9
            low = x - h if x - h >= k.low else x
            cols.append((current({k.path: x + h}) - current({k.path: low})) / (x + h - low))
        return np.column_stack(cols) if cols else np.zeros((len(points), 0)), residual

    def assessment(self, points: SteadyPoints, declared: Rig, starts: Mapping[str, float]) -> Assessment:
        """Every knob's band at the fit (identification.identifiability); the base knobs' declared values are their
        ``starts`` (mu: the declared law's at the points' median speed)."""
        jacobian, residual = self.jacobian(points)
        return assess([k.path for k in self.knobs], jacobian, residual, declared, at_bound=self.at_bound(),
                      values=starts)

    def at_bound(self) -> list[str]:
        """Knobs sitting on a physical bound (within 1e-6 of its span)."""
        out = []
        for k in self.knobs:
            v, span = self.values[k.path], (k.high - k.low if math.isfinite(k.high) else abs(k.start) + 1.0)
            if (v - k.low <= 1e-6 * span) or (math.isfinite(k.high) and k.high - v <= 1e-6 * span):
                out.append(k.path)
        return out


def fit(rig: Rig, points: SteadyPoints, structure: Sequence[str] = (), *, current_measured: bool = False,
        held: Mapping[str, float] | None = None, start: Mapping[str, float] | None = None) -> FittedModel:
    """Least squares of the structure's current against the points' (module docstring).

    ``held``: base knobs fixed at these values (path -> SI); ``start``: knob values (e.g. a smaller
    structure's fit) tried as one more starting point. The scales (bounds, starts) are the whole record's
    when ``points`` is a half of it only through the caller passing the same rig: they follow the points given.
    """
    held = dict(held or {})
    scales = Scales.of(rig, points)
    knobs = structure_knobs(rig, scales, structure, current_measured, held)
    low = np.array([k.low for k in knobs])
    high = np.array([min(k.high, _speed_cap(k, rig, scales)) if k.speed else k.high for k in knobs])
    start0 = np.array([min(max(k.start, k.low), hi) for k, hi in zip(knobs, high)])
    scale = np.maximum(np.abs(start0), np.where(np.isfinite(high - low), (high - low) * 1e-3, 1e-9))

    def residual(x: FloatArray) -> FloatArray:
        model = build(rig, structure, {**held, **dict(zip((k.path for k in knobs), x))})
        return (model_current(model, points.omega, points.tau_load) - points.current) / scales_current

    scales_current = max(points.noise_floor, 1e-12)  # residuals in units of the points' standard errors
    starts = [start0]
    if start:
        starts.append(np.array([start.get(k.path, s) for k, s in zip(knobs, start0)]))
    for j, k in enumerate(knobs):
        if not k.speed:
            continue
        shaft = _speed_cap(k, rig, scales) / LOW_SPEED_FRACTION
        for s in SPEED_STARTS:
            x0 = starts[0].copy()
            x0[j] = s * shaft
            starts.append(x0)
    best = None
    # imported at first use: scipy.optimize takes ~0.4 s to import, paid at start by every executable
    from scipy.optimize import least_squares

    for x0 in starts:
        span = np.where(np.isfinite(high - low), high - low, np.abs(x0) + 1.0)
        x0 = np.clip(x0, low + 1e-6 * span, high - 1e-6 * span)
        result = least_squares(residual, x0, bounds=(low, high), x_scale=scale, method="trf", xtol=1e-10,
                               ftol=1e-12, gtol=1e-12, max_nfev=2000)
        if best is None or result.cost < best.cost:
            best = result
    values = dict(zip((k.path for k in knobs), (float(v) for v in best.x)))
    model = build(rig, structure, {**held, **values})
    rms = float(np.sqrt(np.mean((model_current(model, points.omega, points.tau_load) - points.current) ** 2)))
    return FittedModel(tuple(structure), model, values, rms, knobs, held, rig)


@dataclass
class CrossFit:
    """Each point predicted by the structure fitted on the other half: current [A] and the two fits."""

    structure: tuple[str, ...]
    predicted: FloatArray
    fits: tuple[FittedModel, FittedModel]  # fitted on half 0, on half 1

    def rms(self, points: SteadyPoints) -> float:
        return float(np.sqrt(np.mean((self.predicted - points.current) ** 2)))


def cross_fit(rig: Rig, points: SteadyPoints, structure: Sequence[str] = (), *, current_measured: bool = False,
              held: Mapping[str, float] | None = None,
              starts: tuple[FittedModel, FittedModel] | None = None) -> CrossFit:
    """Fit on each half, predict the other (:func:`halves`); ``starts``: fits per half to start from."""
    half = halves(points)
    predicted = np.full(len(points), np.nan)
    fits = []
    for h in (0, 1):
        fitted = fit(rig, points.subset(half == h), structure, current_measured=current_measured, held=held,
                     start=starts[h].values if starts else None)
        other = half != h
        predicted[other] = fitted.current(points.omega[other], points.tau_load[other])
        fits.append(fitted)
    return CrossFit(tuple(structure), predicted, (fits[0], fits[1]))


@dataclass
class Selection:
    """The forward selection (module docstring): per round, every term tried and its held-out RMS [A]."""

    accepted: list[str]
    rounds: list[dict[str, float]]  # term -> held-out RMS with it added, per round
    held_out: list[float]  # held-out RMS of the accepted structure after each round (the base first)
    floor: float  # [A]
    final: CrossFit = field(repr=False, default=None)  # type: ignore[assignment]
    traded: dict[str, float] = field(default_factory=dict)  # term -> its base's worst band ratio (TRADED_RATIO)

    @property
    def unexplained(self) -> bool:
        """Held-out RMS still above AT_FLOOR x the floor with no term qualifying."""
        return self.held_out[-1] > AT_FLOOR * self.floor

    def lines(self, unit: float = 1.0, label: str = "A") -> list[str]:
        """The rounds as a user reads them; ``unit``: factor from A to the shown unit ``label``."""
        out = [f"term selection (cross-fitted held-out RMS, noise floor {unit * self.floor:.4g} {label}): base "
               f"{unit * self.held_out[0]:.4g}"]
        for k, tried in enumerate(self.rounds):
            ranked = ", ".join(f"{n} {unit * v:.4g}" for n, v in sorted(tried.items(), key=lambda kv: kv[1]))
            taken = self.accepted[k] if k < len(self.accepted) else \
                f"none (no term lowers it by {MIN_IMPROVEMENT:.0%})"
            out.append(f"  round {k + 1}: {ranked} -> {taken}")
        out.append(f"  left: {unit * self.held_out[-1]:.4g} {label} = {self.held_out[-1] / self.floor:.2f} x the "
                   f"floor" + (f" (unexplained: above {AT_FLOOR:g} x)" if self.unexplained else " (at the floor)"))
        out += [f"  not tried: {name}, it fits only by trading the base away (a base parameter's 95 % band "
                f"{ratio:.3g} x its tolerance)" for name, ratio in self.traded.items()]
        return out


def select(rig: Rig, points: SteadyPoints, terms: Sequence[str] = tuple(TERMS), *, current_measured: bool = False,
           held: Mapping[str, float] | None = None, progress: Callable[[int, int], None] | None = None) -> Selection:
    """Forward selection of terms by cross-fitted held-out RMS (module docstring); ``progress(done, most)``."""
    accepted: list[str] = []
    current = cross_fit(rig, points, accepted, current_measured=current_measured, held=held)
    history, rounds = [current.rms(points)], []
    floor = points.noise_floor
    done, most = 0, len(terms) * (len(terms) + 1) // 2
    scales = Scales.of(rig, points)
    starts = {k.path: k.start for k in base_knobs(rig, scales, current_measured)}
    traded: dict[str, float] = {}
    while history[-1] > AT_FLOOR * floor:
        tried, fits = {}, {}
        for name in terms:
            if name in accepted or (name in LAW_TERMS and LAW_TERMS & set(accepted)) or name in traded:
                continue
            structure = [*accepted, name]
            knobs = len(structure_knobs(rig, scales, structure, current_measured, held))
            if len(points) // 2 < knobs + SPARE_POINTS:
                continue  # a half could not pin it
            # a term that only fits by trading the base away (mu against the supports, a drag against the load) is
            # none: the data would pin nothing of the base beside it
            whole = fit(rig, points, structure, current_measured=current_measured, held=held)
            assessment = whole.assessment(points, rig, starts)
            base = [p for p in assessment.names if p in starts]
            ratio = max((assessment.half_width[p] / assessment.band[p] for p in base if assessment.band[p] > 0),
                        default=0.0)
            done += 1
            if progress is not None:
                progress(done, most)
            if not ratio <= TRADED_RATIO:
                traded[name] = ratio
                continue
            fits[name] = cross_fit(rig, points, structure, current_measured=current_measured, held=held,
                                   starts=current.fits)
            tried[name] = fits[name].rms(points)
        rounds.append(tried)
        if not tried:
            break
        best = min(tried, key=tried.get)
        if tried[best] > (1.0 - MIN_IMPROVEMENT) * history[-1]:
            break
        accepted.append(best)
        current = fits[best]
        history.append(tried[best])
    return Selection(accepted, rounds, history, floor, current, traded)


__all__ = ["AT_FLOOR", "CrossFit", "FittedModel", "Knob", "LAW_TERMS", "MIN_IMPROVEMENT", "Scales", "Selection",
           "SteadyPoints", "TERMS", "Term", "base_knobs", "build", "cross_fit", "fit", "halves", "knob_values",
           "model_current", "select", "steady_points", "structure_knobs", "term_knobs"]
