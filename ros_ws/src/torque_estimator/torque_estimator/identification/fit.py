"""Fit the rig's uncertain parameters, the effects it lacks and its sensors' noise to a recorded run.

Two roads, chosen by what the record is:

Steady points (identification.steady)
    Every run of the record is held at one speed against one load (a folder of EPOS exports, a joint
    held at a few speeds): each run is one point, and the base unknowns (mu, the worm shaft's drags,
    the gear shaft's Coulomb drag; K_t where the record measured a current) are fitted with the terms
    a cross-fitted term selection accepts (a support's low-speed rise, the tooth mu law's shape, a
    viscous drag law): what one load can tell, mu against the supports' friction, through how they
    change with speed.
Time series (worm_model.residuals)
    Anything else (an excitation with speed and load steps, a robot's run): the residual analysis of
    the drive current sample by sample, with its settings for identification (:data:`IDENTIFY_SETTINGS`).

Which parameters (:func:`candidates`)
    The standard set of worm_model.residuals.free (mu, K_t, the drive motor's drags, the gear shaft's
    Coulomb drag, the rotor inertia) plus the output's inertia (``gearbox.gear_inertia``: a datasheet
    does not give it), whatever their ``source:`` or ``assumption:``, plus the rig file's ``free:``
    list; ``--free`` replaces the set. The geometry stays as declared (the lead and pressure angles
    trade off against mu, the radii against K_t). Then identification.identifiability decides what the
    record can tell: no inertia from held speeds, no K_t from a torque channel, and of the rest only
    what the fit pins within its tolerance band and off its physical bound; the others are held at
    their declared values, refitted out, and named with why (:class:`~torque_estimator.identification.
    identifiability.Held`). A record that identifies nothing is refused (:class:`IdentificationError`).
Which effects (time series, :data:`IDENTIFY_SETTINGS`)
    Every effect ``residuals`` accepts, with four settings changed: an effect must lower the
    held-out RMS of the current by 0.1 % (residuals: 2 %), it may raise the transmission
    error's by up to 5 % (residuals: as much as the first; no estimator reads the transmission
    error, and a Stribeck law moves it by ~3 % through mu), no effect is refused because the
    current is already near its noise floor (residuals: within 1.1 x), and none is dropped for
    taking only a share of a residual outside the vocabulary (residuals' step 5: that share is
    still a share of the static map the estimator inverts).  An estimator
    averages the current over hundreds of samples: a systematic 0.01 A, half the per-sample
    noise, is ~5 % of the load range on the coast flank, where the current moves little with
    the load; a Stribeck rise, a load-dependent mu or the PWM ripple's sampled bias each buy
    0.1-0.5 % of the RMS and 0.5-2 % of the range at the estimate.  The BIC test and the
    consistency over the held-out blocks (the block bootstrap) still guard against fitting noise.
Which samples (time series, :data:`QUASI_STATIC_ACCELERATION`)
    Those an estimator reads as steady: |alpha| <= 200 rad/s^2, LiveEstimator's default
    TRANSIENT threshold.  Above it the residual is the dynamics a quasi-static map leaves out
    (the current sensor's filter, the inductance, backlash impacts at reversals: 0.08 A RMS at
    200-1000 rad/s^2 and 0.35 A above, against the 0.03 A noise of steady samples, with the
    true model and every true effect): 2 % of the samples made half the residual's variance and
    hid every effect smaller than it from the held-out blocks.
The sensors (identification.noise)
    The current's and the speed's white noise and grid step, and the encoder's counts per turn, as
    the record shows them: the observers' gains and the estimators' thresholds follow from them.
Figures (simulated rig with every default effect on, the rig file off by mu x1.3, K_t x1.05, drags
    x2, 85 s record, 17 held-out points, % of the load range; evaluation.identified): 0.5 % / no
    guard took the identified model to 2.97 / 6.96 % (mean / max); these settings to 0.71 / 1.52,
    0.58 / 1.91 and 0.92 / 2.15 % (seeds 1-3).
Ranges
    The speed and load range the record covered (99.9 percentile of |omega_worm|, 0.5 / 99.5
    percentiles of tau_load) go into the written file's ``identification:`` section: the estimators take
    their table, their OUT_OF_CALIBRATION limits and their default load prior from there. A record of one
    load has no range: the model is trusted within :data:`ONE_LOAD_MARGIN` of that load either side (it
    has seen that load only; beyond that it extrapolates).
No ROS.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from worm_model.physics.parameters import Rig, default_rig_path, load_rig
from worm_model.residuals import analysis as an
from worm_model.residuals.extended import ExtendedModel
from worm_model.residuals.fitting.fitting import Fit
from worm_model.residuals.free import (LOWER_BOUNDS, STANDARD_REFIT, check_free, get_value, read_free,
                                       resolve_parameters)
from worm_model.residuals.model import prepare_signals
from worm_model.residuals.report import correction_line, corrections, mu_line
from worm_model.rig_data.schema import MeasuredData

from torque_estimator.identification import steady
from torque_estimator.identification.identifiability import Assessment, Held, RecordFacts
from torque_estimator.identification.noise import SensorNoise, measure, measure_held
from torque_estimator.errors import IdentificationError

#: the residual analysis' settings for identification (module docstring: what differs and why)
IDENTIFY_SETTINGS = an.Settings(min_improvement=0.001, other_signal_tolerance=0.05, at_floor=0.0, max_effects=10,
                                check_outside_vocabulary=False)
#: [rad/s^2] samples accelerating faster are left out of the fit (module docstring: LiveEstimator's TRANSIENT)
QUASI_STATIC_ACCELERATION = 200.0
#: fewer samples than this in either set of the split cannot rank the candidates
MIN_SAMPLES = 200
#: a one-load record's model is trusted within this fraction of the load either side (module docstring)
ONE_LOAD_MARGIN = 0.5
#: the output's inertia: fitted besides the standard set (module docstring)
OUTPUT_INERTIA = "gearbox.gear_inertia"
#: the inertias: never fitted from held speeds
INERTIAS = frozenset({"drive_motor.rotor_inertia", "gearbox.worm_inertia", "gearbox.gear_inertia"})


def default_refit(rig_file: str | Path | None, free: Sequence[str] | None = None) -> tuple[list[str], str]:
    """(parameters to fit, where the choice came from): ``free`` if given, else the standard set and the output's
    inertia (whatever the provenance of the declared numbers) plus the rig file's ``free:`` list (module
    docstring). The friction model's mu appears as ``friction.mu`` (worm_model.residuals.free.resolve_parameters
    names it for the rig).

    Raises:
        ParameterError: an unreadable rig file or an unknown parameter name.
    """
    if free is not None:
        return check_free(free, "--free"), "--free"
    listed = read_free(rig_file)
    names = list(STANDARD_REFIT) + [OUTPUT_INERTIA] + [n for n in listed if n not in STANDARD_REFIT]
    why = "the standard set and the output's inertia, whatever the provenance of the declared numbers"
    return list(dict.fromkeys(names)), why + (" + the rig file's free: list" if listed else "")


def record_facts(data: MeasuredData, steady_record: bool) -> RecordFacts:
    """What the record holds (identifiability.RecordFacts): its distinct loads and speeds, whether it moves through
    speeds (a time series) or holds them, and its current's provenance."""
    finite = np.isfinite(data.tau_load)
    load = data.tau_load[finite]
    scale = max(float(np.max(np.abs(load))) if len(load) else 0.0, 1e-12)
    loads = len(np.unique(np.round(load / scale, 3))) if len(load) else 0
    speed = data.omega_worm[np.isfinite(data.omega_worm)]
    top = max(float(np.max(np.abs(speed))) if len(speed) else 0.0, 1e-12)
    speeds = len(np.unique(np.round(speed / top, 2)))
    directions = int(np.any(speed > 0)) + int(np.any(speed < 0))
    return RecordFacts(loads, speeds, not steady_record, bool(data.current_from_torque), directions)


def a_priori(names: Sequence[str], facts: RecordFacts) -> list[Held]:
    """What the record cannot tell whatever the fit (identifiability module docstring)."""
    out = []
    for name in names:
        if name in INERTIAS and not facts.accelerates:
            out.append(Held(name, "held speeds", "(the record holds its speeds: no acceleration shows an inertia); "
                                                 "to identify it, record speed steps"))
        elif name == "drive_motor.torque_constant" and facts.current_from_torque:
            out.append(Held(name, "torque channel", "(the record's current is the drive's torque channel over "
                                                    "K_t: K_t x current is what was measured)"))
    return out


@dataclass
class Identification:
    """The identified model, how it was found, and what the record covered."""

    model: ExtendedModel
    declared: Rig
    road: str  # "steady points" or "time series"
    fitted: list[str]  # rig leaves identified
    choice: str  # where the candidate list came from
    corrections: dict[str, tuple[float, float, float]]  # parameter -> (declared, identified, 95 % half-width), SI
    held: list[Held]
    found: list[str]  # terms or effects the model gained
    rms_before: float  # [A] the rig file as declared
    rms_after: float  # [A] held-out (cross-fitted for steady points)
    speed_max: float  # [rad/s] covered
    torque_range: tuple[float, float]  # [N m] covered (widened for one load: ONE_LOAD_MARGIN)
    loads: int  # distinct loads in the record
    rig_time: float  # [s] of samples
    samples: int
    noise: SensorNoise | None
    report: list[str] = field(default_factory=list)  # the road's own lines (selection rounds, ...)
    analysis: an.Analysis | None = None  # the residual analysis (time series)
    problem: an.Problem | None = None

    def correction_lines(self) -> list[str]:
        """The corrections as ``residuals`` prints them (and mu as a friction coefficient)."""
        if self.analysis is not None and self.problem is not None:
            rows = [r for r in corrections(self.problem, self.analysis) if r["name"] in self.fitted]
            lines = [correction_line(row) for row in rows]
            mu = mu_line(self.problem, self.analysis)
            return lines + ([mu] if mu else [])
        out = []
        for name, (before, after, half) in self.corrections.items():
            ratio = f"; x{after / before:.3g}" if before else ""
            out.append(f"parameter {name}: declared {before:.6g} -> {after:.6g} +- {half:.2g} (95 %{ratio})")
        return out

    def section(self, source: str) -> dict:
        """The ``identification:`` section of the written file."""
        return {
            "source": source,
            "road": self.road,
            "friction_law": {"declared": self.declared.friction.model, "identified": self.model.rig.friction.model},
            "samples": int(self.samples), "rig_time_s": round(self.rig_time, 3),
            "speed_max": {"value": round(self.speed_max, 6), "unit": "rad/s"},
            "torque_min": {"value": round(self.torque_range[0], 9), "unit": "N m"},
            "torque_max": {"value": round(self.torque_range[1], 9), "unit": "N m"},
            "loads": int(self.loads),
            "fitted": list(self.fitted), "fitted_choice": self.choice,
            "held": {h.parameter: h.detail for h in self.held},
            "effects_found": list(self.found),
            "rms_before_A": float(f"{self.rms_before:.6g}"),
            "rms_after_A": float(f"{self.rms_after:.6g}"),
        }


def identify(data: MeasuredData, rig_file: str | Path | None, free: Sequence[str] | None = None,
             settings: an.Settings = IDENTIFY_SETTINGS,
             progress: Callable[[str, int, int], None] | None = None) -> Identification:
    """Fit the rig file's uncertain parameters, the effects and the sensors' noise to ``data`` (module docstring).

    Raises:
        ParameterError: a bad rig file or parameter name.
        IdentificationError: too few usable samples, or nothing the record can identify.
    """
    declared = load_rig(rig_file or None)
    names, choice = default_refit(rig_file, free)
    origin = "--free" if free is not None else str(rig_file or default_rig_path())
    names = resolve_parameters(declared, names, origin)
    points = steady.steady_points(data)
    if points is not None:
        ident = _steady_road(data, points, declared, names, choice, progress)
    else:
        ident = _time_series_road(data, declared, names, choice, settings, progress)
    if not ident.fitted and not ident.found:
        raise IdentificationError(
            f"{data.source}: nothing in this record identifies any parameter of the rig file; "
            + "; ".join(h.line().removeprefix("not identifiable from this run: ") for h in ident.held))
    return ident


def _ranges(data: MeasuredData) -> tuple[float, tuple[float, float], int]:
    """(speed_max [rad/s], load range [N m], distinct loads) the record covered (module docstring: Ranges)."""
    finite = np.isfinite(data.current_drive) & np.isfinite(data.omega_worm)
    speed = np.abs(data.omega_worm[finite])
    tau = data.tau_load[np.isfinite(data.tau_load)]
    low, high = (float(np.percentile(tau, 0.5)), float(np.percentile(tau, 99.5)))
    scale = max(float(np.max(np.abs(tau))), 1e-12)
    loads = len(np.unique(np.round(tau / scale, 3)))
    if not high - low > 1e-6 * scale:  # one load: trusted within the margin of it
        load = 0.5 * (low + high)
        low, high = load - ONE_LOAD_MARGIN * abs(load), load + ONE_LOAD_MARGIN * abs(load)
        if not high > low:
            low, high = -1e-3, 1e-3  # no load at all: a token range around 0
    return float(np.percentile(speed, 99.9)), (low, high), loads


def _rig_time(data: MeasuredData) -> float:
    return float(sum(np.ptp(data.t[data.run == r]) + data.sample_period for r in np.unique(data.run)))




# --------------------------------------------------------------------------- steady points
def _steady_road(data: MeasuredData, points: steady.SteadyPoints, declared: Rig, names: list[str], choice: str,
                 progress: Callable[[str, int, int], None] | None) -> Identification:
    """Steady points: term selection, then the base knobs the points pin (module docstring)."""
    facts = record_facts(data, steady_record=True)
    held = a_priori(names, facts)
    current_measured = "drive_motor.torque_constant" in names and not facts.current_from_torque
    mu_name = "friction.mu_constant"
    wanted = {n if n not in ("friction.scale", "friction.mu_constant") else mu_name for n in names}
    scales = steady.Scales.of(declared, points)
    base = steady.base_knobs(declared, scales, current_measured)
    fixed = {k.path: k.start for k in base if k.path not in wanted}  # not asked for: the declared value
    for name in names:
        if name not in {k.path for k in base} and name not in (mu_name, "friction.scale") \
                and name not in {h.parameter for h in held}:
            held.append(Held(name, "steady", "(steady points fit the drags, mu and K_t only)"))
    selection = steady.select(declared, points, current_measured=current_measured, held=fixed,
                              progress=None if progress is None else lambda d, m: progress("terms tried", d, m))
    structure = list(selection.accepted)
    starts = {k.path: k.start for k in base}
    base_paths = [k.path for k in base if k.path not in fixed]
    fitted = steady.fit(declared, points, structure, current_measured=current_measured, held=fixed)
    for _ in range(len(base_paths) + len(structure) + 1):
        # a support's rise that fitted to nothing is no term
        empty = [n for n in structure if n.endswith("_support_stribeck")
                 and fitted.values[steady.term_knobs(n, declared, scales)[0].path] <= 0.0]
        if empty:
            structure = [n for n in structure if n not in empty]
        else:
            assessment = fitted.assessment(points, declared, starts)
            worst = assessment.worst(base_paths)
            if worst is None:
                break
            held.append(assessment.held(worst, facts))
            fixed[worst] = starts[worst]
            base_paths.remove(worst)
        fitted = steady.fit(declared, points, structure, current_measured=current_measured, held=fixed)
    final_cross = steady.cross_fit(declared, points, structure, current_measured=current_measured, held=fixed)
    before = steady.model_current(ExtendedModel(declared), points.omega, points.tau_load)
    assessment = fitted.assessment(points, declared, starts)
    identified = [k.path for k in fitted.knobs if k.path.split(".")[0] in steady.RIG_SECTIONS]
    corrections_ = {p: (starts.get(p, get_value(declared, p)), fitted.values[p], assessment.half_width[p])
                    for p in identified}
    speed_max, torque_range, loads = _ranges(data)
    unit = declared.drive_motor.torque_constant * 1e3
    report = selection.lines(unit, "mN m") if facts.current_from_torque else selection.lines()
    if structure != selection.accepted:
        report.append(f"  kept: {', '.join(structure) or 'none'} (a rise that fitted to nothing is no term)")
    return Identification(
        model=fitted.model, declared=declared, road="steady points", fitted=identified, choice=choice,
        corrections=corrections_, held=held, found=list(structure),
        rms_before=float(np.sqrt(np.mean((before - points.current) ** 2))),
        rms_after=final_cross.rms(points), speed_max=speed_max, torque_range=torque_range, loads=loads,
        rig_time=_rig_time(data), samples=len(data), report=report,
        noise=measure_held(data.current_drive, data.omega_worm, None, data.run))


# --------------------------------------------------------------------------- time series
def _time_series_road(data: MeasuredData, declared: Rig, names: list[str], choice: str, settings: an.Settings,
                      progress: Callable[[str, int, int], None] | None) -> Identification:
    """The residual analysis on the samples, on the parameters the record pins (module docstring)."""
    finite = np.isfinite(data.current_drive)
    signals = prepare_signals(declared, data, settings.alpha_time_constant, settings.reference_temperature)
    quasi_static = np.abs(signals.alpha) <= QUASI_STATIC_ACCELERATION
    facts = record_facts(data, steady_record=False)
    held = a_priori(names, facts)
    free = [n for n in names if n not in {h.parameter for h in held}]
    settings = settings.for_rig(declared)
    split = an.make_split(signals, replace(settings, refit=tuple(free)), finite & quasi_static)
    for name, mask in (("training", split.train), ("held-out", split.held_out)):
        if mask.sum() < MIN_SAMPLES:
            raise IdentificationError(f"{data.source}: only {int(mask.sum())} {name} samples with |omega_worm| >= "
                                      f"{settings.min_speed:g} rad/s and |alpha| <= {QUASI_STATIC_ACCELERATION:g} "
                                      f"rad/s^2 (need {MIN_SAMPLES}): record longer")

    def problem_of(refit: Sequence[str]) -> an.Problem:
        return an.Problem(declared, [], signals, data.current_drive, split, replace(settings, refit=tuple(refit)))

    # the parameters the declared structure pins (identifiability), held one at a time, worst first
    for _ in range(len(free)):
        declared_fit = an.fit(problem_of(free), [])
        worst, assessment = _worst(declared_fit, declared, free)
        if worst is None:
            break
        held.append(assessment.held(worst, facts))
        free.remove(worst)
    problem = problem_of(free)
    result = an.analyse(problem, progress)
    # what the final structure left on a physical bound is no value for it: held, and the analysis repeated
    for _ in range(len(free)):
        worst, assessment = _worst(result.final, declared, free, bound_only=True)
        if worst is None:
            break
        held.append(assessment.held(worst, facts))
        free.remove(worst)
        problem = problem_of(free)
        result = an.analyse(problem, progress)
    model = ExtendedModel(*an.extended_effects(result), settings.alpha_time_constant)
    aliased = result.aliased_parameters
    fitted = [p for p in problem.free if p not in aliased]
    final = result.final
    corrections_ = {p: (get_value(declared, p), get_value(model.rig, p), float(final.free_ci.get(p, math.nan)))
                    for p in fitted}
    speed_max, torque_range, loads = _ranges(data)
    moving = np.abs(data.omega_worm) >= settings.min_speed
    noise = measure(data.current_drive, data.omega_worm, data.theta_worm, data.run, moving & quasi_static)
    return Identification(
        model=model, declared=declared, road="time series", fitted=fitted, choice=choice, corrections=corrections_,
        held=held, found=list(result.found), rms_before=result.rms_before, rms_after=final.rms_held_out,
        speed_max=speed_max, torque_range=torque_range, loads=loads, rig_time=_rig_time(data), samples=len(data),
        noise=noise, analysis=result, problem=problem)


def _worst(fit_: Fit, declared: Rig, free: Sequence[str], bound_only: bool = False
           ) -> tuple[str | None, Assessment]:
    """The parameter of ``free`` to hold first at a residual-analysis fit, and the assessment."""
    names = list(fit_.free)
    corr = fit_.free_correlation if fit_.free_correlation is not None else np.eye(len(names))
    at_bound = [p for p in names if p in LOWER_BOUNDS and fit_.free_values[p] <= LOWER_BOUNDS[p]]
    assessment = Assessment.of(names, fit_.free_ci, corr, declared, at_bound)
    candidates = [p for p in names if p in free]
    if bound_only:
        bound = [p for p in at_bound if p in candidates]
        return (bound[0] if bound else None), assessment
    return assessment.worst(candidates), assessment


__all__ = ["IDENTIFY_SETTINGS", "ONE_LOAD_MARGIN", "QUASI_STATIC_ACCELERATION", "Identification",
           "default_refit", "identify", "record_facts"]
