"""calibrate: run the paper's calibration grid and write the calibration database.

    ros2 run torque_estimator calibrate --out calibration.json            # simulator, in-process
    ros2 run torque_estimator calibrate --out calibration.json --live     # the rig on the ROS graph
    ros2 run torque_estimator calibrate --out calibration.json --resume   # continue an interrupted run

Every point: the speed controller holds a constant worm speed while the load
motors apply a constant torque; once steady (the stated criterion), a window
is averaged and its spread kept. The grid is 17 speeds x 16 torques in both
directions unless told otherwise.

Without --live the grid runs on the simulated rig inside this process, in
batches of points side by side (fast, deterministic for a seed). With --live
it drives whatever rig is on the graph (sim_node, or driver_node on the real
rig) point by point through controller_node, which must be running.

Either way a journal (<out>.partial) is rewritten atomically after every
point (live) or batch (simulator); after Ctrl-C, SIGTERM or even SIGKILL the
same command with --resume measures only the missing points. The journal is
deleted once the database is written. Exit codes: 0 done, 1 the live rig
failed, 2 bad input, 130 interrupted (journal kept).
"""
from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

from worm_model.physics.parameters import load_rig

from torque_estimator.calibration.batch import DEFAULT_BATCH_SIZE, CalibrationGrid, calibrate_simulated
from torque_estimator.estimation.database import FORMAT, save_database
from torque_estimator.errors import CalibrationError, LiveRigError
from torque_estimator.calibration.journal import CalibrationJournal, default_journal_path
from torque_estimator.calibration.live import PointByPoint, live_settings
from torque_estimator.calibration.operating_points import SteadyStateCriterion
from worm_model.cli.progress import ProgressBar
from worm_model.cli.errors import run_tool
from worm_model.errors import InputError
from worm_model.cli.options import Parser, existing_file, integer, number, output_path
from worm_model.files.reading import load_json
from worm_model.files.writing import Output, check_output

EXIT_INTERRUPTED = 130


def _is_calibration(path: Path) -> bool:
    """``path`` holds a calibration database (what --force may replace)."""
    document = load_json(path, "calibration file")
    return isinstance(document, dict) and document.get("format") == FORMAT


#: what calibrate writes at --out; --force replaces only a calibration database (worm_model.files.writing)
OUTPUT = Output("calibrate", recognise=_is_calibration)
#: largest grid dimension and longest time per point [s] accepted (the paper's grid is 17 x 16, points take ~1 s)
MAX_GRID = 200
MAX_POINT_TIME = 600.0


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="calibrate", description=__doc__.split("\n\n")[0],
                                epilog="\n\n".join(__doc__.split("\n\n")[1:]),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=output_path, required=True,
                   help="calibration database to write (JSON); an existing file is replaced only with --force")
    p.add_argument("--force", action="store_true", help="replace an existing --out file")
    p.add_argument("--rig", type=existing_file, default=None,
                   help="rig parameter YAML recorded in the database (default: the bundled NMRV030 rig); "
                        "with --live it must describe the rig on the graph")
    grid = p.add_argument_group("grid")
    grid.add_argument("--speeds", type=integer(1, MAX_GRID), default=17,
                      help="number of worm speeds per direction (default 17)")
    grid.add_argument("--torques", type=integer(2, MAX_GRID), default=16, help="number of load torques (default 16)")
    grid.add_argument("--speed-min", type=number("rad/s", 0, open_low=True), default=20.0,
                      help="smallest worm speed [rad/s] (default 20)")
    grid.add_argument("--speed-max", type=number("rad/s", 0, open_low=True), default=340.0,
                      help="largest worm speed [rad/s], at most the rig's no-load speed (default 340)")
    grid.add_argument("--torque-fraction", type=number("", 0, 1, open_low=True), default=0.9,
                      help="load torques span +- this fraction of what the load motors can make (default 0.9)")
    steady = p.add_argument_group("steady-state criterion (operating_points.SteadyStateCriterion)")
    default = SteadyStateCriterion()
    steady.add_argument("--window", type=number("s", 0, MAX_POINT_TIME, open_low=True), default=default.window,
                        help=f"averaging window of a steady point [s] (default {default.window:g})")
    steady.add_argument("--settle-time", type=number("s", 0, MAX_POINT_TIME), default=default.settle_time,
                        help=f"earliest start of a point's first window [s] (default {default.settle_time:g})")
    steady.add_argument("--timeout", type=number("s", 0, MAX_POINT_TIME, open_low=True), default=default.timeout,
                        help=f"after this [s] an unsettled point keeps its last window and is listed as "
                             f"unsettled (default {default.timeout:g})")
    sim = p.add_argument_group("simulator (without --live)")
    sim.add_argument("--seed", type=integer(0, 2**63 - 1), default=0,
                     help="seed of the simulated sensor noise (default 0)")
    sim.add_argument("--batch-size", type=integer(1, 100_000), default=DEFAULT_BATCH_SIZE,
                     help=f"points simulated side by side; the journal is written after each batch "
                          f"(default {DEFAULT_BATCH_SIZE})")
    live = p.add_argument_group("live rig (--live)")
    live.add_argument("--live", action="store_true",
                      help="drive the rig on the ROS graph (needs /rig/sample and controller_node)")
    live.add_argument("--start-timeout", type=number("s", 0, 3600, open_low=True), default=30.0,
                      help="wait this long [s] for the rig's samples and controller_node (default 30)")
    resume = p.add_argument_group("resuming")
    resume.add_argument("--resume", action="store_true",
                        help="continue the interrupted run recorded in the journal (same options required; "
                             "starts afresh if there is no journal)")
    resume.add_argument("--journal", type=Path, default=None, help="journal file (default: <out>.partial)")
    resume.add_argument("--drop-bad-points", action="store_true",
                        help="with --resume: measure again the points the journal holds with a missing or "
                             "non-finite value, instead of refusing the journal")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def _interrupt(signum, _frame) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: list[str] | None = None) -> int:
    return run_tool("calibrate", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    journal_path = args.journal or default_journal_path(args.out)
    rig = load_rig(args.rig)
    top_speed = rig.supply_voltage / rig.drive_motor.back_emf_constant
    if args.speed_max > top_speed:
        raise InputError("--speed-max", f"{args.speed_max:g} rad/s is beyond what the rig can reach "
                                        f"(no-load speed {top_speed:.4g} rad/s at {rig.supply_voltage:g} V)")
    if not args.speed_min < args.speed_max:
        raise InputError("--speed-min", f"{args.speed_min:g} rad/s must be below --speed-max {args.speed_max:g} rad/s")
    grid = CalibrationGrid.paper(rig, args.speeds, args.torques, args.speed_min, args.speed_max,
                                 args.torque_fraction)
    check_output(args.out, args.force, inputs=[args.rig, journal_path], output=OUTPUT)
    if journal_path.is_dir():
        raise InputError(f"--journal {journal_path}", "is a folder, expected a file name")
    if not journal_path.exists():  # a new journal is an output like --out: writable, never over an input
        check_output(journal_path, option="--journal", inputs=[args.rig, args.out])
    if args.resume and journal_path.exists():  # a journal that cannot be finished is refused before measuring
        journal = CalibrationJournal.load(journal_path, len(grid.speeds) * len(grid.torques), args.drop_bad_points)
        for dropped in journal.dropped:
            print(f"calibrate: journal {journal_path}: {dropped}: measured again", file=sys.stderr)
    criterion = SteadyStateCriterion(window=args.window, settle_time=args.settle_time, timeout=args.timeout)
    n = len(grid.speeds) * len(grid.torques)
    signal.signal(signal.SIGTERM, _interrupt)  # `kill` gets the same clean stop as Ctrl-C
    start = time.monotonic()
    try:
        with ProgressBar(n, "calibration points", enabled=not args.quiet) as bar:
            if args.live:
                db = _calibrate_live(args, rig, grid, criterion, journal_path, bar)
            else:
                db = calibrate_simulated(rig, grid, seed=args.seed, criterion=criterion, batch_size=args.batch_size,
                                         journal=journal_path, resume=args.resume,
                                         drop_bad_points=args.drop_bad_points,
                                         progress=lambda fraction: bar.update_to(round(fraction * n)))
        save_database(db, args.out)
    except KeyboardInterrupt:
        done = _points_in(journal_path)
        print(f"\ncalibrate: interrupted after {done} of {n} points; journal {journal_path}; "
              "run the same command with --resume to continue", file=sys.stderr)
        return EXIT_INTERRUPTED
    except CalibrationError as err:  # includes JournalError
        print(f"calibrate: {err}", file=sys.stderr)
        return 2
    except LiveRigError as err:  # the journal keeps the points measured
        print(f"calibrate: {err}\ncalibrate: {_points_in(journal_path)} of {n} points are in {journal_path}; "
              "fix the graph and run the same command with --resume", file=sys.stderr)
        return 1
    journal_path.unlink(missing_ok=True)
    unsettled = len(db.steady_state["unsettled_points"])
    print(f"calibrate: {len(db)} points ({len(grid.speeds)} speeds x {len(grid.torques)} torques), "
          f"{unsettled} unsettled, torque range {db.torque_range:.3f} N m, "
          f"{time.monotonic() - start:.1f} s -> {args.out}")
    return 0


def _calibrate_live(args, rig, grid, criterion, journal_path, bar):
    """The --live path; the ROS shell is imported only here (the simulator path needs no rclpy)."""
    from torque_estimator.calibration.calibration_node import run_live

    n = len(grid.speeds) * len(grid.torques)
    journal = CalibrationJournal.open(journal_path, live_settings(grid, rig, criterion), n, args.resume,
                                      args.drop_bad_points)
    run = PointByPoint(grid, journal, criterion, 1.0 / rig.sensors.sample_rate_hz)
    bar.update_to(len(journal.points))
    run_live(run, start_timeout=args.start_timeout, on_point=lambda: bar.update_to(len(journal.points)))
    if run.skipped_samples:
        print(f"calibrate: skipped {run.skipped_samples} samples with a NaN/inf channel", file=sys.stderr)
    return run.database(rig)


def _points_in(journal_path: Path) -> int:
    """Points recorded in a journal file (0 if there is none or it cannot be read)."""
    try:
        return len(CalibrationJournal.load(journal_path, n_points=sys.maxsize).points)
    except CalibrationError:
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
