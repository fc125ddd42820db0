"""calibrate: run the paper's calibration grid on the simulated rig and write the database.

    ros2 run torque_estimator calibrate --out calibration.json

Every point: the speed controller holds a constant worm speed while the load
motors apply a constant torque; once steady, a window is averaged. The grid is
17 speeds x 16 torques in both directions unless told otherwise.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from worm_model.parameters import ParameterError, load_rig

from .calibration import CalibrationGrid, calibrate_simulated
from .calibration_database import save_database
from .operating_points import SteadyStateCriterion
from .progress import ProgressBar


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="calibrate", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--out", type=Path, required=True, help="calibration database to write (JSON)")
    p.add_argument("--rig", type=Path, default=None, help="rig parameter YAML (default: the bundled NMRV030 rig)")
    p.add_argument("--speeds", type=int, default=17, help="number of worm speeds per direction")
    p.add_argument("--torques", type=int, default=16, help="number of load torques")
    p.add_argument("--speed-min", type=float, default=20.0, help="smallest worm speed [rad/s]")
    p.add_argument("--speed-max", type=float, default=340.0, help="largest worm speed [rad/s]")
    p.add_argument("--torque-fraction", type=float, default=0.9,
                   help="load torques span +- this fraction of what the load motors can make")
    p.add_argument("--window", type=float, default=SteadyStateCriterion.window,
                   help="averaging window of a steady point [s]")
    p.add_argument("--timeout", type=float, default=SteadyStateCriterion.timeout,
                   help="time after which an unsettled point is kept as it is [s]")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulated sensor noise")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        rig = load_rig(args.rig)
        grid = CalibrationGrid.paper(rig, args.speeds, args.torques, args.speed_min, args.speed_max,
                                     args.torque_fraction)
    except (ParameterError, ValueError) as err:
        print(f"calibrate: {err}", file=sys.stderr)
        return 2
    criterion = SteadyStateCriterion(window=args.window, timeout=args.timeout)
    n = len(grid.speeds) * len(grid.torques)
    start = time.monotonic()
    with ProgressBar(n, "calibration points settled", enabled=not args.quiet) as bar:
        db = calibrate_simulated(rig, grid, seed=args.seed, criterion=criterion,
                                 progress=lambda fraction: bar.update_to(round(fraction * n)))
    save_database(db, args.out)
    unsettled = len(db.steady_state["unsettled_points"])
    print(f"calibrate: {len(db)} points ({len(grid.speeds)} speeds x {len(grid.torques)} torques), "
          f"{unsettled} unsettled, torque range {db.torque_range:.3f} N m, "
          f"{time.monotonic() - start:.1f} s -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
