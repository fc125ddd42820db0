"""estimate: run an estimator over a logged run as estimator_node would, and score it against the log's tau_load.

    ros2 run torque_estimator estimate run.csv|bag --method extended_model --model-file identified_rig.yaml
    ros2 run torque_estimator estimate run.csv --method knn --calibration calibration.json
    ros2 run torque_estimator estimate run.csv --method observer [--model-file identified_rig.yaml]

Every sample of the log (a CSV in the worm_rig_data schema, a rosbag2 bag, or an EPOS Studio
export or a folder of them with the load given by --load-torque or --load-mass/--pulley-radius;
read by worm_model.rig_data.read_rig_data) goes through LiveEstimator with the method, exactly as
estimator_node runs it on /rig/samples: the same class, the node's parameters (defaults,
or --params-file's estimator_node section), built by the node's builder (estimation.settings:
the same rule for the rig of the inertia compensation, rig_file, else model_file, else the
bundled rig; a calibration checked against that rig).  The estimate is written
as a CSV column (--out): the log's columns, then tau_estimate [N m],
tau_estimate_uncertainty [N m] and estimate_flags (EstimateFlags bits).

Scoring, when the log has tau_load (the load reading the rig logged), over the estimates the estimator
trusts (no flag: what the standard outputs carry as a load); trusted_pct is their share of the samples
where the worm moves. A log whose every run is held at one speed and load (a folder of EPOS exports, a
joint held at a few speeds: identification.steady) is scored run by run, each one steady point: its mean
speed and current through the estimator's map (one line a point). Any other log is cut into
consecutive windows of the calibration's averaging window (0.5 s); a window is a *steady
point* when calibration's steady-state criterion holds within it (operating_points.
SteadyStateCriterion: the mean speeds of its two halves within 2 % + 0.5 rad/s of each
other, its mean currents within 0.01 A, each tolerance widened to 3 standard errors of a
half's mean where the rig's own noise is larger) and its mean speed is clear of standstill
(worm_model.physics.resolution.standstill_speed: twice the rig's speed noise; the estimators
are kinetic).  Per steady point the error is |mean estimate - mean tau_load|; the rest
of the samples (transients; standstill left out) give an RMS of the sample-by-sample error.
Errors are in % of the log's load range (the 0.5 .. 99.5 percentiles of tau_load); a log held at one
load (a hanging mass: no range) is scored in % of that load's magnitude. A log of a few moves (a
start-stop run: at most MOVE_LINES) is also reported move by move (offline.moves: each move's mean
trusted estimate over its cruise against its mean tau_load, lifting or lowering, the trusted share).
Nothing else is used: the figures come from the log and the files given, never from
knowledge of a simulator.  The last line printed is
    estimate: method=<m> mae_pct=<x> max_pct=<x> steady_points=<n> transient_rms_pct=<x> trusted_pct=<x>
Methods: knn needs --calibration; extended_model and observer need no calibration (their
ranges come from the rig file, or from the identification: section of --model-file).
Exit codes: 0 done, 2 bad input.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from worm_model.cli.errors import run_tool
from worm_model.errors import InputError, ParameterError, RigDataError
from worm_model.cli.options import Parser, input_problem, number, output_path
from worm_model.files.writing import Output, atomic_file, check_output
from worm_model.physics.parameters import Rig
from worm_model.physics.resolution import current_sigma, speed_sigma, standstill_speed
from worm_model.rig_data.epos_options import add_epos_arguments, epos_settings
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData, csv_header
from worm_rig_driver.robot.standard_outputs import UNTRUSTED

from torque_estimator.calibration.operating_points import SteadyStateCriterion
from torque_estimator.errors import CalibrationError, ReplayError
from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.live import LiveEstimator
from torque_estimator.estimation.registry import ESTIMATORS, METHODS
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.identification.steady import SteadyPoints, steady_points
from torque_estimator.offline.moves import score_moves
from torque_estimator.offline.replay import node_parameters
from worm_model.cli.progress import ProgressBar

PROG = "estimate"
#: a log of at most this many moves is reported move by move (offline.moves: a start-stop run)
MOVE_LINES = 12
#: what estimate writes; --force replaces only a CSV with its estimate column (worm_model.files.writing)
OUTPUT = Output(PROG, recognise=lambda path: "tau_estimate" in csv_header(path))
#: a steady window's halves may differ by this many standard errors of a half's mean (its own noise), where that is
#: more than the calibration's criterion allows
HALF_WINDOW_SIGMAS = 3.0


@dataclass
class LogEstimate:
    """Per-sample estimates of one log."""

    torque: np.ndarray  # [N m]
    uncertainty: np.ndarray  # [N m]
    flags: np.ndarray  # EstimateFlags bits


@dataclass
class Figures:
    """The scores of an estimate against the log's tau_load (module docstring)."""

    mae_pct: float
    max_pct: float
    steady_points: int
    transient_rms_pct: float
    load_range: float  # [N m]: what 100 % is
    one_load: bool = False  # the log has one load: load_range is its magnitude
    trusted_pct: float = math.nan  # of the samples where the worm moves, those trusted (no flag)
    held_runs: bool = False  # the log is runs held at one point each, scored as such (PointEstimates)

    def line(self, method: str) -> str:
        return (f"{PROG}: method={method} mae_pct={self.mae_pct:.2f} max_pct={self.max_pct:.2f} "
                f"steady_points={self.steady_points} transient_rms_pct={self.transient_rms_pct:.2f} "
                f"trusted_pct={self.trusted_pct:.1f}")


@dataclass
class PointEstimates:
    """A log of held runs (identification.steady.steady_points) scored as steady points: per run its mean speed
    [rad/s], mean current [A] and load [N m], and the estimator's quasi-static estimate of the mean (the
    estimator's own map, its load prior included) with its flags and other candidate."""

    points: SteadyPoints
    torque: np.ndarray  # [N m]
    flags: np.ndarray
    other: np.ndarray  # [N m], NaN where not ambiguous

    @classmethod
    def of(cls, data: MeasuredData, estimator) -> "PointEstimates | None":
        points = steady_points(data)
        if points is None:
            return None
        est = estimator.estimate(points.omega, points.current)
        other = np.full(len(points), np.nan) if est.other is None else np.asarray(est.other, dtype=float)
        return cls(points, np.asarray(est.torque, dtype=float), np.asarray(est.flags, dtype=np.int64), other)

    def lines(self, data: MeasuredData, span: float) -> list[str]:
        """One line a point: its run's file (or run number), speed, load, estimate, error in % of ``span``."""
        out = []
        for k in range(len(self.points)):
            run = int(self.points.run[k])
            name = Path(data.run_sources[run]).name if data.run_sources else f"run {run}"
            error = 100.0 * (self.torque[k] - self.points.tau_load[k]) / span
            flags = EstimateFlags(int(self.flags[k]))
            out.append(f"{PROG}: point {name}: omega {self.points.omega[k]:+.4g} rad/s, load "
                       f"{self.points.tau_load[k]:+.5g} N m, estimate {self.torque[k]:+.5g} N m ({error:+.2f} %)"
                       + (f", {flags.name}" if flags else ""))
        return out


def run_estimator(data: MeasuredData, make_live: Callable[[], LiveEstimator], progress=None) -> LogEstimate:
    """Feed every sample to a LiveEstimator from ``make_live``: a fresh one per run of the log (a gap in t),
    as a node restarted there."""
    n = len(data)
    torque, spread, flags = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, dtype=np.int64)
    voltage = data.voltage_drive if data.voltage_drive is not None else np.full(n, np.nan)
    omega, current, theta = data.omega_worm.tolist(), data.current_drive.tolist(), data.theta_worm.tolist()
    volts, runs = voltage.tolist(), data.run
    core = make_live()
    for k in range(n):
        if k and runs[k] != runs[k - 1]:
            core = make_live()
        est = core.update(omega[k], current[k], voltage_drive=volts[k], theta_worm=theta[k])
        torque[k], spread[k], flags[k] = est.torque, est.uncertainty, est.flags
        if progress is not None and k % 2000 == 0:
            progress(k)
    return LogEstimate(torque, spread, flags)


def window_criterion(data: MeasuredData, rig: Rig, criterion: SteadyStateCriterion = SteadyStateCriterion()
                     ) -> SteadyStateCriterion:
    """The steady-state criterion for this log's windows: the calibration's, its speed and current tolerances widened
    to HALF_WINDOW_SIGMAS standard errors of a half window's mean where the rig's noise (its sensors: section, what
    identify measured) is larger than they allow (a drive sampled at 25 Hz averages 6 samples a half window)."""
    half = max(1, int(round(criterion.window / data.sample_period)) // 2)
    se = HALF_WINDOW_SIGMAS * math.sqrt(2.0 / half)
    return replace(criterion, speed_floor=max(criterion.speed_floor, se * speed_sigma(rig)),
                   current_drift=max(criterion.current_drift, se * current_sigma(rig)))


def steady_windows(data: MeasuredData, criterion: SteadyStateCriterion = SteadyStateCriterion(),
                   min_speed: float = 0.0) -> list[slice]:
    """The steady points of a log (module docstring): consecutive windows of ``criterion.window`` per run, their mean
    speed above ``min_speed`` [rad/s] (a standing worm is no point of the kinetic model)."""
    size = max(2, int(round(criterion.window / data.sample_period)))
    half = size // 2
    out = []
    for r in np.unique(data.run):
        idx = np.flatnonzero(data.run == r)
        for first in range(idx[0], idx[-1] + 1 - size + 1, size):
            w, i = data.omega_worm[first:first + size], data.current_drive[first:first + size]
            if not (np.all(np.isfinite(w)) and np.all(np.isfinite(i))):
                continue
            mean = float(np.mean(w))
            if abs(mean) <= min_speed:
                continue
            if (abs(np.mean(w[:half]) - np.mean(w[half:]))
                    <= criterion.speed_tolerance * abs(mean) + criterion.speed_floor
                    and abs(np.mean(i[:half]) - np.mean(i[half:])) <= criterion.current_drift):
                out.append(slice(first, first + size))
    return out


def figures(data: MeasuredData, estimate: LogEstimate, rig: Rig,
            criterion: SteadyStateCriterion = SteadyStateCriterion(),
            points: PointEstimates | None = None) -> Figures | None:
    """Scores against the log's tau_load (module docstring); ``rig``: the estimator's (its sensors' noise sets what
    stands, worm_model.physics.resolution, and how steady a window must be, :func:`window_criterion`); ``points``:
    a log of held runs, scored as its points; None when the log has no finite tau_load."""
    reference = data.tau_load
    finite = np.isfinite(reference)
    if not finite.any():
        return None
    low, high = np.percentile(reference[finite], [0.5, 99.5])
    span = float(high - low)
    one_load = not span > 0.0
    if one_load:  # one load (e.g. a hanging mass): % of that load
        span = float(np.max(np.abs(reference[finite]))) or float("nan")
    still = standstill_speed(rig)
    moving = np.abs(data.omega_worm) > still
    trusted = np.isfinite(estimate.torque) & ((np.asarray(estimate.flags) & int(UNTRUSTED)) == 0)
    trusted_pct = 100.0 * float(np.mean(trusted[moving])) if moving.any() else math.nan
    if points is not None:  # held runs: each one steady point
        ok = np.isfinite(points.torque)
        errors_pct = 100.0 * np.abs(points.torque[ok] - points.points.tau_load[ok]) / span
        return Figures(float(np.mean(errors_pct)) if len(errors_pct) else math.nan,
                       float(np.max(errors_pct)) if len(errors_pct) else math.nan, int(ok.sum()), math.nan, span,
                       one_load, trusted_pct, held_runs=True)
    windows = steady_windows(data, window_criterion(data, rig, criterion), still)
    errors = []
    steady = np.zeros(len(data), dtype=bool)
    for window in windows:  # scored over the estimates the estimator trusts, as the standard outputs carry them
        est, ref = estimate.torque[window], reference[window]
        ok = trusted[window] & np.isfinite(ref)
        steady[window] = True
        if ok.sum() >= 2:
            errors.append(abs(float(np.mean(est[ok]) - np.mean(ref[ok]))))
    errors_pct = 100.0 * np.array(errors) / span
    rest = ~steady & trusted & finite & moving
    rms = float(np.sqrt(np.mean((estimate.torque[rest] - reference[rest]) ** 2))) if rest.any() else math.nan
    return Figures(float(np.mean(errors_pct)) if len(errors_pct) else math.nan,
                   float(np.max(errors_pct)) if len(errors_pct) else math.nan,
                   len(errors_pct), 100.0 * rms / span, span, one_load, trusted_pct)


def write_estimate_csv(path: Path, data: MeasuredData, estimate: LogEstimate) -> None:
    """The log's columns, then tau_estimate, tau_estimate_uncertainty, estimate_flags."""
    names = data.names
    columns = [getattr(data, c).tolist() for c in names] + [estimate.torque.tolist(), estimate.uncertainty.tolist()]

    def cell(v):
        return "" if math.isnan(v) else repr(v)

    with path.open("w", newline="", encoding="utf-8") as handle:
        handle.write(",".join(names + ["tau_estimate", "tau_estimate_uncertainty", "estimate_flags"]) + "\n")
        for row, flag in zip(zip(*columns), estimate.flags.tolist()):
            handle.write(",".join(cell(v) for v in row) + f",{flag}\n")


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description=__doc__.split("\n\n")[0],
                                epilog="\n\n".join(__doc__.split("\n\n")[1:]),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("log", type=Path,
                   help="the logged run: a worm_rig_data CSV, a rosbag2 bag (directory, .mcap, .db3), "
                        "or an EPOS Studio export or folder of them (with the load options below)")
    p.add_argument("--method", required=True, choices=sorted(ESTIMATORS),
                   help="the estimator (estimator_node's method)")
    p.add_argument("--calibration", type=Path, default=None,
                   help="calibration database (calibrate); required by knn, optional for the others (ranges)")
    p.add_argument("--model-file", type=Path, default=None,
                   help="extended rig file (identify or residuals): inverted by extended_model, the observer's model")
    p.add_argument("--rig", type=Path, default=None,
                   help="rig file (estimator_node's rig_file; default: the model file, else the bundled rig)")
    p.add_argument("--params-file", type=Path, default=None,
                   help="a graph parameter file whose estimator_node section sets the filters (default: the node's "
                        "defaults)")
    p.add_argument("--load-min", type=number("N m", -1e4, 1e4), default=None,
                   help="least load the drive carries [N m] (estimator_node's load_min: gear frame, + opposing + "
                        "rotation); with --load-max, what tells a self-locking drive's two candidate loads apart "
                        "(extended_model, observer, momentum)")
    p.add_argument("--load-max", type=number("N m", -1e4, 1e4), default=None,
                   help="largest load the drive carries [N m] (estimator_node's load_max)")
    p.add_argument("--out", type=output_path, default=None,
                   help="CSV to write (default: <log without suffix>_<method>.csv beside the log); an existing "
                        "one is replaced only with --force, and only if estimate wrote it")
    p.add_argument("--force", action="store_true", help="replace an existing --out that estimate wrote before")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_epos_arguments(p)
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool(PROG, lambda: _main(argv))  # Ctrl-C: exit 130, the output untouched


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)

    def fail(where: str, what: str) -> int:
        print(f"{PROG}: {where}: {what}", file=sys.stderr)
        return 2

    for option, path in (("--calibration", args.calibration), ("--model-file", args.model_file), ("--rig", args.rig),
                         ("--params-file", args.params_file)):
        if path is not None and (problem := input_problem(path, "file")):
            return fail(option, f"{path}: {problem}")
    out = args.out or args.log.with_name(f"{args.log.stem}_{args.method}.csv")
    inputs = [args.log, args.calibration, args.model_file, args.rig, args.params_file]
    try:  # before any work: never over an input, --force only over estimate's own output
        check_output(out, args.force, inputs=inputs, output=OUTPUT)
    except InputError as err:
        return fail(err.where, err.what)
    try:
        params = node_parameters(args.params_file)["estimator_node"]
    except ReplayError as err:
        return fail("--params-file", str(err))
    prior = {name: value for name, value in (("load_min", args.load_min), ("load_max", args.load_max))
             if value is not None}
    if prior and "load_min" not in {o.name for o in METHODS[args.method].options}:
        return fail("--load-min / --load-max", f"the {args.method} method reads no load prior (extended_model, "
                                               "observer and momentum do)")
    if len(prior) == 1:
        return fail("--load-min / --load-max", "give both, the least and the largest load")
    settings = EstimatorSettings.from_parameters(
        {**params, **prior, "method": args.method, "rig_file": args.rig or params.get("rig_file"),
         "model_file": args.model_file or params.get("model_file"), "calibration_file": args.calibration}, args.method)
    try:
        built = build_estimator(settings)
    except CalibrationError as err:
        return fail("--calibration", str(err) if args.calibration is not None else f"{err}: pass --calibration FILE")
    except ParameterError as err:
        return fail("--model-file" if settings.model_file else "--rig", str(err))
    except ValueError as err:
        where = ("--load-min / --load-max" if prior and str(err).startswith("load_") else
                 "--params-file" if args.params_file else "--method")
        return fail(where, str(err).removeprefix("load_min / load_max: "))
    try:  # its units checked against the rig
        data = read_rig_data(args.log, rig=built.rig, epos=epos_settings(args, built.rig))
    except RigDataError as err:
        return fail("log", str(err))
    except InputError as err:  # an option of the EPOS reader
        return fail(err.where, err.what)
    for note in data.notes:
        print(f"{PROG}: note: {note}")
    if METHODS[args.method].reads_voltage and (data.voltage_drive is None or not np.isfinite(data.voltage_drive).any()):
        return fail("log", f"{args.log}: the {args.method} method needs the voltage_drive column (momentum, knn and "
                           "extended_model do without)")
    estimator, model_file, rig_file = built.estimator, settings.model_file, settings.rig_file
    start = time.monotonic()
    with ProgressBar(len(data), "samples", enabled=not args.quiet) as bar:
        estimate = run_estimator(data, lambda: built.live(data.sample_period), bar.update_to)
    try:
        with atomic_file(out, args.force, inputs=inputs, output=OUTPUT) as tmp:
            write_estimate_csv(tmp, data, estimate)
    except InputError as err:
        return fail(err.where, err.what)
    ranges = getattr(estimator, "ranges_from", None)
    print(f"{PROG}: {args.log}: {len(data)} samples, {data.t[-1] - data.t[0]:.1f} s, "
          f"{len(np.unique(data.run))} run(s); "
          f"{args.method} from {args.calibration or model_file or rig_file or 'the bundled rig'}"
          + (f" (table ranges from the {ranges})" if ranges else "")
          + f"; {time.monotonic() - start:.1f} s -> {out}")
    points = PointEstimates.of(data, estimator)
    score = figures(data, estimate, built.rig, points=points)
    if score is None:
        print(f"{PROG}: method={args.method} samples={len(data)} (no tau_load in the log: no figures)")
        return 0
    if score.one_load:
        print(f"{PROG}: the log has one load, {score.load_range:.4f} N m: errors in % of it")
    else:
        print(f"{PROG}: load range of the log {score.load_range:.4f} N m (0.5..99.5 percentiles of tau_load)")
    if points is not None:
        print(f"{PROG}: the log is {len(points.points)} runs each held at one speed and load: each scored as one "
              "steady point, its mean speed and current through the estimator's map")
        for line in points.lines(data, score.load_range):
            print(line)
    if points is None:
        trusted = (np.asarray(estimate.flags) & int(UNTRUSTED)) == 0
        found = score_moves(data, estimate.torque, trusted, standstill_speed(built.rig))
        if 0 < len(found) <= MOVE_LINES:
            for number, move in enumerate(found, 1):
                print(move.line(PROG, number, data.t, score.load_range))
    print(score.line(args.method))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
