"""foreign: the datasheet road on worm drives the project did not make, as a new user walks it.

    python -m torque_estimator.evaluation.datasheet_road [--seconds 240]     (make evaluate runs it too)

The drives are evaluation.foreign's: a simulator of their own equations (it imports nothing of the
project) and three drives, each with its catalogue numbers and a hidden truth the project never
reads: ``foreign30`` (30:1, constant mu 0.06, an encoder of 2000 counts for the speed, 4 mA of
current noise, nothing on the output but the load), ``big50`` (50:1 industrial, an encoder of 4096
counts averaged over 4 samples) and ``lift40`` (40:1, self-locking: a Stribeck mu above the
self-locking limit, a tacho, a quantised current sensor, 500 Hz). For each, only what a user has:

1. ``rig_from_datasheet`` with its catalogue numbers and nothing else (the default template of a
   drive on a robot: no load motors, stand-ins scaled to the drive);
2. ``identify --from`` one recording (an excitation of seeded speed and load steps, 240 s);
3. ``estimate`` on a second recording of the same drive with the file identify wrote, for
   extended_model, momentum and observer: the steady windows' mean error and largest error in % of
   the recording's load range (offline.estimate.figures).

For the self-locking lift, a lift's own run as well: ``estimate`` on a start-stop run (rest, lower the
hanging load, stop, lift it, stop) without a prior and with ``--load-min 0 --load-max`` twice the load.

The lines (one each):
    foreign: drive=<d> method=<m> mae_pct=<x> max_pct=<x> steady_points=<n> trusted_pct=<x>
    foreign_lift: drive=lift40 method=<m> prior=<yes|no> mae_pct=<x> max_pct=<x> trusted_pct=<x>
"""
from __future__ import annotations

import argparse
import tempfile
from dataclasses import dataclass
from pathlib import Path

from worm_model.calc.datasheet import main as rig_from_datasheet
from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, number
from worm_model.rig_data.reader import read_rig_data

from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.evaluation.foreign.drives import DRIVES, datasheet_args
from torque_estimator.evaluation.foreign.recordings import excitation, speed_range, start_stop, validation, write_csv
from torque_estimator.identification.fit import Identification, identify
from torque_estimator.identification.writing import write_identified
from torque_estimator.offline.estimate import Figures, PointEstimates, figures, run_estimator

#: [s] of each recording
SECONDS = 240.0
#: the methods compared (the observer reads the recordings' voltage)
METHODS = ("extended_model", "momentum", "observer")
#: the seeds of the two recordings of each drive
IDENTIFY_SEED, ESTIMATE_SEED = 1, 2


@dataclass
class DriveResult:
    """One drive through the road: what identify found, and estimate's figures per method."""

    drive: str
    identification: Identification
    figures: dict[str, Figures]

    def lines(self) -> list[str]:
        return [f"foreign: drive={self.drive} method={m} mae_pct={f.mae_pct:.2f} max_pct={f.max_pct:.2f} "
                f"steady_points={f.steady_points} trusted_pct={f.trusted_pct:.1f}" for m, f in self.figures.items()]


def rig_file(drive: str, folder: Path) -> Path:
    """``rig_from_datasheet`` with the drive's catalogue numbers only (module docstring, step 1)."""
    path = folder / f"{drive}.yaml"
    code = rig_from_datasheet(["--out", str(path), "--name", drive, "--source", f"{drive} catalogue",
                               *datasheet_args(DRIVES[drive])])
    if code != 0:
        raise RuntimeError(f"rig_from_datasheet refused {drive}'s catalogue (exit {code})")
    return path


def estimate_figures(csv: Path, model_file: Path, method: str, options: dict | None = None) -> Figures:
    """``estimate`` on a recording with the file identify wrote (module docstring, step 3)."""
    built = build_estimator(EstimatorSettings(method, model_file=str(model_file), options=options or {}))
    data = read_rig_data(csv, rig=built.rig)
    estimate = run_estimator(data, lambda: built.live(data.sample_period))
    return figures(data, estimate, built.rig, points=PointEstimates.of(data, built.estimator))


def run_drive(drive: str, folder: Path, seconds: float = SECONDS) -> DriveResult:
    """One drive through the datasheet road (module docstring)."""
    rig_path = rig_file(drive, folder)
    record, check = folder / f"{drive}_identify.csv", folder / f"{drive}_estimate.csv"
    write_csv(record, excitation(DRIVES[drive], seconds, IDENTIFY_SEED))
    write_csv(check, validation(DRIVES[drive], seconds, ESTIMATE_SEED))
    data = read_rig_data(record, rig=None, check=False)
    ident = identify(data, rig_path)
    model_file = folder / f"{drive}_identified.yaml"
    write_identified(model_file, rig_path, ident, record.name)
    return DriveResult(drive, ident, {m: estimate_figures(check, model_file, m) for m in METHODS})


def lift_lines(folder: Path) -> list[str]:
    """The self-locking lift's start-stop run, without and with a prior (module docstring)."""
    drive = DRIVES["lift40"]
    model_file = folder / "lift40_identified.yaml"
    run = folder / "lift40_start_stop.csv"
    load = drive.load_scale
    write_csv(run, start_stop(drive, load, speed_range(drive)[1] / 3.0, seed=3))
    out = []
    for method in METHODS:
        for prior in (False, True):
            options = {"load_min": 0.0, "load_max": 2.0 * load} if prior else {}
            f = estimate_figures(run, model_file, method, options)
            out.append(f"foreign_lift: drive=lift40 method={method} prior={'yes' if prior else 'no'} "
                       f"mae_pct={f.mae_pct:.2f} max_pct={f.max_pct:.2f} trusted_pct={f.trusted_pct:.1f}")
    return out


def run(seconds: float = SECONDS, progress=None) -> list[str]:
    """Every drive's lines, then the lift's (module docstring)."""
    lines = []
    with tempfile.TemporaryDirectory(prefix="datasheet_road_") as name:
        folder = Path(name)
        for k, drive in enumerate(("foreign30", "big50", "lift40")):
            result = run_drive(drive, folder, seconds)
            ident = result.identification
            lines.append(f"  {drive}: identify fitted {', '.join(ident.fitted)}; held "
                         f"{', '.join(h.parameter for h in ident.held) or 'none'}; found "
                         f"{', '.join(ident.found) or 'none'}; friction law {ident.model.rig.friction.model}")
            lines += result.lines()
            if progress is not None:
                progress(k + 1)
        lines += lift_lines(folder)
    return lines


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="datasheet_road", description=__doc__.split("\n\n")[0],
               epilog="\n\n".join(__doc__.split("\n\n")[1:]), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=number("s", 10.0, 3600.0), default=SECONDS,
                   help=f"length of each recording [s] (default {SECONDS:g})")
    return p


def main(argv: list[str] | None = None) -> int:
    def go() -> int:
        args = build_parser().parse_args(argv)
        print("\n".join(run(args.seconds)))
        return 0

    return run_tool("datasheet_road", go)


__all__ = ["METHODS", "DriveResult", "estimate_figures", "lift_lines", "main", "rig_file", "run", "run_drive"]


if __name__ == "__main__":
    raise SystemExit(main())
