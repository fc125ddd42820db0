"""real: the model against a real worm drive's measured motor torque, and the load estimated from it.

    python -m torque_estimator.evaluation.real_drive --out out/real [--force]     (make evaluate runs it too)

The data: the T-RO 2021 worm drive's 46 steady-state EPOS exports (worm_model/data/tro2021,
SOURCE.md: 23 speeds from 1 to 200 rpm of the motor, lifting and lowering a 0.096 kg mass on a
20 mm pulley, 18.84 mN m on the gear; read by worm_model.rig_data.epos, the three dirty rows
skipped and counted). Each file is one steady point: mean speed, mean motor torque and its
standard error (from 10 consecutive blocks: the EPOS's averaging correlates neighbouring rows).
The rig file is worm_model/data/tro2021_worm_rig.yaml (their geometry and their fitted
frictions, every number cited).

Side by side on the same 46 points:

* **T-RO fit**: their model with their parameters through their equations
  (evaluation.tro2021_model, written from their paper's scripts);
* **ours, their parameters**: this project's model (Eq. 28 with the drags, through
  ExtendedModel) with the rig file's numbers (the same to 1e-10 N m: the two implementations agree);
* **ours, fitted**: the base model (constant mu, the support frictions) plus the terms the
  residual selection of evaluation.steady_fit accepts by cross-fitted held-out improvement.

The load: the points are split into two halves (alternate speeds in each direction); the
selected structure is fitted on one half and the load at the other half's points is
estimated from speed and torque alone by the extended-model estimator (estimation.
extended_model, as ``estimate`` runs it: a table of the fitted model's drive current over
speed and load, inverted), then the halves swap. The table spans the measured speeds and the
loads the model was fitted at widened by half the load on either side (:data:`LOAD_MARGIN`):
the model has seen one load only, and outside that range it is extrapolation. The margin
matters while lowering: there the model's torque is V-shaped in the load (physics.md section
8) and the other arm of the V, a load of a few mN m driven on the driving flank against the
gear support's friction, asks about the same torque as the 18.8 mN m being lowered on the
coast flank; from 0 to twice the load the estimator (which takes the driving flank's
candidate) picks that arm at 1, 2 and 6 rpm. Baseline (model-free in speed): the held-out speed's torque interpolated
from the training speeds in the same direction (linearly; the nearest at the ends), inverted
through the same estimator. The data's own bound per point: the torque's standard error
through the model's slope dT/dtau_load, in % of the load; where the model's torque is
V-shaped in the load (lowering at the slowest speeds: two loads give the measured torque),
the estimator flags AMBIGUOUS and the two candidates are reported.

The residuals tool on the same data, sample by sample (:func:`residuals_tool`:
worm_model.residuals' analysis as the ``residuals`` command runs it, with the rig file as
declared and samples down to 0.05 rad/s): once with its standard refitted set, once with the
set a single load can identify (mu scale and the drags: K_t and the rotor inertia trade off
against them when the load never changes and the speed is held), each reported as it names
effects and what it leaves unexplained.

The last line:
    real: drive=tro2021_worm points=<n> fit_rms_mNm=<x> tro_fit_rms_mNm=<x> load_mae_pct=<x>
          load_max_pct=<x> baseline_mae_pct=<x> mu=<x> tro_mu=0.12
(on one line) with fit_rms our fitted model's torque RMS over all points, tro_fit_rms the T-RO
fit's, load_* the cross-fitted estimate's mean and largest error in % of the load, mu our
fitted kinetic mu.
"""
from __future__ import annotations

import argparse
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser
from worm_model.cli.progress import ProgressBar
from worm_model.files.writing import atomic_dir, check_output
from worm_model.physics.parameters import ParameterError, Rig, load_rig
from worm_model.residuals import analysis as residual_analysis
from worm_model.residuals.extended import ExtendedModel
from worm_model.residuals.free import STANDARD_REFIT, get_value
from worm_model.residuals.model import prepare_signals
from worm_model.rig_data.epos import EposExport, EposSettings, read_epos_folder, steady_point
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import RigDataError

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.extended_model import ExtendedModelEstimator
from torque_estimator.evaluation.steady_fit import TERMS, FittedModel, Selection, SteadyPoints, fit, halves, \
    model_torque, select
from torque_estimator.evaluation.tro2021_model import TRO_NOMINAL_TORQUE, TroDrive, motor_torque, payload

def data_folder() -> Path:
    """worm_model's data/tro2021/driveNo3/steady_state/0.096kg (installed package data)."""
    import worm_model  # noqa: PLC0415 - only to find its data

    return Path(worm_model.__file__).resolve().parent / "data" / "tro2021" / "driveNo3" / "steady_state" / "0.096kg"


def rig_file() -> Path:
    """worm_model's data/tro2021_worm_rig.yaml."""
    import worm_model  # noqa: PLC0415

    return Path(worm_model.__file__).resolve().parent / "data" / "tro2021_worm_rig.yaml"


#: the hanging load [N m] (their 9.812 m/s^2 x 0.096 kg x 0.02 m)
LOAD = payload()
#: the estimator's table: speed step [rad/s] (the support's Stribeck rise decays over ~0.25 rad/s) and loads
SPEED_STEP = 0.01
TORQUE_POINTS = 401
#: the table's loads: the fitted load +- this fraction of it (module docstring)
LOAD_MARGIN = 0.5


@dataclass(frozen=True)
class Point:
    """One steady-state file: ``rpm`` its nominal speed (signed, the file's name), the means in SI."""

    file: str
    rpm: int
    omega: float  # [rad/s]
    torque: float  # [N m]
    torque_sd: float  # [N m]
    torque_sem: float  # [N m]

    @property
    def direction(self) -> str:
        return "lifting" if self.omega > 0 else "lowering"


def read_points(folder: Path | None = None) -> tuple[list[Point], list[EposExport]]:
    """The steady points of the folder's exports (dirty rows skipped: EposExport.dirty lists them)."""
    exports = read_epos_folder(folder or data_folder(), skip_bad_rows=True)
    points = []
    for export in exports:
        p = steady_point(export)
        name = Path(export.source).stem
        match = re.fullmatch(r"(n?)(\d+)", name)
        rpm = int(match.group(2)) if match else round(p.speed * 30 / math.pi)
        rpm = rpm if p.speed > 0 else -rpm
        points.append(Point(Path(export.source).name, rpm, p.speed, p.torque * TRO_NOMINAL_TORQUE,
                            p.torque_sd * TRO_NOMINAL_TORQUE, p.torque_sem * TRO_NOMINAL_TORQUE))
    points.sort(key=lambda q: (q.omega < 0, abs(q.omega)))
    return points, exports


def steady_points(points: list[Point]) -> SteadyPoints:
    return SteadyPoints(np.array([p.omega for p in points]), np.array([p.torque for p in points]),
                        np.array([p.torque_sem for p in points]), np.full(len(points), LOAD))


@dataclass
class LoadEstimates:
    """Per point, cross-fitted: estimate [N m], flags, baseline estimate [N m], the data's bound [% of load],
    the other candidate load [N m] where AMBIGUOUS (NaN elsewhere)."""

    estimate: np.ndarray
    flags: np.ndarray
    baseline: np.ndarray
    bound_pct: np.ndarray
    other: np.ndarray

    @property
    def error_pct(self) -> np.ndarray:
        return 100.0 * (self.estimate - LOAD) / LOAD

    @property
    def baseline_pct(self) -> np.ndarray:
        return 100.0 * (self.baseline - LOAD) / LOAD

    @property
    def ambiguous(self) -> np.ndarray:
        return (self.flags & int(EstimateFlags.AMBIGUOUS)) != 0


def estimator_for(fitted: FittedModel, omega_max: float, margin: float = LOAD_MARGIN) -> ExtendedModelEstimator:
    """The extended-model estimator of a fitted model; table: |omega| up to omega_max, loads LOAD (1 +- margin)."""
    return ExtendedModelEstimator(model=fitted.model, ranges=(omega_max, (1.0 - margin) * LOAD, (1.0 + margin) * LOAD),
                                  speed_points=int(math.ceil(omega_max / SPEED_STEP)) + 1,
                                  torque_points=TORQUE_POINTS, current_noise=0.0)


def _interpolate(omega: float, train_omega: np.ndarray, train_torque: np.ndarray) -> float:
    """Torque at |omega| from the training points of the same direction: linear, the nearest at the ends."""
    same = np.sign(train_omega) == np.sign(omega)
    speed, torque = np.abs(train_omega[same]), train_torque[same]
    order = np.argsort(speed)
    return float(np.interp(abs(omega), speed[order], torque[order]))


def estimate_loads(rig: Rig, sp: SteadyPoints, structure: tuple[str, ...], margin: float = LOAD_MARGIN
                   ) -> LoadEstimates:
    """The cross-fitted load estimates (module docstring); ``margin``: the table's loads, LOAD (1 +- margin)."""
    half = halves(sp.omega)
    n = len(sp)
    out = LoadEstimates(np.full(n, np.nan), np.zeros(n, dtype=np.int64), np.full(n, np.nan), np.full(n, np.nan),
                        np.full(n, np.nan))
    omega_max = 1.05 * float(np.max(np.abs(sp.omega)))
    for h in (0, 1):
        train, held = half == h, half != h
        fitted = fit(rig, sp.subset(train), structure)
        estimator = estimator_for(fitted, omega_max, margin)
        kt = fitted.model.rig.drive_motor.torque_constant
        idx = np.flatnonzero(held)
        result = estimator.estimate(sp.omega[idx], sp.torque[idx] / kt)
        out.estimate[idx], out.flags[idx] = result.torque, result.flags
        interpolated = np.array([_interpolate(sp.omega[k], sp.omega[train], sp.torque[train]) for k in idx])
        out.baseline[idx] = estimator.estimate(sp.omega[idx], interpolated / kt).torque
        step = 1e-5 * LOAD
        slope = (fitted.torque(sp.omega[idx], out.estimate[idx] + step)
                 - fitted.torque(sp.omega[idx], out.estimate[idx] - step)) / (2 * step)
        out.bound_pct[idx] = 100.0 * sp.torque_sem[idx] / np.abs(slope) / LOAD
        for k in idx:
            if out.flags[k] & int(EstimateFlags.AMBIGUOUS):
                out.other[k] = _other_crossing(fitted, sp.omega[k], sp.torque[k], out.estimate[k], margin)
    return out


def _other_crossing(fitted: FittedModel, omega: float, torque: float, chosen: float, margin: float) -> float:
    """The load on the V's other arm that gives the same torque (the one the estimator did not choose)."""
    loads = np.linspace((1.0 - margin) * LOAD, (1.0 + margin) * LOAD, 4001)
    excess = fitted.torque(np.full(len(loads), omega), loads) - torque
    crossings = np.flatnonzero(np.sign(excess[:-1]) != np.sign(excess[1:]))
    candidates = [loads[c] - excess[c] * (loads[c + 1] - loads[c]) / (excess[c + 1] - excess[c]) for c in crossings]
    others = [c for c in candidates if abs(c - chosen) > 0.02 * LOAD]
    return float(others[0]) if others else math.nan


#: what one load level can identify of the standard refitted set (module docstring)
SINGLE_LOAD_REFIT = ("friction.scale", "drive_motor.coulomb_drag", "drive_motor.viscous_drag",
                     "load_motor.coulomb_drag")
#: [rad/s] the residuals tool's slowest samples here (its default 5 rad/s would leave out 1-47 rpm)
RESIDUALS_MIN_SPEED = 0.05


@dataclass
class ResidualsRun:
    """What the residuals tool found: effects named, corrections (declared, identified), the residual left."""

    refit: tuple[str, ...]
    found: list[str]
    corrections: dict[str, tuple[float, float]]
    rms_before: float  # [A]
    rms_after: float  # [A]
    floor: float  # [A]
    unexplained: bool
    goes_with: list[str]  # "quantity share%: detail", largest first

    def lines(self) -> list[str]:
        out = [f"  residuals tool, refitted {', '.join(self.refit)}: found {', '.join(self.found) or 'none'}; "
               f"held-out RMS {self.rms_before:.4f} -> {self.rms_after:.4f} A, {self.rms_after / self.floor:.2f} x "
               f"the noise floor {self.floor:.4f} A" + ("; UNEXPLAINED" if self.unexplained else "")]
        out += [f"    correction {p}: {a:.4g} -> {b:.4g} (x{b / a:.3g})" for p, (a, b) in self.corrections.items()]
        out += [f"    the unexplained residual goes with {g}" for g in self.goes_with[:3]]
        return out


def residuals_tool(refit: tuple[str, ...] = STANDARD_REFIT) -> ResidualsRun:
    """The residual analysis on the exports, sample by sample, as the ``residuals`` command runs it (module
    docstring)."""
    rig = load_rig(rig_file())
    data = read_rig_data(data_folder(), epos=EposSettings(load_torque=LOAD,
                                                          nominal_current=rig.drive_motor.rated_current,
                                                          skip_bad_rows=True))
    settings = residual_analysis.Settings(min_speed=RESIDUALS_MIN_SPEED, refit=tuple(refit))
    signals = prepare_signals(rig, data, settings.alpha_time_constant, settings.reference_temperature)
    split = residual_analysis.make_split(signals, settings, np.isfinite(data.current_drive))
    problem = residual_analysis.Problem(rig, [], signals, data.current_drive, split, settings)
    result = residual_analysis.analyse(problem)
    corrections = {p: (get_value(rig, p), get_value(result.final.rig, p)) for p in problem.free}
    floor = result.noise.rms if result.noise is not None else math.nan
    goes = [] if result.unexplained is None else [
        f"{c.quantity} {100 * c.share:.1f} % ({c.detail})"
        for c in sorted(result.unexplained.correlations, key=lambda c: -c.share)]
    return ResidualsRun(tuple(refit), result.found, corrections, result.rms_before, result.final.rms_held_out, floor,
                        result.unexplained is not None, goes)


@dataclass
class Study:
    """Everything the study found (module docstring)."""

    points: list[Point]
    skipped: list[str]
    measured: np.ndarray  # [N m]
    tro: np.ndarray  # T-RO fit [N m]
    declared: np.ndarray  # ours with their parameters [N m]
    base: FittedModel  # ours, no speed law, fitted on all points
    tro_structure: FittedModel  # ours with the paper's mu law refitted (their structure, our fit)
    final: FittedModel  # ours with the selected terms, fitted on all points
    fitted: np.ndarray  # final's torque [N m]
    selection: Selection
    loads: LoadEstimates
    residuals: list[ResidualsRun] = field(default_factory=list)
    rig: Rig = field(repr=False, default=None)  # type: ignore[assignment]

    # ---------------------------------------------------------------- figures
    @staticmethod
    def _rms(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.asarray(x) ** 2)))

    @property
    def fit_rms(self) -> float:
        return self._rms(self.fitted - self.measured)

    @property
    def tro_rms(self) -> float:
        return self._rms(self.tro - self.measured)

    def direction(self, name: str) -> np.ndarray:
        return np.array([p.direction == name for p in self.points])

    def load_figures(self, mask: np.ndarray | None = None) -> tuple[float, float, float]:
        """(mean |error|, largest |error|, baseline mean |error|) in % of the load over ``mask`` (all points)."""
        m = np.ones(len(self.points), dtype=bool) if mask is None else mask
        err, base = np.abs(self.loads.error_pct[m]), np.abs(self.loads.baseline_pct[m])
        return float(np.mean(err)), float(np.max(err)), float(np.mean(base))

    @property
    def mu(self) -> float:
        return self.final.values["friction.mu_constant"]

    def line(self) -> str:
        mae, worst, baseline = self.load_figures()
        return (f"real: drive=tro2021_worm points={len(self.points)} fit_rms_mNm={1e3 * self.fit_rms:.4f} "
                f"tro_fit_rms_mNm={1e3 * self.tro_rms:.4f} load_mae_pct={mae:.2f} load_max_pct={worst:.2f} "
                f"baseline_mae_pct={baseline:.2f} mu={self.mu:.4f} tro_mu={TroDrive().kin_friction:g}")


def run_study(progress=None) -> Study:
    """Read the data, fit, select, estimate (module docstring)."""
    rig = load_rig(rig_file())
    points, exports = read_points()
    skipped = [str(row) for export in exports for row in export.dirty]
    sp = steady_points(points)
    tro = motor_torque(TroDrive(), sp.omega, LOAD)
    declared = model_torque(ExtendedModel(rig), sp.omega, sp.tau_load)
    selection = select(rig, sp, progress=progress)
    final = fit(rig, sp, selection.accepted)
    base = fit(rig, sp, ())
    tro_structure = fit(rig, sp, ("tooth_stribeck",))
    loads = estimate_loads(rig, sp, tuple(selection.accepted))
    runs = [residuals_tool(STANDARD_REFIT), residuals_tool(SINGLE_LOAD_REFIT)]
    return Study(points, skipped, sp.torque, tro, declared, base, tro_structure, final,
                 final.torque(sp.omega, sp.tau_load), selection, loads, runs, rig)


# --------------------------------------------------------------------------- report
_PARAMETERS = (  # (label, our knob path, T-RO value, unit scale, unit)
    ("kinetic mu", "friction.mu_constant", 0.12, 1.0, ""),
    ("worm-side Coulomb (their inSupBreak)", "drive_motor.coulomb_drag", 5.5e-4, 1e3, "mN m"),
    ("worm-side viscous (their inSupVisc)", "drive_motor.viscous_drag", 1.15e-5, 1e6, "uN m s/rad"),
    ("gear-side Coulomb (their outSupBreak)", "load_motor.coulomb_drag", 4e-3, 1e3, "mN m"),
    ("gear-side Stribeck rise", "gear_support_stribeck.torque", 0.0, 1e3, "mN m"),
    ("gear-side Stribeck speed (worm)", "gear_support_stribeck.speed", math.nan, 1.0, "rad/s"),
    ("tooth mu Stribeck rise (their strbInf)", "friction.stribeck_rise", 0.06, 1.0, ""),
    ("tooth mu Stribeck speed (their strbVelocity)", "friction.stribeck_speed", 0.688, 1.0, "rad/s"),
)


def _parameter(fitted: FittedModel, path: str, rig: Rig) -> float:
    if path not in fitted.values:
        return math.nan
    value = fitted.values[path]
    if path == "friction.stribeck_speed":  # sliding speed -> the worm's rad/s, their unit
        return value * math.cos(rig.gearbox.lead_angle) / rig.gearbox.worm_pitch_radius
    return value


def lines(study: Study) -> list[str]:
    """The printed report: data, the three models per point, parameters, residual selection, loads, the line."""
    out = [f"real: {len(study.points)} steady points from {data_folder()} (rig file {rig_file().name}); "
           f"{len(study.skipped)} dirty row(s) skipped:"]
    out += [f"  {row}" for row in study.skipped]
    out.append(f"  load {1e3 * LOAD:.3f} mN m on the gear; torques in mN m; load errors in % of the load "
               "(cross-fitted: fitted on the other half of the speeds)")
    header = (f"  {'rpm':>5} {'measured':>9} {'+-sem':>6} {'T-RO':>7} {'ours(TRO)':>9} {'ours fit':>8}  "
              f"{'load err':>8} {'baseline':>8} {'bound':>6}")
    out.append(header)
    for k, p in enumerate(study.points):
        flag = " AMBIGUOUS (other: %.1f mN m)" % (1e3 * study.loads.other[k]) if study.loads.ambiguous[k] else ""
        out.append(f"  {p.rpm:>5d} {1e3 * p.torque:9.3f} {1e3 * p.torque_sem:6.3f} {1e3 * study.tro[k]:7.3f} "
                   f"{1e3 * study.declared[k]:9.3f} {1e3 * study.fitted[k]:8.3f}  {study.loads.error_pct[k]:+8.2f} "
                   f"{study.loads.baseline_pct[k]:+8.2f} {study.loads.bound_pct[k]:6.2f}{flag}")
    out.append(f"  torque RMS [mN m]: T-RO fit {1e3 * study.tro_rms:.4f}, ours with their parameters "
               f"{1e3 * Study._rms(study.declared - study.measured):.4f}, ours fitted (paper's structure: mu law "
               f"refitted) {1e3 * study.tro_structure.rms:.4f}, ours fitted (constant mu) {1e3 * study.base.rms:.4f}, "
               f"ours fitted ({' + '.join(['base', *study.selection.accepted])}) {1e3 * study.fit_rms:.4f}")
    for name in ("lifting", "lowering"):
        m = study.direction(name)
        mae, worst, baseline = study.load_figures(m)
        out.append(f"  {name}: torque RMS T-RO {1e3 * Study._rms(study.tro[m] - study.measured[m]):.4f}, ours "
                   f"{1e3 * Study._rms(study.fitted[m] - study.measured[m]):.4f} mN m; load error mean {mae:.2f} % "
                   f"largest {worst:.2f} % (baseline mean {baseline:.2f} %); the data's bound mean "
                   f"{float(np.mean(study.loads.bound_pct[m])):.2f} %; ambiguous points "
                   f"{int(np.sum(study.loads.ambiguous[m]))}")
    out.append("  parameters: T-RO | ours fitted (paper's structure) | ours fitted (selected)")
    for label, path, tro, scale, unit in _PARAMETERS:
        ours_tro = _parameter(study.tro_structure, path, study.rig)
        ours = _parameter(study.final, path, study.rig)
        out.append(f"    {label:45s} {tro * scale:10.4g} | {ours_tro * scale:10.4g} | {ours * scale:10.4g} {unit}")
    sel = study.selection
    out.append(f"  residual selection (cross-fitted held-out RMS, noise floor {1e3 * sel.floor:.4f} mN m): base "
               f"{1e3 * sel.held_out[0]:.4f}")
    for k, tried in enumerate(sel.rounds):
        ranked = ", ".join(f"{n} {1e3 * v:.4f}" for n, v in sorted(tried.items(), key=lambda kv: kv[1]))
        taken = sel.accepted[k] if k < len(sel.accepted) else "none (no term lowers it by 10 %)"
        out.append(f"    round {k + 1}: {ranked} -> {taken}")
    out.append(f"  left: held-out RMS {1e3 * sel.held_out[-1]:.4f} mN m = {sel.held_out[-1] / sel.floor:.2f} x the "
               f"floor" + (" (unexplained: above 1.1 x)" if sel.unexplained else " (at the floor)"))
    for run in study.residuals:
        out += run.lines()
    out.append(study.line())
    return out


def plot(study: Study, path: Path) -> Path:
    """Measured vs modelled motor torque over speed, both directions, and the load errors."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    sp = steady_points(study.points)
    grid = np.geomspace(0.09, 22.0, 400)
    for col, (name, sign) in enumerate((("lifting (+ rotation)", 1.0), ("lowering (- rotation)", -1.0))):
        ax = axes[0, col]
        m = np.sign(sp.omega) == sign
        rpm = np.abs(sp.omega[m]) * 30 / math.pi
        ax.errorbar(rpm, 1e3 * sign * sp.torque[m], yerr=2e3 * sp.torque_sem[m], fmt="o", color="k", ms=4,
                    label="measured (mean +- 2 s.e.)")
        w = sign * grid
        tau = np.full(len(grid), LOAD)
        ax.plot(grid * 30 / math.pi, 1e3 * sign * motor_torque(TroDrive(), w, LOAD), "--", color="tab:red",
                label=f"T-RO fit (their parameters), RMS {1e3 * Study._rms(study.tro[m] - study.measured[m]):.3f}")
        ax.plot(grid * 30 / math.pi, 1e3 * sign * study.base.torque(w, tau), ":", color="tab:gray",
                label="ours fitted, constant mu, RMS "
                      f"{1e3 * Study._rms(study.base.torque(sp.omega[m], sp.tau_load[m]) - study.measured[m]):.3f}")
        ax.plot(grid * 30 / math.pi, 1e3 * sign * study.final.torque(w, tau), "-", color="tab:blue",
                label=f"ours fitted + {', '.join(study.selection.accepted) or 'nothing'}, RMS "
                      f"{1e3 * Study._rms(study.fitted[m] - study.measured[m]):.3f}")
        ax.set_xscale("log")
        ax.set_title(f"{name}: |motor torque| [mN m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax2 = axes[1, col]
        ax2.axhline(0.0, color="k", lw=0.5)
        ax2.fill_between(rpm, -study.loads.bound_pct[m], study.loads.bound_pct[m], color="tab:green", alpha=0.2,
                         label="the data's bound (1 s.e. of the torque)")
        ax2.plot(rpm, study.loads.error_pct[m], "o-", color="tab:blue", ms=4, label="ours, cross-fitted")
        ax2.plot(rpm, study.loads.baseline_pct[m], "s--", color="tab:orange", ms=3, label="baseline (interpolated)")
        amb = study.loads.ambiguous[m]
        if amb.any():
            ax2.plot(rpm[amb], study.loads.error_pct[m][amb], "x", color="tab:red", ms=9, label="AMBIGUOUS")
        ax2.set_xscale("log")
        ax2.set_xlabel("motor (worm) speed [rpm]")
        ax2.set_ylabel("load error [% of 18.84 mN m]")
        lim = max(15.0, min(60.0, float(np.nanmax(np.abs(study.loads.error_pct))) * 1.1))
        ax2.set_ylim(-lim, lim)
        ax2.grid(True, which="both", alpha=0.3)
        ax2.legend(fontsize=7)
    fig.suptitle("T-RO 2021 worm drive (60:1, 0.096 kg on 20 mm): measured and modelled motor torque")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="real_drive", description=__doc__.split("\n\n")[0],
               epilog="\n\n".join(__doc__.split("\n\n")[1:]), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True,
                   help="folder for real_drive_torque.png, created (an existing one only with --force)")
    p.add_argument("--force", action="store_true", help="replace an existing --out folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool("real_drive", lambda: _main(argv), (ParameterError, RigDataError))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    check_output(args.out, args.force, folder=True)
    with ProgressBar(2 * len(TERMS), "terms tried", enabled=not args.quiet) as bar:
        study = run_study(progress=bar.update_to)
    with atomic_dir(args.out, args.force) as folder:
        plot(study, folder / "real_drive_torque.png")
    print("\n".join(lines(study)[:-1]))
    print(f"real: wrote {args.out / 'real_drive_torque.png'}")
    print(lines(study)[-1])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
