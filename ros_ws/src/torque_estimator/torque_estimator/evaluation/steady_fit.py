"""Our model fitted to steady operating points: the unknowns a user cannot know, and what the model lacks.

A *steady point* is a drive held at one speed against a known load: mean worm speed
omega [rad/s], mean motor torque T [N m] (K_t x the drive current; the EPOS reports it
directly) with its standard error, load tau_load [N m] (+ opposes + rotation). The model is
the project's: :class:`~worm_model.residuals.extended.ExtendedModel` (Eq. 28 at zero
acceleration with the rig's friction law, the drive motor's drags on the worm shaft, the
load motors' drags on the gear shaft) plus effects, evaluated through its drive current,
so the estimators invert exactly what is fitted here.

The fit (:func:`fit`): scipy least squares of the model's torque against the measured one
over the parameters of a *structure*: the base (:func:`base_knobs`: the tooth-thread mu as a
constant, the worm shaft's Coulomb and viscous drags, the gear shaft's Coulomb drag: the
paper's support frictions) plus named *terms* (:data:`TERMS`), each rig leaves (a dotted
path, as worm_model.residuals.free names them) or an effect's values and grid speed,
every one inside physical bounds (no negative drag, mu below Remark 4's engagement limit).
Terms with a speed scale are started from several speeds (:data:`SPEED_STARTS`), the best
kept.

What the model lacks (:func:`select`): the points are split in two halves, alternate
speeds in each direction (:func:`halves`); a structure is scored by its *cross-fitted*
held-out RMS (fit on one half, predict the other, both ways). Starting from the base, the
term whose addition lowers that RMS most is accepted if it lowers it by at least
:data:`MIN_IMPROVEMENT` (relative) while the RMS is above :data:`AT_FLOOR` x the noise
floor (the RMS of the points' standard errors); the loop stops when no term qualifies. A
term that the data does not need is not named; a residual left above the floor with no
term explaining it is reported as such.

Two terms are outside the residual analysis' vocabulary (worm_model.residuals.effects), so
they are defined here as effects of the same protocol: :class:`SupportStribeck` (a
Stribeck rise of a shaft support's Coulomb friction at low speed) and
:class:`ModeDependentMu` (a different mu on the driving and the coast flank: the
direction asymmetry the mode physics does not explain).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray
from worm_model.residuals.effects import EFFECTS, GridParameter, Parameter
from worm_model.residuals.extended import ExtendedModel
from worm_model.residuals.free import set_values
from worm_model.residuals.model import Signals

#: a term is accepted when it lowers the cross-fitted held-out RMS by at least this fraction
MIN_IMPROVEMENT = 0.10
#: no term is added once the held-out RMS is within this multiple of the noise floor
AT_FLOOR = 1.1
#: starting speeds [rad/s of the worm] tried for a term's speed scale (the best fit is kept)
SPEED_STARTS = (0.1, 0.3, 1.0)
#: a Stribeck term's speed scale stays below this fraction of the fastest point's speed: a rise that
#: decays over the whole range is not a low-speed effect (the vocabulary's viscous_drag exponent is that)
LOW_SPEED_FRACTION = 0.1


# --------------------------------------------------------------------------- points
@dataclass(frozen=True)
class SteadyPoints:
    """Steady operating points, arrays of shape (n,): omega [rad/s], torque, torque_sem, tau_load [N m]."""

    omega: FloatArray
    torque: FloatArray
    torque_sem: FloatArray
    tau_load: FloatArray

    def __len__(self) -> int:
        return len(self.omega)

    def subset(self, mask: np.ndarray) -> "SteadyPoints":
        return SteadyPoints(*(np.asarray(a)[mask] for a in (self.omega, self.torque, self.torque_sem, self.tau_load)))

    @property
    def noise_floor(self) -> float:
        """[N m] the RMS of the points' standard errors: no model can predict held-out points better."""
        return float(np.sqrt(np.mean(self.torque_sem ** 2)))


def halves(omega: FloatArray) -> np.ndarray:
    """Half (0 or 1) of every point: alternate speeds in each direction, counted from the slowest (half 0)."""
    omega = np.asarray(omega, dtype=float)
    out = np.zeros(len(omega), dtype=int)
    for side in (omega > 0, omega < 0):
        idx = np.flatnonzero(side)
        out[idx[np.argsort(np.abs(omega[idx]))]] = np.arange(len(idx)) % 2
    return out


def signals(model: ExtendedModel, omega: FloatArray, tau_load: FloatArray) -> Signals:
    """The model's inputs at steady points: zero acceleration, worm angle 0 (no periodic effect is fitted)."""
    return model.signals(omega, 0.0, tau_load, 0.0, run=np.arange(len(np.atleast_1d(omega))))


def model_torque(model: ExtendedModel, omega: FloatArray, tau_load: FloatArray) -> FloatArray:
    """Motor torque K_t i [N m] the model expects at steady speed omega [rad/s] against tau_load [N m]."""
    return model.drive_torque(signals(model, omega, tau_load))


# --------------------------------------------------------------------------- effects outside the vocabulary
class _StudyEffect:
    """What ExtendedModel and the estimators read of an effect (worm_model.residuals.effects.Effect)."""

    family = "regression"
    fitted_signal = "current_drive"
    grid_parameters: tuple[GridParameter, ...] = ()

    def grid(self, rig, signals):  # pragma: no cover - the residual analysis' screening is not run on these
        return [{}]

    def unavailable(self, rig, signals):
        return None

    def signature(self, rig, signals, grid):
        return "omega_worm [rad/s]", signals.omega


class SupportStribeck(_StudyEffect):
    """A Stribeck rise of a shaft support's Coulomb friction: ``torque`` exp(-|omega_worm| / ``speed``) sign(omega).

    ``shaft`` "gear" adds it to the gear side (where the load is: it is reflected through the
    mesh with the engaged flank's K_s, so it raises the torque while lifting and *lowers* it
    while lowering a self-locked load); "worm" to the worm side (both directions alike).
    ``speed`` [rad/s] is the worm's speed at which the rise has decayed to 1/e.
    """

    parameters = (Parameter("torque", "N m", "support friction added at standstill"),)
    grid_parameters = (GridParameter("speed", "rad/s", "worm speed over which it decays"),)

    def __init__(self, shaft: str) -> None:
        self.shaft = shaft
        self.name = f"{shaft}_support_stribeck"
        self.description = f"Stribeck rise of the {shaft} shaft's support friction at low speed"

    def shapes(self, rig, signals, grid):
        sigma = np.where(signals.omega < 0.0, -1.0, 1.0)
        return {f"{self.shaft}_torque": (sigma * np.exp(-np.abs(signals.omega) / grid["speed"]))[:, None]}


class ModeDependentMu(_StudyEffect):
    """mu + ``difference`` / 2 on the driving flank (the load opposes the motion) and - ``difference`` / 2 on the
    coast flank: a direction asymmetry of the tooth friction beyond what the mode physics gives."""

    name = "mode_dependent_mu"
    description = "a different mu on the driving and the coast flank"
    parameters = (Parameter("difference", "1", "mu(driving flank) - mu(coast flank)"),)

    def shapes(self, rig, signals, grid):
        sigma = np.where(signals.omega < 0.0, -1.0, 1.0)
        return {"mu": (0.5 * np.sign(sigma * signals.tau_load))[:, None]}


# --------------------------------------------------------------------------- structure
@dataclass(frozen=True)
class Knob:
    """One fitted number: a rig leaf (``path``: dotted) or an effect's value/grid (``path``: effect.parameter).

    ``start`` and ``low``/``high`` in SI; ``speed``: a speed scale, started from :data:`SPEED_STARTS`.
    """

    path: str
    start: float
    low: float
    high: float
    speed: bool = False  # a Stribeck speed scale: multi-start, capped at LOW_SPEED_FRACTION of the data's range


@dataclass(frozen=True)
class Term:
    """A named addition to the base model: its knobs and, when it is an effect, the effect."""

    name: str
    description: str
    knobs: tuple[Knob, ...]
    effect: object | None = None


def base_knobs(rig: Rig) -> tuple[Knob, ...]:
    """The paper's unknowns without a speed law: mu (constant) and the support frictions (module docstring)."""
    mu_max = 0.9 * rig.gearbox.mu_engagement_max
    return (Knob("friction.mu_constant", min(0.12, 0.5 * mu_max), 0.0, mu_max),
            Knob("drive_motor.coulomb_drag", 5e-4, 0.0, 0.05),
            Knob("drive_motor.viscous_drag", 1e-5, 0.0, 1e-2),
            Knob("load_motor.coulomb_drag", 4e-3, 0.0, 1.0))


#: the terms :func:`select` tries (module docstring); SupportStribeck / ModeDependentMu are defined above
TERMS: dict[str, Term] = {t.name: t for t in (
    Term("tooth_stribeck", "the paper's Stribeck law of the tooth-thread mu: mu_k + mu_s exp(-V_s / V_st)^2",
         (Knob("friction.stribeck_rise", 0.05, 0.0, 1.0), Knob("friction.stribeck_speed", 3e-3, 1e-5, 0.5, True))),
    Term("gear_support_stribeck", SupportStribeck("gear").description,
         (Knob("gear_support_stribeck.torque", 5e-3, 0.0, 1.0), Knob("gear_support_stribeck.speed", 0.3, 1e-3, 50.0,
                                                                      True)), SupportStribeck("gear")),
    Term("worm_support_stribeck", SupportStribeck("worm").description,
         (Knob("worm_support_stribeck.torque", 5e-4, 0.0, 0.05), Knob("worm_support_stribeck.speed", 0.3, 1e-3, 50.0,
                                                                       True)), SupportStribeck("worm")),
    Term("viscous_drag", EFFECTS["viscous_drag"].description,
         (Knob("viscous_drag.worm_torque", 1e-4, 0.0, 0.1), Knob("viscous_drag.gear_torque", 1e-3, 0.0, 1.0),
          Knob("viscous_drag.exponent", 1.0, 0.25, 2.0)), EFFECTS["viscous_drag"]),
    Term("mode_dependent_mu", ModeDependentMu.description,
         (Knob("mode_dependent_mu.difference", 0.0, -0.1, 0.1),), ModeDependentMu()),
)}


def _stribeck_speed_start(rig: Rig, speed: float) -> float:
    """A worm speed [rad/s] as the sliding speed [m/s] of friction.stribeck_speed."""
    return speed * rig.gearbox.worm_pitch_radius / math.cos(rig.gearbox.lead_angle)


@dataclass
class FittedModel:
    """A fitted structure: the model, its values by knob path, its in-sample RMS [N m]."""

    structure: tuple[str, ...]
    model: ExtendedModel
    values: dict[str, float]
    rms: float
    knobs: tuple[Knob, ...] = ()

    def torque(self, omega: FloatArray, tau_load: FloatArray) -> FloatArray:
        return model_torque(self.model, omega, tau_load)


def build(base: Rig, structure: Sequence[str], values: Mapping[str, float]) -> ExtendedModel:
    """The model of a structure with ``values`` (knob path -> SI value); leaves not in ``values`` as in ``base``."""
    leaves = {p: v for p, v in values.items() if p.split(".")[0] in {f.name for f in dataclasses.fields(Rig)}}
    rig = set_values(base, list(leaves), list(leaves.values()))
    effects = []
    for name in structure:
        term = TERMS[name]
        if term.effect is None:
            continue
        params = {p.name: values[f"{name}.{p.name}"] for p in term.effect.parameters}
        grid = {g.name: values[f"{name}.{g.name}"] for g in term.effect.grid_parameters}
        effects.append((term.effect, params, grid))
    return ExtendedModel(rig, effects)


def structure_knobs(base: Rig, structure: Sequence[str]) -> tuple[Knob, ...]:
    return base_knobs(base) + tuple(k for name in structure for k in TERMS[name].knobs)


def fit(base: Rig, points: SteadyPoints, structure: Sequence[str] = (),
        start: Mapping[str, float] | None = None) -> FittedModel:
    """Least squares of the structure's torque against the points (module docstring); base: the rig whose
    other leaves hold (its friction law with ``stribeck_rise`` 0 is a constant mu). ``start``: knob values
    (e.g. a smaller structure's fit) tried as one more starting point."""
    base = set_values(base, ["friction.stribeck_rise"], [0.0]) if "tooth_stribeck" not in structure else base
    knobs = structure_knobs(base, structure)
    fastest = float(np.max(np.abs(points.omega)))
    low = np.array([k.low for k in knobs])
    high = np.array([min(k.high, LOW_SPEED_FRACTION * (_stribeck_speed_start(base, fastest)
                                                       if k.path == "friction.stribeck_speed" else fastest))
                     if k.speed else k.high for k in knobs])
    scale = np.maximum(np.abs(np.array([k.start for k in knobs])), (high - low) * 1e-3)

    def residual(x: FloatArray) -> FloatArray:
        model = build(base, structure, dict(zip((k.path for k in knobs), x)))
        return (model_torque(model, points.omega, points.tau_load) - points.torque) * 1e3  # [mN m]

    speed_knobs = [j for j, k in enumerate(knobs) if k.speed]
    starts = [np.array([k.start for k in knobs])]
    if start:
        starts.append(np.array([start.get(k.path, k.start) for k in knobs]))
    for j in speed_knobs:
        for s in SPEED_STARTS:
            x0 = starts[0].copy()
            x0[j] = _stribeck_speed_start(base, s) if knobs[j].path == "friction.stribeck_speed" else s
            starts.append(x0)
    best = None
    for x0 in starts:
        x0 = np.clip(x0, low + 1e-6 * (high - low), high - 1e-6 * (high - low))
        result = least_squares(residual, x0, bounds=(low, high), x_scale=scale, method="trf", xtol=1e-9,
                               ftol=1e-10, gtol=1e-10, max_nfev=1000)
        if best is None or result.cost < best.cost:
            best = result
    values = dict(zip((k.path for k in knobs), (float(v) for v in best.x)))
    model = build(base, structure, values)
    rms = float(np.sqrt(np.mean(((model_torque(model, points.omega, points.tau_load) - points.torque)) ** 2)))
    return FittedModel(tuple(structure), model, values, rms, knobs)


@dataclass
class CrossFit:
    """Each point predicted by the structure fitted on the other half: torque [N m] and the two fits."""

    structure: tuple[str, ...]
    predicted: FloatArray
    fits: tuple[FittedModel, FittedModel]  # fitted on half 0, on half 1

    def rms(self, points: SteadyPoints) -> float:
        return float(np.sqrt(np.mean((self.predicted - points.torque) ** 2)))


def cross_fit(base: Rig, points: SteadyPoints, structure: Sequence[str] = (),
              starts: tuple[FittedModel, FittedModel] | None = None) -> CrossFit:
    """Fit on each half, predict the other (:func:`halves`); ``starts``: fits per half to start from."""
    half = halves(points.omega)
    predicted = np.full(len(points), np.nan)
    fits = []
    for h in (0, 1):
        fitted = fit(base, points.subset(half == h), structure, starts[h].values if starts else None)
        held = half != h
        predicted[held] = fitted.torque(points.omega[held], points.tau_load[held])
        fits.append(fitted)
    return CrossFit(tuple(structure), predicted, (fits[0], fits[1]))


@dataclass
class Selection:
    """The forward selection (module docstring): per round, every term tried and its held-out RMS [N m]."""

    accepted: list[str]
    rounds: list[dict[str, float]]  # term -> held-out RMS with it added, per round
    held_out: list[float]  # held-out RMS of the accepted structure after each round (the base first)
    floor: float
    final: CrossFit = field(repr=False, default=None)  # type: ignore[assignment]

    @property
    def unexplained(self) -> bool:
        """Held-out RMS still above AT_FLOOR x the floor with no term qualifying."""
        return self.held_out[-1] > AT_FLOOR * self.floor


def select(base: Rig, points: SteadyPoints, terms: Sequence[str] = tuple(TERMS),
           progress: Callable[[int], None] | None = None) -> Selection:
    """Forward selection of terms by cross-fitted held-out RMS (module docstring)."""
    accepted: list[str] = []
    current = cross_fit(base, points, accepted)
    history, rounds = [current.rms(points)], []
    floor = points.noise_floor
    done = 0
    while history[-1] > AT_FLOOR * floor:
        tried = {}
        fits = {}
        for name in terms:
            if name in accepted:
                continue
            fits[name] = cross_fit(base, points, [*accepted, name], current.fits)
            tried[name] = fits[name].rms(points)
            done += 1
            if progress is not None:
                progress(done)
        rounds.append(tried)
        if not tried:
            break
        best = min(tried, key=tried.get)
        if tried[best] > (1.0 - MIN_IMPROVEMENT) * history[-1]:
            break
        accepted.append(best)
        current = fits[best]
        history.append(tried[best])
    return Selection(accepted, rounds, history, floor, current)


__all__ = ["AT_FLOOR", "CrossFit", "FittedModel", "Knob", "MIN_IMPROVEMENT", "ModeDependentMu", "Selection",
           "SteadyPoints", "SupportStribeck", "TERMS", "Term", "base_knobs", "build", "cross_fit", "fit", "halves",
           "model_torque", "select", "signals"]
