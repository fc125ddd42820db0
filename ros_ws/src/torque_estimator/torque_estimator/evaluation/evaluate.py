"""evaluate: the paper's held-out test (Table 3, Figure 13) of a τ_d estimator, plus error sweeps.

    ros2 run torque_estimator evaluate [--calibration calibration.json] [--out out/evaluate]

Calibrates the paper's grid on the simulated rig (17 speeds x 16 torques, both
directions) unless --calibration names a database, then measures 17 held-out
operating points that are not grid points (random speeds and torques, seeded;
the four quadrants of direction x torque sign take turns, so both signs and
both directions are in) quasi-statically on the simulated rig and estimates
each. Prints the paper's Table 3 (speed, current, true τ_d, estimated τ_d,
error %), writes held_out_deviation.png (like Figure 13), and, unless
--no-sweeps, error_sweeps.png: the error against k (both weightings), grid
density and sensor noise, each on --sweep-points held-out points.

Then, unless --no-transient, every estimator of the registry side by side:
its held-out figures and how it follows a load step, a speed ramp and a
reversal, streamed as estimator_node runs it (evaluation.transient), one line
each
    transient: method=<m> step90_ms=<x> overshoot_pct=<x> ramp_err_pct=<x> reversal_err_pct=<x>
and the observer's steady noise against the best any estimator can do from these
sensors at its bandwidth (observer.steady_state_bound, a Cramér-Rao-type bound)
    noise: method=observer std=<x> bound=<x> N m ratio=<x>
and the momentum observer's (current and speed only) noise on a constant load against its predicted
steady noise, and the least noise any linear estimator that reaches 90 % of a step 5 samples after it
has on these sensors (momentum.linear_noise_bound: why it detects steps instead)
    noise: method=momentum std=<x> predicted=<x> N m ratio=<x> linear_5_sample_floor=<x> N m
and the gearbox's health (health.study): detection of a 10 % and a 5 % rise of mu with the oil
temperature measured and estimated, false alarms over 1000 healthy checks, the live monitor on a
lubricant loss and a cold start, the real drive's check (health.real_drive), as lines
    health: change=mu+10% detected_in_checks=<n> ... temperature=measured
    health: false_alarms=<n> of <m> temperature=measured
    health: live lubricant_loss=mu+30% warn_after_s=<x> ...
and health_trend.png (a simulated gearbox's life with its alarm bands), health_live.png (the live
monitor on the two scenarios); then the fast road (evaluation.identified): \
on the simulated rig with every default effect
on and the rig file off (mu x1.3, K_t x1.05, drags x2), one `identify` run against the
k-NN grid calibrated on that rig, the extended model and the observer with the identified
parameters, on the same held-out points, ending with
    identify: rig_time_s=<x> identified_mae_pct=<x> identified_max_pct=<x> observer_mae_pct=<x> ...

Then, unless --no-real, a real worm drive's measurements through the tools a user runs
(evaluation.real_drive: the T-RO 2021 drive's 46 steady exports, identify --from one half and estimate
on the other, their published fit beside identify's; its two start-stop runs through estimate with
the file identify wrote, with and without a load prior; real_drive_torque.png), one line per move
    real_start_stop: file=<f> method=<m> prior=<yes|no> move=<lifting|lowering> error_pct=<x> ...
ending with
    real: drive=tro2021_worm road=identify+estimate points=<n> fit_rms_mNm=<x> tro_fit_rms_mNm=<x> ...
and, unless --no-foreign, the datasheet road on three drives the project did not make
(evaluation.datasheet_road: a simulator of their own, rig_from_datasheet with their catalogue numbers,
identify --from one recording, estimate on another), one line per drive and method
    foreign: drive=<d> method=<m> mae_pct=<x> max_pct=<x> steady_points=<n> trusted_pct=<x>
and the self-locking lift's start-stop run with and without a load prior
    foreign_lift: drive=lift40 method=<m> prior=<yes|no> mae_pct=<x> max_pct=<x> trusted_pct=<x>

Errors are |estimated - true| in % of the calibrated torque range (max - min
of the database's τ_d). The last line printed is
    <method>: mae_pct=<mean error> max_pct=<largest error> points=<n>
"""
from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, existing_file, integer, output_path
from worm_model.files.writing import Output, atomic_dir, check_output
from worm_model.physics.parameters import load_rig
from torque_estimator.evaluation.residual_cases.catalogue import full_matrix, small_matrix
from torque_estimator.evaluation.residual_cases.report import evaluate_lines

from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.database import load_database
from torque_estimator.errors import CalibrationError
from torque_estimator.estimation.registry import ESTIMATORS, make_estimator
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.evaluation.held_out import (format_table, measure_held_out, score, sweep_grid_density, sweep_k,
                                                  sweep_noise)
from torque_estimator.estimation.knn import WEIGHTINGS
from torque_estimator.estimation.observer import steady_state_bound
from torque_estimator.estimation.momentum import linear_noise_bound
from torque_estimator.estimation.momentum import predicted_noise as momentum_noise
from torque_estimator.evaluation.transient import STEP_SPEED, ensemble_noise, transient_figures
from torque_estimator.evaluation.identified import evaluate_lines as identified_lines
from torque_estimator.evaluation import datasheet_road, real_drive
from torque_estimator.evaluation.plots import held_out_deviation, sweeps
from worm_model.cli.progress import Progress, ProgressBar

#: what evaluate writes into --out; --force replaces only a folder it wrote (worm_model.files.writing)
OUTPUT = Output("evaluate", names=("*.png",))
#: seeds of the step experiment (the ramp and the reversal take a third)
TRANSIENT_SEEDS = 12
#: samples after a load step by which the momentum observer is asked to have 90 % of it (5 ms at 1 kHz)
MOMENTUM_STEP_SAMPLES = 5


def _number_list(kind: Callable[[str], float], minimum: float, what: str) -> Callable[[str], list[Any]]:
    """argparse type: a non-empty comma-separated list of ``kind`` values, each >= ``minimum``."""

    def parse(text: str) -> list[Any]:
        try:
            values = [kind(v) for v in text.split(",") if v.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a comma-separated list of {what}: {text!r}") from None
        if not values or min(values) < minimum:
            raise argparse.ArgumentTypeError(f"need {what} >= {minimum}: {text!r}")
        return values

    return parse


_int_list = _number_list(int, 1, "integers")
_float_list = _number_list(float, 0, "numbers")


def _sizes(text: str) -> list[tuple[int, int]]:
    try:
        sizes = [tuple(int(x) for x in item.lower().split("x")) for item in text.split(",") if item.strip()]
    except ValueError:
        sizes = []
    if not sizes or any(len(s) != 2 or s[0] < 1 or s[1] < 2 for s in sizes):
        raise argparse.ArgumentTypeError(f"need SPEEDSxTORQUES items (speeds >= 1, torques >= 2): {text!r}")
    return sizes  # type: ignore[return-value]


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="evaluate", description=__doc__.split("\n\n")[0],
                                epilog="\n\n".join(__doc__.split("\n\n")[1:]),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--calibration", type=existing_file, default=None,
                   help="calibration database to evaluate (default: calibrate the paper's grid now)")
    p.add_argument("--rig", type=existing_file, default=None,
                   help="rig parameter YAML of the simulated rig (default: the bundled NMRV030 rig)")
    p.add_argument("--out", type=output_path, default=Path("out/evaluate"),
                   help="folder for the PNGs, created (default out/evaluate; an existing one only with --force)")
    p.add_argument("--force", action="store_true", help="replace an existing --out folder")
    p.add_argument("--method", default="knn", choices=sorted(ESTIMATORS), help="estimator (default knn)")
    p.add_argument("--k", type=integer(1, 64), default=4, help="neighbours of the k-NN estimator (default 4)")
    p.add_argument("--weighting", default="inverse_distance", choices=sorted(WEIGHTINGS),
                   help="k-NN weighting (default inverse_distance)")
    p.add_argument("--points", type=integer(1, 10_000), default=17,
                   help="held-out points of the table (default 17, as the paper)")
    p.add_argument("--seed", type=integer(0, 2**32 - 2), default=0,
                   help="seed of the calibration noise; held-out draws and their noise use seed+1 (default 0)")
    p.add_argument("--speeds", type=integer(1, 1000), default=17,
                   help="speeds per direction of the calibration grid (default 17)")
    p.add_argument("--torques", type=integer(2, 1000), default=16, help="torques of the calibration grid (default 16)")
    sweep = p.add_argument_group("sweeps")
    sweep.add_argument("--no-sweeps", action="store_true", help="only the table and the deviation plot")
    sweep.add_argument("--no-transient", action="store_true",
                       help="leave out the estimators side by side (held-out, step, ramp, reversal)")
    sweep.add_argument("--sweep-points", type=integer(1, 10_000), default=68,
                       help="held-out points each sweep value is scored on (default 68)")
    sweep.add_argument("--ks", type=_int_list, default=[1, 2, 3, 4, 6, 8, 12, 16],
                       help="k values, comma-separated (default 1,2,3,4,6,8,12,16)")
    sweep.add_argument("--grid-sizes", type=_sizes, default=[(3, 3), (5, 4), (9, 8), (17, 16), (33, 32)],
                       help="grid densities as SPEEDSxTORQUES, comma-separated (default 3x3,5x4,9x8,17x16,33x32)")
    sweep.add_argument("--noise", type=_float_list, default=[0.0, 0.5, 1.0, 2.0, 4.0],
                       help="sensor noise factors (x the rig's current and speed noise), comma-separated "
                            "(default 0,0.5,1,2,4)")
    p.add_argument("--no-real", action="store_true",
                   help="skip the real worm drive (the T-RO 2021 measurements through identify and estimate, ~1 min): "
                        "its table, real_drive_torque.png, its `real_start_stop:` and `real:` lines")
    p.add_argument("--no-foreign", action="store_true",
                   help="skip the datasheet road on drives the project did not make (~4 min): its `foreign:` lines")
    p.add_argument("--no-residuals", action="store_true", help="skip the residuals tool's case matrix")
    p.add_argument("--no-health", action="store_true",
                   help="skip the gearbox health study (~1800 simulated checks, the live scenarios: ~10 min)")
    p.add_argument("--residual-cases", choices=("full", "small"), default="full",
                   help="the residuals tool's case matrix: full (two rigs, both friction models; every effect alone "
                        "and in pairs with the declared values nominal, high and low, copied from a catalogue, or "
                        "drags declared 0; clean data; out-of-vocabulary effects; plants without drag: 163 cases, "
                        "~10 min) or small (a 22-case subset, ~2 min); default full")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool("evaluate", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    start = time.monotonic()
    inputs = [args.calibration, args.rig]
    check_output(args.out, args.force, folder=True, inputs=inputs, output=OUTPUT)
    rig = load_rig(args.rig)
    if args.calibration is not None:
        db = load_database(args.calibration, rig)  # refuses no torque range, one point repeated, rpm
        grid = CalibrationGrid(speeds=db.speed_setpoints, torques=db.torque_setpoints)
        source = str(args.calibration)
    else:
        grid = CalibrationGrid.paper(rig, args.speeds, args.torques)
        n = len(grid.speeds) * len(grid.torques)
        with ProgressBar(n, "calibration points", enabled=not args.quiet) as bar:
            db = calibrate_simulated(rig, grid, seed=args.seed,
                                     progress=lambda f: bar.update_to(round(f * n)))
        source = f"calibrated now, seed {args.seed}"
    options = {"k": args.k, "weighting": args.weighting} if args.method == "knn" else {}
    try:
        estimator = make_estimator(args.method, db, **options)
    except ValueError as err:
        raise CalibrationError(f"--method {args.method}: {err}") from None
    with atomic_dir(args.out, args.force, inputs=inputs, output=OUTPUT) as folder:
        pngs, ev = _evaluate(args, rig, grid, db, estimator, options, source, folder)
    print(f"\nevaluate: wrote {', '.join(str(args.out / p.name) for p in pngs)} in {time.monotonic() - start:.1f} s")
    print(f"{args.method}: mae_pct={ev.mae_pct:.2f} max_pct={ev.max_pct:.2f} points={len(ev.tau_true)}")
    return 0


def _evaluate(args, rig, grid, db, estimator, options, source, out: Path):
    """Everything but the last two lines, the PNGs written into ``out``; returns their paths and the table's
    evaluation."""
    print(f"evaluate: {args.method} ({', '.join(f'{k}={v}' for k, v in options.items())}) on {len(db)} "
          f"calibration points ({source}), torque range {db.torque_range:.4f} N·m")

    ev = score(estimator, measure_held_out(rig, grid, args.points, args.seed + 1), db.torque_range)
    print(f"\nTable 3: {args.points} held-out operating points (not grid points), simulated rig")
    print("\n".join(format_table(ev)))
    print(f"  mean error {ev.mae_pct:.2f} %, largest {ev.max_pct:.2f} % of the calibrated torque range")
    pngs = [held_out_deviation(out / "held_out_deviation.png", ev.tau_true, ev.tau_estimated, db.torque_range)]

    if not args.no_sweeps:
        results = run_sweeps(args, rig, grid, db, options)
        reference = {"neighbours k": args.k, "calibration points": len(db), "sensor noise (x the rig's)": 1.0}
        pngs.append(sweeps(out / "error_sweeps.png", results, reference))
        print(f"\nSweeps ({args.sweep_points} held-out points each; mean / largest error, % of torque range)")
        for result in results:
            for label, mae in result.mae_pct.items():
                cells = "  ".join(f"{v:g}: {m:.2f}/{x:.2f}" for v, m, x in
                                  zip(result.values, mae, result.max_pct[label]))
                print(f"  {result.name} [{label}]  {cells}")
    if not args.no_transient:
        side_by_side(args, rig, grid, db)
        # identify from one short run vs the k-NN grid, on the simulated rig with every effect on
        print("\n".join(identified_lines(rig, args.points, args.seed + 1, args.k, args.weighting)))
    if not args.no_real:  # a real drive's measurements through identify and estimate
        with Progress(enabled=not args.quiet) as progress:
            def on_real(label: str, done: int, total: int) -> None:
                if progress.name != label:
                    progress.stage(f"real drive: {label}", total)
                progress.update_to(done)

            study = real_drive.study_in_temporary_folder(on_real)
        print("\nA real worm drive (the T-RO 2021 measurements through identify and estimate, evaluation.real_drive)")
        print("\n".join(real_drive.lines(study)))
        pngs.append(real_drive.plot(study, out / "real_drive_torque.png"))
    if not args.no_foreign:  # the datasheet road on drives the project did not make
        with ProgressBar(3, "foreign drives", enabled=not args.quiet) as bar:
            lines = datasheet_road.run(progress=bar.update_to)
        print("\nThe datasheet road on worm drives the project did not make (their own simulator; "
              "rig_from_datasheet, identify --from one recording, estimate on another: evaluation.datasheet_road)")
        print("\n".join(lines))
    if not args.no_health:  # the gearbox's health: checks, trend, live monitor (health.study)
        from torque_estimator.health.study import evaluate_lines as health_lines  # noqa: PLC0415

        with Progress(enabled=not args.quiet) as progress:
            def on_progress(label: str, done: int, total: int) -> None:
                if progress.name != label:
                    progress.stage(label, total)
                progress.update_to(done)

            lines = health_lines(rig, args.seed, out=out, progress=on_progress)
        print("\n".join(lines))
        pngs += [out / "health_trend.png", out / "health_live.png"]
    if not args.no_residuals:  # the residuals tool's case matrix; ends with its `residuals:` line
        cases = full_matrix() if args.residual_cases == "full" else small_matrix()
        with ProgressBar(len(cases), "residuals cases", enabled=not args.quiet) as bar:
            print("\n".join(evaluate_lines(cases, progress=bar.update_to)))
    return pngs, ev


def side_by_side(args, rig, grid, db) -> None:
    """Every registered estimator: held-out figures, transient lines, the observer's noise against its bound."""
    measured = measure_held_out(rig, grid, args.points, args.seed + 1)
    print(f"\nEstimators side by side ({args.points} held-out points; transients streamed as estimator_node runs "
          f"them, {TRANSIENT_SEEDS} seeds; % of the torque range)")
    lines = []
    with ProgressBar(len(ESTIMATORS), "estimators", enabled=not args.quiet) as bar:
        for i, method in enumerate(ESTIMATORS):
            options = {"k": args.k, "weighting": args.weighting} if method == "knn" else {}
            built = build_estimator(EstimatorSettings(method, options=options), rig=rig, database=db)
            ev = score(built.estimator, measured, db.torque_range)
            figures = transient_figures(rig, built, db.torque_range, seeds=TRANSIENT_SEEDS, seed=args.seed)
            print(f"  {method:15s} held-out mean {ev.mae_pct:.2f} % max {ev.max_pct:.2f} %; steady noise "
                  f"{figures.steady_std:.2e} N m")
            lines.append(figures.line())
            if method == "observer":
                bound = steady_state_bound(rig, STEP_SPEED, 0.0)
                lines.append(f"noise: method=observer std={figures.steady_std:.2e} bound={bound:.2e} N m "
                             f"ratio={figures.steady_std / bound:.2f}")
            if method == "momentum":
                lines.append(momentum_noise_line(rig, built, args.seed))
            bar.update_to(i + 1)
    print("\n".join(lines))


def momentum_noise_line(rig, built, seed: int) -> str:
    """The momentum observer's noise on a constant load (across seeds) against its predicted steady noise at its
    bandwidth, and the noise floor of any linear estimator that follows a step in MOMENTUM_STEP_SAMPLES samples
    (momentum.linear_noise_bound: why it detects steps instead)."""
    std = ensemble_noise(rig, built, seeds=TRANSIENT_SEEDS, seed=seed)
    predicted = momentum_noise(rig, STEP_SPEED, 0.0, built.estimator.bandwidth)
    floor = linear_noise_bound(rig, STEP_SPEED, 0.0, MOMENTUM_STEP_SAMPLES)
    return (f"noise: method=momentum std={std:.2e} predicted={predicted:.2e} N m ratio={std / predicted:.2f} "
            f"linear_{MOMENTUM_STEP_SAMPLES}_sample_floor={floor:.2e} N m")


def run_sweeps(args, rig, grid, db, options) -> list:
    """Error against k, grid density and sensor noise, with one progress bar over the calibrations."""
    steps = 1 + len(args.grid_sizes) + len(args.noise)
    with ProgressBar(steps, "sweeps", enabled=not args.quiet) as bar:
        done = [0]

        def tick() -> None:
            done[0] += 1
            bar.update_to(done[0])

        measured = measure_held_out(rig, grid, args.sweep_points, args.seed + 1)
        results = []
        if args.method == "knn":
            results.append(sweep_k(db, measured, args.ks))
        tick()
        results.append(sweep_grid_density(rig, args.grid_sizes, measured, seed=args.seed, method=args.method,
                                          options=options, reference=db, progress=tick))
        results.append(sweep_noise(rig, grid, args.noise, args.sweep_points, seed=args.seed, method=args.method,
                                   options=options, reference=(db, measured), progress=tick))
    return results


if __name__ == "__main__":
    raise SystemExit(main())
