"""real: a real worm drive's measurements through the tools a user runs: ``identify --from``, then ``estimate``.

    python -m torque_estimator.evaluation.real_drive --out out/real [--force]     (make evaluate runs it too)

The data: the T-RO 2021 worm drive's 46 steady-state EPOS exports and its two start-stop runs
(worm_model/data/tro2021, SOURCE.md: a 60:1 self-locking worm drive, 23 held speeds from 1 to 200 rpm
of the motor lifting and lowering a 0.096 kg mass on a 20 mm pulley, 18.84 mN m on the gear), read as
``identify`` and ``estimate`` read them (worm_model.rig_data.read_rig_data with what the command
lines ``--load-mass 0.096 --pulley-radius 0.02 --gravity 9.812 --skip-bad-rows`` give), with the
project's rig file for the drive (worm_model/data/tro2021_worm_rig.yaml: their geometry and their
fitted frictions, every number cited). Everything below runs the tools' own functions, nothing of
the study's own:

* **Steady points, cross-fitted.** The exports are split in two halves (alternate speeds in each
  direction, identification.steady.halves); ``identify`` (identification.fit.identify, and the file
  identification.writing writes) fits one half, ``estimate`` (offline.estimate.PointEstimates: each
  held export one steady point through the estimator ``estimate`` builds, estimation.settings) estimates
  the other half's load from speed and torque alone, then the halves swap. Errors in % of the load;
  the data's own bound per point is its torque's standard error through the identified model's slope
  dT/dtau_load (lowering a self-locked load, the motor torque moves by 1/53 of the load's change).
* **The model against their fit.** ``identify`` on all 46 exports, its motor torque beside the T-RO
  fit (evaluation.tro2021_model: their model with their parameters, written from their scripts) and
  the rig file as declared (this project's model with their parameters, the same to 1e-10 N m).
* **The start-stop runs** (:func:`moves`): ``estimate`` with the file identify wrote from the
  steady exports, on start_stop/{10,200}.csv (lowering, stop, lifting, stop), extended_model and
  momentum, without a prior and with ``--load-min 0 --load-max 0.04``. Per direction, its moves as
  ``estimate`` scores them (offline.moves: each move's cruise, its samples above half its top speed past
  its first 0.5 s) taken together: the mean trusted estimate's error, the share trusted, and
  what the data itself allows: the move's mean torque against the steady export's at the same nominal
  speed, through the identified model's slope (two recordings of one operating point differ by that
  much, so no model of one can be closer to the other); and what the model allows: the load the
  identified model gives for the move's own mean speed and torque (on the coast arm while lowering),
  the estimate an estimator averaging perfectly over the move would make with this model. The two
  differ by the model's residual at the steady export (a fit within the points' noise leaves one).

The lines (each on one line):
    real: drive=tro2021_worm road=identify+estimate points=<n> fit_rms_mNm=<x> tro_fit_rms_mNm=<x>
          lift_mae_pct=<x> lift_max_pct=<x> lower_mae_pct=<x> lower_bound_pct=<x> mu=<x> tro_mu=0.12
          not_identifiable=<names>
    real_start_stop: file=<f> method=<m> prior=<yes|no> move=<lifting|lowering> error_pct=<x>
          data_bound_pct=<x> model_bound_pct=<x> trusted_pct=<x> worst_pct=<x> worst_bound_pct=<x>
(worst_pct: the largest error of one trusted estimate in the move; worst_bound_pct: the data's bound on one
worm turn, the largest over the moves' whole worm turns of the turn's mean torque against the steady export's,
through the model's slope: the ripple repeats with the worm's turn, so no estimate that averages less than a turn
is steadier, and none from a model of the steady exports is nearer than the turn's own torque allows.)
"""
from __future__ import annotations

import argparse
import math
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser
from worm_model.cli.progress import Progress
from worm_model.files.writing import Output, atomic_dir, check_output
from worm_model.physics.parameters import Rig, load_rig
from worm_model.physics.resolution import standstill_speed
from worm_model.residuals.extended import ExtendedModel
from worm_model.rig_data.epos import EposSettings, hanging_load
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData
from worm_rig_driver.robot.standard_outputs import UNTRUSTED

from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.evaluation.tro2021_model import (TRO_GRAVITY, TRO_MASS, TRO_PULLEY_RADIUS, TroDrive,
                                                       motor_torque)
from torque_estimator.identification.fit import Identification, identify
from torque_estimator.identification.steady import SteadyPoints, halves, model_current, steady_points
from torque_estimator.identification.writing import write_identified
from torque_estimator.offline.estimate import PointEstimates, run_estimator
from torque_estimator.offline.moves import score_moves

#: the hanging load [N m] (their 9.812 m/s^2 x 0.096 kg x 0.02 m), as --load-mass/--pulley-radius/--gravity give it
LOAD = hanging_load(TRO_MASS, TRO_PULLEY_RADIUS, TRO_GRAVITY)
#: the start-stop exports, slow first
START_STOP_FILES = ("10.csv", "200.csv")
#: the user's prior for the hanging load: --load-min 0 --load-max 0.04 [N m]
PRIOR = (0.0, 0.04)
#: the methods run on the start-stop exports (current and speed only: the exports carry no voltage)
START_STOP_METHODS = ("extended_model", "momentum")
#: what the study writes into --out; --force replaces only a folder it wrote (worm_model.files.writing)
OUTPUT = Output("real_drive", names=("*.png", "*.yaml"))


def data_root() -> Path:
    """worm_model's data/tro2021/driveNo3 (installed package data)."""
    import worm_model  # noqa: PLC0415 - only to find its data

    return Path(worm_model.__file__).resolve().parent / "data" / "tro2021" / "driveNo3"


def data_folder() -> Path:
    """The 46 steady-state exports."""
    return data_root() / "steady_state" / "0.096kg"


def start_stop_folder() -> Path:
    return data_root() / "start_stop"


def rig_file() -> Path:
    """worm_model's data/tro2021_worm_rig.yaml."""
    import worm_model  # noqa: PLC0415

    return Path(worm_model.__file__).resolve().parent / "data" / "tro2021_worm_rig.yaml"


def read(path: Path, rig: Rig, skip_bad_rows: bool = True) -> MeasuredData:
    """An export or a folder of them, as ``identify`` / ``estimate`` read it with the hanging load's options."""
    epos = EposSettings(load_torque=LOAD, nominal_current=rig.drive_motor.rated_current, skip_bad_rows=skip_bad_rows)
    return read_rig_data(path, rig=rig, epos=epos)


def nominal_rpm(source: str, omega: float) -> int:
    """The export's nominal speed [rpm], signed: its file name (``n10.csv`` lifts at +10 rpm, ``10.csv`` lowers)."""
    match = re.fullmatch(r"(n?)(\d+)", Path(source).stem)
    rpm = int(match.group(2)) if match else round(abs(omega) * 30.0 / math.pi)
    return rpm if omega > 0 else -rpm


# --------------------------------------------------------------------------- steady points
@dataclass
class Road:
    """identify on one half, estimate on the other, and back (module docstring)."""

    points: SteadyPoints
    files: list[str]
    estimate: np.ndarray  # [N m] per point, from the half it was not identified on
    flags: np.ndarray
    bound_pct: np.ndarray  # the data's bound per point [% of the load]
    identifications: tuple[Identification, Identification]

    @property
    def error_pct(self) -> np.ndarray:
        return 100.0 * (self.estimate - LOAD) / LOAD

    def figures(self, lifting: bool) -> tuple[float, float, float]:
        """(mean |error|, largest |error|, mean bound) [% of the load] of one direction's points."""
        m = (self.points.omega > 0) == lifting
        err = np.abs(self.error_pct[m])
        return float(np.mean(err)), float(np.max(err)), float(np.mean(self.bound_pct[m]))


def slope(model: ExtendedModel, omega: np.ndarray, load: float = LOAD) -> np.ndarray:
    """dT/dtau_load [1] of the model's motor torque at steady speed omega [rad/s] and ``load`` [N m]."""
    step = 1e-4 * abs(load)
    kt = model.rig.drive_motor.torque_constant
    return kt * (model_current(model, omega, load + step) - model_current(model, omega, load - step)) / (2 * step)


def model_load(model: ExtendedModel, omega: float, current: float) -> float:
    """[N m] the load in [0, 2 LOAD] at which the model draws ``current`` [A] at ``omega`` [rad/s]: the largest
    such (lowering a self-locked load, the coast arm's; lifting there is one), NaN where none does."""
    loads = np.linspace(0.0, 2.0 * LOAD, 801)
    excess = np.array([model_current(model, np.array([omega]), load)[0] for load in loads]) - current
    found = np.flatnonzero(np.sign(excess[:-1]) != np.sign(excess[1:]))
    if len(found) == 0:
        return math.nan
    k = int(found[-1])
    return float(loads[k] + (loads[k + 1] - loads[k]) * excess[k] / (excess[k] - excess[k + 1]))


def cross_fitted(data: MeasuredData, rig_path: Path, folder: Path,
                 progress=None) -> Road:
    """The steady road, cross-fitted (module docstring); the two identified files are written into ``folder``."""
    points = steady_points(data)
    half = halves(points)
    n = len(points)
    estimate, flags, bound = np.full(n, np.nan), np.zeros(n, dtype=np.int64), np.full(n, np.nan)
    idents = []
    for h in (0, 1):
        train = data.subset(np.isin(data.run, points.run[half == h]))
        ident = identify(train, rig_path, progress=progress)
        path = folder / f"identified_half{h}.yaml"
        write_identified(path, rig_path, ident, f"{data_folder()} (half {h}: alternate speeds)")
        built = build_estimator(EstimatorSettings("extended_model", model_file=str(path)))
        held = half != h
        test = data.subset(np.isin(data.run, points.run[held]))
        pe = PointEstimates.of(test, built.estimator)
        estimate[held], flags[held] = pe.torque, pe.flags
        kt = ident.model.rig.drive_motor.torque_constant
        bound[held] = 100.0 * kt * points.current_sem[held] / np.abs(slope(ident.model, points.omega[held])) / LOAD
        idents.append(ident)
    files = [Path(data.run_sources[r]).name for r in points.run]
    return Road(points, files, estimate, flags, bound, (idents[0], idents[1]))


# --------------------------------------------------------------------------- start-stop runs
@dataclass(frozen=True)
class Move:
    """One move of a start-stop export through ``estimate`` (module docstring); loads [N m]."""

    file: str
    method: str
    prior: bool
    move: str  # "lifting" (+ rotation) or "lowering"
    mean: float  # the mean trusted estimate [N m]
    trusted: float  # [1] of the move's samples
    worst: float  # [% of the load] the largest error of one trusted estimate
    bound: float  # [% of the load] what the data allows (module docstring)
    torque: float  # [N m] the move's mean motor torque
    steady_torque: float  # [N m] the steady export's at the same nominal speed
    model_load: float  # [N m] the identified model's load for the move's mean speed and torque (module docstring)
    worst_bound: float  # [% of the load] the data's bound on one worm turn: the largest of the moves' turns

    @property
    def model_bound_pct(self) -> float:
        return 100.0 * (self.model_load - LOAD) / LOAD

    @property
    def error_pct(self) -> float:
        return 100.0 * (self.mean - LOAD) / LOAD

    def line(self) -> str:
        return (f"real_start_stop: file={self.file} method={self.method} prior={'yes' if self.prior else 'no'} "
                f"move={self.move} error_pct={self.error_pct:.1f} data_bound_pct={self.bound:.1f} "
                f"model_bound_pct={self.model_bound_pct:.1f} "
                f"trusted_pct={100.0 * self.trusted:.0f} worst_pct={self.worst:.0f} "
                f"worst_bound_pct={self.worst_bound:.0f}")


def worm_turns(data: MeasuredData, cruise: np.ndarray) -> list[np.ndarray]:
    """A move's cruise (sample indices) cut into whole worm turns, from its start: each the samples over which
    the worm turned 2 pi (the last, shorter, left out); a cruise shorter than one turn (10 rpm: a turn takes 6 s)
    is its one piece. The torque's ripple repeats with the worm's turn, so a turn's mean is the shortest average
    free of it."""
    if not len(cruise):
        return []
    angle = np.abs(np.cumsum(data.omega_worm[cruise]) * data.sample_period)
    index = np.floor(angle / (2.0 * math.pi)).astype(int)
    return [cruise[index == k] for k in range(int(index[-1]))] or [cruise]


def moves(path: Path, model_file: Path, method: str, prior: bool, rig: Rig, steady: dict[int, float],
          options: dict[str, float] | None = None) -> tuple[list[Move], MeasuredData, np.ndarray, np.ndarray]:
    """``estimate`` on one start-stop export (module docstring): its moves as ``estimate`` scores them
    (offline.moves), the lowering ones and the lifting ones each taken together, the data, the estimate and its
    flags. ``steady``: the steady exports' mean motor torque [N m] by nominal rpm (signed); ``options``: more of
    the estimator's parameters (what ``estimate --params-file`` sets; the nodes' defaults when None)."""
    options = {**(options or {}), **({"load_min": PRIOR[0], "load_max": PRIOR[1]} if prior else {})}
    built = build_estimator(EstimatorSettings(method, model_file=str(model_file), options=options))
    data = read(path, built.rig, skip_bad_rows=False)
    estimate = run_estimator(data, lambda: built.live(data.sample_period))
    model = ExtendedModel.load(model_file)
    kt = built.rig.drive_motor.torque_constant
    trusted = np.isfinite(estimate.torque) & ((estimate.flags & int(UNTRUSTED)) == 0)
    scored = score_moves(data, estimate.torque, trusted, standstill_speed(built.rig))
    out = []
    for name in ("lowering", "lifting"):
        these = [m for m in scored if m.kind == name]
        if not these:
            continue
        idx = np.concatenate([m.cruise for m in these])
        ok = trusted[idx]
        mean = float(np.mean(estimate.torque[idx][ok])) if ok.any() else math.nan
        worst = float(np.max(np.abs(estimate.torque[idx][ok] - LOAD))) / LOAD * 100.0 if ok.any() else math.nan
        speed = float(np.mean(data.omega_worm[idx]))
        torque = float(np.mean(kt * data.current_drive[idx]))
        sign = 1 if speed > 0 else -1
        rpm = sign * min((abs(r) for r in steady), key=lambda r: abs(r - abs(speed) * 30.0 / math.pi))
        reference = steady.get(rpm, math.nan)
        per_load = 100.0 / abs(float(slope(model, np.array([speed]))[0])) / LOAD  # [% of the load per N m]
        turns = np.array([kt * np.mean(data.current_drive[turn]) for m in these for turn in worm_turns(data, m.cruise)])
        out.append(Move(path.name, method, prior, name, mean, float(np.mean(ok)), worst,
                        abs(torque - reference) * per_load, torque, reference,
                        model_load(model, speed, float(np.mean(data.current_drive[idx]))),
                        float(np.max(np.abs(turns - reference))) * per_load if len(turns) else math.nan))
    return out, data, estimate.torque, estimate.flags


# --------------------------------------------------------------------------- the study
@dataclass
class Study:
    """Everything the study found (module docstring)."""

    road: Road
    full: Identification  # identify on all the steady exports
    points: SteadyPoints
    files: list[str]
    measured: np.ndarray  # [N m] the points' mean motor torque
    sem: np.ndarray  # [N m]
    tro: np.ndarray  # T-RO fit [N m]
    declared: np.ndarray  # ours with their parameters [N m]
    fitted: np.ndarray  # identify's model [N m]
    skipped: list[str]
    moves: list[Move] = field(default_factory=list)
    traces: dict = field(default_factory=dict)  # (file, method) -> (t, estimate, flags), with the prior
    rig: Rig = field(repr=False, default=None)  # type: ignore[assignment]

    @staticmethod
    def _rms(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.asarray(x) ** 2)))

    @property
    def fit_rms(self) -> float:
        return self._rms(self.fitted - self.measured)

    @property
    def tro_rms(self) -> float:
        return self._rms(self.tro - self.measured)

    @property
    def mu(self) -> float:
        rig = self.full.model.rig
        return float(rig.friction.mu_constant if rig.friction.model != "agma" else math.nan)

    def line(self) -> str:
        lift_mae, lift_max, _ = self.road.figures(True)
        lower_mae, _, lower_bound = self.road.figures(False)
        held = ",".join(h.parameter for h in self.full.held) or "none"
        return (f"real: drive=tro2021_worm road=identify+estimate points={len(self.points)} "
                f"fit_rms_mNm={1e3 * self.fit_rms:.4f} tro_fit_rms_mNm={1e3 * self.tro_rms:.4f} "
                f"lift_mae_pct={lift_mae:.2f} lift_max_pct={lift_max:.2f} lower_mae_pct={lower_mae:.2f} "
                f"lower_bound_pct={lower_bound:.2f} mu={self.mu:.4f} tro_mu={TroDrive().kin_friction:g} "
                f"not_identifiable={held}")


def run_study(folder: Path, progress=None) -> Study:
    """Read the data, identify, estimate (module docstring); the identified files are written into ``folder``."""
    rig_path = rig_file()
    rig = load_rig(rig_path)
    data = read(data_folder(), rig)
    skipped = [note.removeprefix("skipped: ") for note in data.notes if note.startswith("skipped: ")]
    road = cross_fitted(data, rig_path, folder, progress)
    full = identify(data, rig_path, progress=progress)
    model_file = folder / "identified.yaml"
    write_identified(model_file, rig_path, full, str(data_folder()))
    points = road.points
    kt = rig.drive_motor.torque_constant
    measured, sem = kt * points.current, kt * points.current_sem
    tro = motor_torque(TroDrive(), points.omega, LOAD)
    declared = kt * model_current(ExtendedModel(rig), points.omega, points.tau_load)
    fitted = kt * model_current(full.model, points.omega, points.tau_load)
    files = [Path(data.run_sources[r]).name for r in points.run]
    study = Study(road, full, points, files, measured, sem, tro, declared, fitted, skipped, rig=rig)
    steady = {nominal_rpm(f, w): t for f, w, t in zip(files, points.omega, measured)}
    for name in START_STOP_FILES:
        for method in START_STOP_METHODS:
            for prior in (False, True):
                found, run, torque, flags = moves(start_stop_folder() / name, model_file, method, prior, rig, steady)
                study.moves += found
                if prior:
                    study.traces[(name, method)] = (run.t, torque, flags, run.omega_worm)
    return study


# --------------------------------------------------------------------------- report
def lines(study: Study) -> list[str]:
    """The printed report: the data, the model against their fit per point, the cross-fitted loads, what identify
    held and found, the start-stop moves, the lines."""
    full = study.full
    out = [f"real: {len(study.points)} steady points from {data_folder()} (rig file {rig_file().name}); "
           f"{len(study.skipped)} dirty row(s) skipped:"]
    out += [f"  {row}" for row in study.skipped]
    out.append(f"  identify --from the exports (all of them): {full.road}; fitted "
               f"{', '.join(full.fitted)}; found {', '.join(full.found) or 'none'}")
    out += [f"    {line}" for line in full.correction_lines()]
    out += [f"  {h.line()}" for h in full.held]
    out += [f"  {line}" for line in full.report]
    out.append(f"  load {1e3 * LOAD:.3f} mN m on the gear; torques in mN m; load errors in % of the load (estimate on "
               "each half with the file identify wrote from the other)")
    out.append(f"  {'file':>9} {'rpm':>5} {'measured':>9} {'+-sem':>6} {'T-RO':>7} {'declared':>8} {'identify':>8}  "
               f"{'load err':>8} {'bound':>6}")
    for k in range(len(study.points)):
        flags = EstimateFlags(int(study.road.flags[k]))
        rpm = nominal_rpm(study.files[k], study.points.omega[k])
        out.append(f"  {study.files[k]:>9} {rpm:>5d} {1e3 * study.measured[k]:9.3f} {1e3 * study.sem[k]:6.3f} "
                   f"{1e3 * study.tro[k]:7.3f} {1e3 * study.declared[k]:8.3f} {1e3 * study.fitted[k]:8.3f}  "
                   f"{study.road.error_pct[k]:+8.2f} {study.road.bound_pct[k]:6.2f}"
                   + (f" {flags.name}" if flags else ""))
    out.append(f"  torque RMS [mN m]: T-RO fit {1e3 * study.tro_rms:.4f}, ours with their parameters "
               f"{1e3 * Study._rms(study.declared - study.measured):.4f}, identified {1e3 * study.fit_rms:.4f}; "
               f"the points' noise floor {1e3 * Study._rms(study.sem):.4f}")
    for name, lifting in (("lifting", True), ("lowering", False)):
        m = (study.points.omega > 0) == lifting
        mae, worst, bound = study.road.figures(lifting)
        out.append(f"  {name}: torque RMS T-RO {1e3 * Study._rms(study.tro[m] - study.measured[m]):.4f}, identified "
                   f"{1e3 * Study._rms(study.fitted[m] - study.measured[m]):.4f} mN m; load error mean {mae:.2f} % "
                   f"largest {worst:.2f} %; the data's bound mean {bound:.2f} %")
    out.append("  start-stop runs (estimate with the file identify wrote from all the steady exports; per move its "
               "cruises as estimate scores them, lowering and lifting each taken together):")
    for move in study.moves:
        out.append(f"    {move.file} {move.method:14s} prior {'yes' if move.prior else 'no ':3s} {move.move:8s} "
                   f"mean {1e3 * move.mean:6.2f} mN m ({move.error_pct:+6.1f} %), trusted {100 * move.trusted:3.0f} %, "
                   f"worst {move.worst:3.0f} %; torque {1e3 * move.torque:+.3f} against the steady export's "
                   f"{1e3 * move.steady_torque:+.3f} mN m: the data's bound {move.bound:.1f} % (on one worm turn "
                   f"{move.worst_bound:.0f} %); the model's load for the move's mean torque "
                   f"{move.model_bound_pct:+.1f} %")
    out += [m.line() for m in study.moves]
    out.append(study.line())
    return out


def plot(study: Study, path: Path) -> Path:
    """Measured vs modelled motor torque over speed, both directions, and the cross-fitted load errors; below, the
    start-stop runs' estimates (with the prior) against the load."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, axes = plt.subplots(3, 2, figsize=(11, 10.5), gridspec_kw={"height_ratios": [3, 2, 2.4]})
    pts = study.points
    grid = np.geomspace(0.09, 22.0, 400)
    for col, (name, sign) in enumerate((("lifting (+ rotation)", 1.0), ("lowering (- rotation)", -1.0))):
        ax = axes[0, col]
        m = np.sign(pts.omega) == sign
        rpm = np.abs(pts.omega[m]) * 30 / math.pi
        ax.errorbar(rpm, 1e3 * sign * study.measured[m], yerr=2e3 * study.sem[m], fmt="o", color="k", ms=4,
                    label="measured (mean +- 2 s.e.)")
        w = sign * grid
        kt = study.rig.drive_motor.torque_constant
        ax.plot(grid * 30 / math.pi, 1e3 * sign * motor_torque(TroDrive(), w, LOAD), "--", color="tab:red",
                label=f"T-RO fit (their parameters), RMS {1e3 * Study._rms(study.tro[m] - study.measured[m]):.3f}")
        ax.plot(grid * 30 / math.pi, 1e3 * sign * kt * model_current(study.full.model, w, LOAD), "-",
                color="tab:blue", label="identify --from the exports, RMS "
                f"{1e3 * Study._rms(study.fitted[m] - study.measured[m]):.3f}")
        ax.set_xscale("log")
        ax.set_title(f"{name}: |motor torque| [mN m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        ax2 = axes[1, col]
        ax2.axhline(0.0, color="k", lw=0.5)
        ax2.fill_between(rpm, -study.road.bound_pct[m], study.road.bound_pct[m], color="tab:green", alpha=0.2,
                         label="the data's bound (1 s.e. of the torque)")
        ax2.plot(rpm, study.road.error_pct[m], "o-", color="tab:blue", ms=4,
                 label="estimate, with the file identify wrote from the other half")
        ax2.set_xscale("log")
        ax2.set_xlabel("motor (worm) speed [rpm]")
        ax2.set_ylabel("load error [% of 18.84 mN m]")
        ax2.set_ylim(-30, 30)
        ax2.grid(True, which="both", alpha=0.3)
        ax2.legend(fontsize=7)
    for col, name in enumerate(START_STOP_FILES):
        ax = axes[2, col]
        for method, colour in zip(START_STOP_METHODS, ("tab:blue", "tab:orange")):
            if (name, method) not in study.traces:
                continue
            t, torque, flags, _omega = study.traces[(name, method)]
            trusted = (flags & int(UNTRUSTED)) == 0
            ax.plot(t, np.where(trusted, 1e3 * torque, np.nan), ".", ms=3, color=colour, label=f"{method}, trusted")
        t, _torque, _flags, omega = study.traces[(name, START_STOP_METHODS[0])]
        ax.axhline(1e3 * LOAD, color="k", lw=1, label="the hanging load")
        ax3 = ax.twinx()
        ax3.plot(t, omega * 30 / math.pi, color="0.7", lw=0.8)
        ax3.set_ylabel("motor speed [rpm]", color="0.5")
        ax.set_ylim(0, 40)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("estimated load [mN m]")
        ax.set_title(f"start_stop/{name}: estimate --load-min 0 --load-max 0.04")
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("T-RO 2021 worm drive (60:1, self-locking, 0.096 kg on 20 mm): identify and estimate on its "
                 "measurements")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="real_drive", description=__doc__.split("\n\n")[0],
               epilog="\n\n".join(__doc__.split("\n\n")[1:]), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True,
                   help="folder for real_drive_torque.png and the identified files, created (an existing one only "
                        "with --force)")
    p.add_argument("--force", action="store_true", help="replace an existing --out folder")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool("real_drive", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    check_output(args.out, args.force, folder=True, output=OUTPUT)
    with atomic_dir(args.out, args.force, output=OUTPUT) as folder:
        with Progress(enabled=not args.quiet) as progress:
            def on_progress(label: str, done: int, total: int) -> None:
                if progress.name != label:
                    progress.stage(label, total)
                progress.update_to(done)

            study = run_study(folder, on_progress)
        plot(study, folder / "real_drive_torque.png")
    print("\n".join(lines(study)[:-1]))
    print(f"real: wrote {args.out / 'real_drive_torque.png'}")
    print(lines(study)[-1])
    return 0


def study_in_temporary_folder(progress=None) -> Study:
    """The study with its identified files in a folder of its own, removed afterwards (tests, evaluate)."""
    with tempfile.TemporaryDirectory(prefix="real_drive_") as folder:
        return run_study(Path(folder), progress)


__all__ = ["LOAD", "PRIOR", "START_STOP_FILES", "Move", "Road", "Study", "cross_fitted", "data_folder", "lines",
           "main", "moves", "plot", "read", "rig_file", "run_study", "start_stop_folder", "study_in_temporary_folder"]


if __name__ == "__main__":
    raise SystemExit(main())
