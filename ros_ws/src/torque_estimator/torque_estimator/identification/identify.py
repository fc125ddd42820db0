"""identify: calibrate in a minute; fit the rig from one short excitation and write an extended rig file.

    ros2 run torque_estimator identify --out identified_rig.yaml [--rig rig.yaml]     # the rig on the graph
    ros2 run torque_estimator identify --out identified_rig.yaml --resume                # after Ctrl-C
    ros2 run torque_estimator identify --from run.csv|bag --rig rig.yaml --out identified_rig.yaml

Live (no --from): drives whatever rig is on the graph (sim_node or driver_node, held by
controller_node, which must run) through an excitation of at most 90 s of rig time: at 7
worm speeds per direction the load goes across the load motors' range in steps and back in
a ramp; speed steps and ramps between them, a slow reversal through zero and a fast one
under load (identification/excitation.py); nothing waits for a point to settle.  Every
sample is recorded (<record>, the worm_rig_data CSV schema), then fitted.

Offline (--from): fits a recorded run (CSV in that schema, or a rosbag2 bag).

The fit (identification/fit.py): what varies from gearbox to gearbox, whatever the rig file
says about where its number came from (source: or assumption:): the standard set of
worm_model.residuals.free (mu under the file's friction model, K_t, drags, rotor inertia), plus
the file's free: list (--free replaces both); the geometry stays as declared.  Each correction is
printed as `residuals` prints it (declared -> identified +- interval, tolerance band).  Also
the effects the residual analysis accepts.  Output: the extended rig file (the rig file with identified
values, free:, effects: and an identification: section with the ranges covered), which
estimator_node loads as model_file (method extended_model or observer), and `estimate`
with --model-file.

Live runs are resumable like calibrate: after every segment of the excitation its samples
go to a journal (<out>.partial.json, <out>.partial.csv); after Ctrl-C, SIGTERM or SIGKILL
the same command with --resume records only the missing segments.  On every exit the rig
is commanded to stop (speed 0, load 0).  The last line printed is
    identify: rig_time_s=<x> samples=<n> found=<names|none> rms_before=<x> rms_after=<y> A -> <out>
Exit codes: 0 done, 1 the live rig failed, 2 bad input, 130 interrupted (journal kept).
"""
from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

from worm_model.cli.errors import run_tool
from worm_model.errors import InputError, ParameterError, RigDataError
from worm_model.cli.options import Parser, output_path
from worm_model.cli.progress import Progress, ProgressBar
from worm_model.files.reading import load_yaml
from worm_model.files.writing import Output, atomic_file, check_output
from worm_model.physics.parameters import load_rig
from worm_model.residuals.free import FREE_PARAMETERS
from worm_model.rig_data.epos_options import add_epos_arguments, epos_settings
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import is_rig_csv, write_rig_csv

from torque_estimator.errors import IdentificationError, JournalError, LiveRigError
from torque_estimator.identification.excitation import (DEFAULT_DURATION, MAX_DURATION, default_excitation,
                                                        total_duration)
from torque_estimator.identification.fit import identify
from torque_estimator.identification.writing import write_identified
from torque_estimator.session.recording import ExcitationRun, Journal, journal_paths, run_settings

PROG = "identify"
EXIT_INTERRUPTED = 130


def _is_identified(path: Path) -> bool:
    """``path`` is an extended rig file identify wrote (a rig file with an identification: section)."""
    document = load_yaml(path, "rig parameter file")
    return isinstance(document, dict) and "identification" in document


#: what identify writes; --force replaces only its own earlier output (worm_model.files.writing)
OUTPUT = Output(PROG, recognise=_is_identified)
RECORD = Output(PROG, recognise=is_rig_csv)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description=__doc__.split("\n\n")[0],
                                epilog="\n\n".join(__doc__.split("\n\n")[1:]),
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=output_path, required=True,
                   help="extended rig file to write (YAML; estimator_node's model_file); an existing one is "
                        "replaced only with --force, and only if identify wrote it")
    p.add_argument("--force", action="store_true",
                   help="replace an existing --out (and --record) that identify wrote before")
    p.add_argument("--rig", type=Path, default=None,
                   help="the rig file to start from (worm_rig_parameters); the standard set (mu, K_t, drags, rotor "
                        "inertia) is fitted whatever its source:/assumption: marks, plus its optional free: list "
                        "(default: the bundled NMRV030 rig)")
    p.add_argument("--free", default=None,
                   help="comma-separated parameters to fit instead of the default set; allowed: "
                        f"{', '.join(FREE_PARAMETERS)}")
    p.add_argument("--from", dest="source", type=Path, default=None,
                   help="fit a recorded run instead of driving the rig: a CSV in the worm_rig_data schema or a "
                        "rosbag2 bag (directory, .mcap or .db3)")
    live = p.add_argument_group("live rig (without --from)")
    live.add_argument("--duration", type=float, default=DEFAULT_DURATION,
                      help=f"rig time of the excitation [s], at most {MAX_DURATION:g}; shorter runs fit less well "
                           f"(default {DEFAULT_DURATION:g})")
    live.add_argument("--record", type=output_path, default=None,
                      help="where to keep the recorded run as CSV (default: <out without suffix>_record.csv)")
    live.add_argument("--resume", action="store_true",
                      help="continue the interrupted run in the journal (same --out and --duration required)")
    live.add_argument("--start-timeout", type=float, default=30.0,
                      help="wait this long [s] for the rig's samples and controller_node (default 30)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    add_epos_arguments(p)
    return p


def _fail(where: str, what: str) -> int:
    print(f"{PROG}: {where}: {what}", file=sys.stderr)
    return 2


def _interrupt(signum, _frame) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def main(argv: list[str] | None = None) -> int:
    return run_tool(PROG, lambda: _main(argv))  # Ctrl-C while reading: exit 130, nothing written


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if not args.out.parent.is_dir():
        return _fail("--out", f"folder {args.out.parent} does not exist")
    if not 0 < args.duration <= MAX_DURATION:
        return _fail("--duration", f"must be in (0, {MAX_DURATION:g}] s, got {args.duration:g}")
    if args.start_timeout <= 0:
        return _fail("--start-timeout", f"must be > 0, got {args.start_timeout:g}")
    if args.source is not None and (args.resume or args.record is not None):
        return _fail("--from", "--resume and --record apply to a live run only")
    free = None
    if args.free is not None:
        free = [name.strip() for name in args.free.split(",") if name.strip()]
        bad = [name for name in free if name not in FREE_PARAMETERS]
        if bad or not free:
            return _fail("--free", f"{bad[0] if bad else args.free!r} cannot be fitted "
                                   f"(allowed: {', '.join(FREE_PARAMETERS)})")
    record = None if args.source is not None else args.record or args.out.with_name(args.out.stem + "_record.csv")
    inputs = [args.rig, args.source]
    try:  # before any work: never over an input, --force only over identify's own output
        check_output(args.out, args.force, inputs=inputs, output=OUTPUT)
        if record is not None:
            check_output(record, args.force, option="--record", inputs=[*inputs, args.out], output=RECORD)
    except InputError as err:
        return _fail(err.where, err.what)
    try:
        rig = load_rig(args.rig)
    except ParameterError as err:
        return _fail("--rig", str(err))
    signal.signal(signal.SIGTERM, _interrupt)  # `kill` gets the same clean stop as Ctrl-C
    start = time.monotonic()
    if args.source is not None:
        try:
            data = read_rig_data(args.source, rig=rig, epos=epos_settings(args, rig))
        except RigDataError as err:
            return _fail("--from", str(err))
        except InputError as err:  # an option of the EPOS reader
            return _fail(err.where, err.what)
        for note in data.notes:
            print(f"identify: note: {note}")
        source = str(args.source)
        journal = None
    else:
        try:
            journal, data = _record_live(args, rig)
        except KeyboardInterrupt:
            state, _csv = journal_paths(args.out)
            print(f"\n{PROG}: interrupted; the rig was commanded to stop; journal {state}; run the same command "
                  "with --resume to continue", file=sys.stderr)
            return EXIT_INTERRUPTED
        except JournalError as err:
            return _fail("journal", str(err))
        except LiveRigError as err:
            state, _csv = journal_paths(args.out)
            print(f"{PROG}: live rig: {err}\n{PROG}: the finished segments are in {state}; fix the graph and run "
                  "the same command with --resume", file=sys.stderr)
            return 1
        with atomic_file(record, args.force, option="--record", inputs=[*inputs, args.out], output=RECORD) as tmp:
            write_rig_csv(tmp, data)
        source = f"{record.name} (live rig, {total_duration(default_excitation(rig, args.duration)):.1f} s excitation)"
    progress = Progress(enabled=not args.quiet)

    def on_progress(label: str, done: int, total: int) -> None:
        if progress.name != label:
            progress.stage(label, total)
        progress.update_to(done)

    try:
        ident = identify(data, args.rig, free, progress=on_progress)
        with atomic_file(args.out, args.force, inputs=inputs, output=OUTPUT) as tmp:
            write_identified(tmp, args.rig, ident, source)
    except KeyboardInterrupt:
        progress.close()
        print(f"\n{PROG}: interrupted while fitting" + ("; the record is in the journal: run the same command with "
                                                       "--resume to fit it" if journal is not None else ""),
              file=sys.stderr)
        return EXIT_INTERRUPTED
    except ParameterError as err:
        progress.close()
        return _fail("--free" if free else "--rig", str(err))
    except IdentificationError as err:
        progress.close()
        return _fail("--from" if args.source else "record", str(err))
    except InputError as err:  # --out cannot be written
        progress.close()
        return _fail(err.where, err.what)
    progress.close()
    if journal is not None:
        journal.remove()
    for line in summary(ident, time.monotonic() - start):
        print(line)
    print(f"{PROG}: rig_time_s={ident.rig_time:.1f} samples={ident.samples} road={ident.road.replace(' ', '_')} "
          f"found={','.join(ident.found) or 'none'} "
          f"held={','.join(h.parameter for h in ident.held) or 'none'} "
          f"rms_before={ident.rms_before:.4f} rms_after={ident.rms_after:.4f} A -> {args.out}")
    return 0


def _record_live(args, rig):
    """The live path: journal, excitation on the graph; the ROS shell is imported only here."""
    from torque_estimator.session.recording_node import run_live  # noqa: PLC0415

    timeline = default_excitation(rig, args.duration)
    journal = Journal.open(args.out, run_settings(timeline, {}, "live"), args.resume)
    run = ExcitationRun(timeline, journal, 1.0 / rig.sensors.sample_rate_hz)
    with ProgressBar(run.total_samples, "excitation [samples]", enabled=not args.quiet) as bar:
        bar.update_to(run.samples_done)
        if not run.finished:
            run_live(run, "identify", start_timeout=args.start_timeout, on_tick=lambda: bar.update_to(run.samples_done))
    if run.skipped_samples:
        print(f"{PROG}: skipped {run.skipped_samples} samples with a NaN/inf channel", file=sys.stderr)
    return journal, journal.data(str(journal.csv_path))


def summary(ident, wall: float) -> list[str]:
    """What was fitted and found, for the console."""
    loads = (f"{ident.loads} load, trusted {ident.torque_range[0]:+.4g} .. {ident.torque_range[1]:+.4g} N m"
             if ident.loads == 1 else f"loads {ident.torque_range[0]:+.4g} .. {ident.torque_range[1]:+.4g} N m")
    lines = [f"record ({ident.road}): {ident.samples} samples, {ident.rig_time:.1f} s of rig time; speeds up to "
             f"{ident.speed_max:.4g} rad/s, {loads}",
             f"candidates ({ident.choice})",
             f"fitted: {', '.join(ident.fitted) or 'none'}"]
    lines += [f"  {line}" for line in ident.correction_lines()]
    lines += [held.line() for held in ident.held]
    lines += ident.report
    if ident.noise is not None:
        lines += ident.noise.lines()
    lines.append(f"found: {', '.join(ident.found) or 'none'}; held-out current RMS {ident.rms_before:.4g} A (rig file "
                 f"as declared) -> {ident.rms_after:.4g} A; {wall:.1f} s")
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
