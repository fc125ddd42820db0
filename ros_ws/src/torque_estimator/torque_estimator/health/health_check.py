"""health_check: a short reference run that says what wore, with intervals, against the gearbox's baseline.

    ros2 run torque_estimator health_check --trend gearbox.jsonl [--hours 1520]          # the rig on the graph
    ros2 run torque_estimator health_check --trend gearbox.jsonl --from run.csv|bag       # a recorded run

Live (no --from): drives whatever rig is on the graph (sim_node or driver_node, held by controller_node,
which must run) through the reference run (health/reference.py: 3 worm speeds per direction, 5 held loads
at each, 28.5 s of rig time), recording every sample (the machinery of `identify`); the record goes to
--record. The oil temperature comes from a sensor on --temperature-topic if one publishes, else from the
live monitor's estimate (health_monitor's `health` topic), else from --temperature, else it is assumed
(the settings' ambient: a cold machine).

Offline (--from): a recorded run (CSV in the worm_rig_data schema, or a rosbag2 bag): its steady
constant-speed points are found whatever made the run; its `temperature` column, if any, is the oil's.

The fit (worm_model.health.fit): mu's scale, speed and load laws, the drive- and gear-side drags, the
current sensor's offset, with intervals; the backlash from the transmission error where the gear's angle
is recorded. The check is appended to the trend file (created with the first check) and compared with the
gearbox's baseline: its first checks (--baseline first, default: the settings' baseline_checks) or the
rig file (--baseline rig); mu is compared at the reference temperature through the temperature law the
checks teach (worm_model.health.assess). Findings are printed with their 95 % intervals; the last line is

    health_check: level=<OK|WARN|ERROR> mu_change=<x>% +- <y>% trend=<x>% +- <y>% oil=<t> degC (<source>) -> <trend>

Exit codes: 0 checked (whatever the level), 1 the live rig failed, 2 bad input, 130 interrupted.
"""
from __future__ import annotations

import argparse
import datetime as dt
import math
import sys
import time
from pathlib import Path

import numpy as np

from worm_model.cli.errors import run_tool
from worm_model.errors import FitError, InputError
from worm_model.cli.options import Parser, existing_file, number
from worm_model.cli.progress import ProgressBar
from worm_model.files.writing import check_output
from worm_model.health.assess import Z95, assess_trend, baseline_from_rig, baseline_of
from worm_model.health.blocks import blocks_from_data
from worm_model.health.fit import Temperature, fit_points
from worm_model.health.model import NAMES, UNITS, HealthParameters
from worm_model.health.points import steady_points
from worm_model.health.record import CheckRecord, Trend, read_trend, write_trend
from worm_model.health.settings import HealthSettings, load_settings
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData, write_rig_csv

from torque_estimator.errors import LiveRigError
from torque_estimator.health.reference import LOADS, MAX_DURATION, SPEEDS, reference_run, total_duration

PROG = "health_check"


def _loads(text: str) -> tuple[float, ...]:
    if text == "none":
        return (0.0,)
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a comma-separated list of numbers: {text!r}") from None
    if not values or any(not -1.0 <= v <= 1.0 for v in values):
        raise argparse.ArgumentTypeError(f"load fractions must lie in [-1, 1]: {text!r}")
    return values


def _speeds(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a comma-separated list of numbers: {text!r}") from None
    if not values or any(not (v > 0 and math.isfinite(v)) for v in values):
        raise argparse.ArgumentTypeError(f"speeds must be > 0 rad/s: {text!r}")
    return values


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description=__doc__.split("\n\n")[0], epilog="\n\n".join(__doc__.split("\n\n")[1:]),
               formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--trend", type=Path, required=True,
                   help="the gearbox's trend file (worm_gearbox_health_trend, JSON Lines): read, the check appended, "
                        "written back atomically; created with the first check")
    p.add_argument("--rig", type=existing_file, default=None,
                   help="rig parameter file (worm_rig_parameters; e.g. identify's extended rig file): the model's "
                        "mu law, geometry and motor constant (default: the bundled NMRV030 rig)")
    p.add_argument("--settings", type=existing_file, default=None,
                   help="health settings (worm_gearbox_health_settings YAML: priors, alarm limits, thermal model); "
                        "default: the built-in ones")
    p.add_argument("--from", dest="source", type=Path, default=None,
                   help="check a recorded run instead of driving the rig: a CSV in the worm_rig_data schema or a "
                        "rosbag2 bag (directory, .mcap or .db3)")
    p.add_argument("--hours", type=number("h", 0.0), default=None,
                   help="the gearbox's hours run at this check (its age on the trend's axis; default: unknown)")
    p.add_argument("--temperature", type=number("degC", -50.0, 200.0), default=None,
                   help="the oil temperature [degC] if read off a gauge (used when the run records none and no "
                        "sensor publishes one)")
    p.add_argument("--temperature-sigma", type=number("K", 0.0, open_low=True), default=1.0,
                   help="standard uncertainty of --temperature [K] (default 1)")
    p.add_argument("--baseline", choices=("first", "rig"), default="first",
                   help="what the check is compared with: the trend's first checks (default; the settings' "
                        "baseline_checks of them) or the rig file's values (to within 10 %%)")
    p.add_argument("--plot", type=Path, default=None,
                   help="also write the trend with its alarm bands as a PNG here (an existing file only with --force)")
    p.add_argument("--force", action="store_true", help="let --plot and --record replace existing files")
    p.add_argument("--dry-run", action="store_true", help="check and print, but do not append to the trend")
    live = p.add_argument_group("live rig (without --from)")
    live.add_argument("--speeds", type=_speeds, default=SPEEDS,
                      help=f"worm speeds per direction [rad/s], comma-separated (default "
                           f"{','.join(f'{v:g}' for v in SPEEDS)})")
    live.add_argument("--loads", type=_loads, default=LOADS,
                      help="load levels as fractions of what the load motors make, comma-separated, or 'none' (a "
                           f"robot without load motors) (default {','.join(f'{v:g}' for v in LOADS)})")
    live.add_argument("--record", type=Path, default=None,
                      help="where to keep the recorded run as CSV (default: <trend without suffix>_<date>.csv)")
    live.add_argument("--temperature-topic", default="oil_temperature",
                      help="sensor_msgs/Temperature topic of the oil sensor (default oil_temperature)")
    live.add_argument("--health-topic", default="health",
                      help="the live monitor's worm_msgs/GearboxHealth topic, for its temperature estimate "
                           "(default health)")
    live.add_argument("--start-timeout", type=number("s", 0.0, open_low=True), default=30.0,
                      help="wait this long [s] for the rig's samples and controller_node (default 30)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool(PROG, lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if args.source is not None and args.record is not None:
        raise InputError("--record", "applies to a live run only (not with --from)")
    rig = load_rig(args.rig)
    settings = load_settings(args.settings)
    trend = read_trend(args.trend) if args.trend.exists() else Trend(rig.name, source=str(args.trend))
    if not args.trend.exists():
        check_output(args.trend, option="--trend")
    if args.plot is not None:
        check_output(args.plot, args.force, option="--plot")
    now = dt.datetime.now(dt.timezone.utc).replace(microsecond=0)
    if args.source is not None:
        data = read_rig_data(args.source)
        source = str(args.source)
        graph_temperature = None
    else:
        timeline = reference_run(rig, args.speeds, args.loads)
        if total_duration(timeline) > MAX_DURATION + 5.0:
            raise InputError("--speeds/--loads", f"the run would take {total_duration(timeline):.0f} s of rig time; "
                             f"a check is meant to take ~{MAX_DURATION:g} s: use fewer speeds or loads")
        record_path = args.record or args.trend.with_name(f"{args.trend.stem}_{now:%Y%m%dT%H%M%S}.csv")
        check_output(record_path, args.force, option="--record")
        data, graph_temperature = _record_live(args, rig, timeline)
        write_rig_csv(record_path, data)
        source = f"{record_path.name} (live rig, {total_duration(timeline):.1f} s reference run)"
    temperature = _temperature(data, args, settings, graph_temperature)
    blocks = blocks_from_data(data, rig.gearbox.ratio, settings.live.block_time)
    points = steady_points(blocks, rig, settings.points)
    try:
        fit = fit_points(points, rig, HealthParameters.from_rig(rig), settings.priors)
    except FitError as err:
        raise InputError("--from" if args.source is not None else "record", str(err)) from None
    record = CheckRecord.from_fit(fit, temperature, now.isoformat(), args.hours, source, points)
    trend.records.append(record)
    fixed = baseline_from_rig(rig, settings) if args.baseline == "rig" else None
    assessments = assess_trend(trend.records, settings, rig, fixed)
    result = assessments[-1]
    for line in _summary(fit, record, result, settings, len(trend.records)):
        print(line)
    if not args.dry_run:
        write_trend(args.trend, trend)
    if args.plot is not None:
        baseline = fixed or baseline_of(trend.records, settings, rig)
        _write_plot(args.plot, trend.records, assessments, settings, rig, baseline, f"Gearbox health: {trend.gearbox}")
    mu = "n/a (baseline)" if result is None else f"{result.mu_change.value:+.1%} +- {Z95 * result.mu_change.sigma:.1%}"
    tr = "n/a" if result is None or result.trend_change is None else \
        f"{result.trend_change.value:+.1%} +- {Z95 * result.trend_change.sigma:.1%}"
    print(f"{PROG}: level={record.level} mu_change={mu} trend={tr} oil={temperature.value:.1f} degC "
          f"({temperature.source}) -> {args.trend}{' (dry run: not written)' if args.dry_run else ''}")
    return 0


def _write_plot(path: Path, *args) -> None:
    """The trend figure, written beside ``path`` and moved over it at the end (never half a PNG)."""
    from worm_model.files.writing import atomic_file  # noqa: PLC0415
    from worm_model.health.plots import trend_figure  # noqa: PLC0415 (matplotlib only when asked)

    with atomic_file(path, force=True) as tmp:
        trend_figure(tmp.with_suffix(".png"), *args)
        tmp.with_suffix(".png").replace(tmp)


def _record_live(args, rig, timeline) -> tuple[MeasuredData, tuple | None]:
    """The live path: the oil's temperature before, the reference run, after; the ROS shells are imported here."""
    from torque_estimator.health.check_node import listen_temperature  # noqa: PLC0415
    from torque_estimator.session.recording_node import run_live  # noqa: PLC0415
    from torque_estimator.session.recording import ExcitationRun, Journal, run_settings  # noqa: PLC0415

    before = listen_temperature(args.temperature_topic, args.health_topic, 2.0)
    run = ExcitationRun(timeline, Journal(run_settings(timeline, {}, "live")), 1.0 / rig.sensors.sample_rate_hz)
    try:
        with ProgressBar(run.total_samples, "reference run [samples]", enabled=not args.quiet) as bar:
            run_live(run, "health_check", start_timeout=args.start_timeout,
                     on_tick=lambda: bar.update_to(run.samples_done))
    except LiveRigError as err:
        print(f"{PROG}: live rig: {err}", file=sys.stderr)
        raise SystemExit(1) from None
    after = listen_temperature(args.temperature_topic, args.health_topic, 2.0)
    heard = [t for t in (before, after) if t is not None]
    graph = None
    if heard:
        source = "measured" if any(t[0] == "measured" for t in heard) else "estimated"
        same = [t for t in heard if t[0] == source]
        graph = (source, float(np.mean([t[1] for t in same])), float(np.nanmax([t[2] for t in same])))
    return run.journal.data(f"live rig ({time.strftime('%Y-%m-%d %H:%M')})"), graph


def _temperature(data: MeasuredData, args, settings: HealthSettings, graph) -> Temperature:
    """The check's oil temperature: the run's column, the graph's sensor or estimate, the option, or assumed."""
    sensor = settings.temperature.sensor_sigma
    if data.temperature is not None and np.isfinite(data.temperature).any():
        t = data.temperature[np.isfinite(data.temperature)]
        return Temperature(float(t.mean()), math.hypot(sensor, float(t.std())), "measured")
    if graph is not None:
        source, value, sigma = graph
        return Temperature(value, sigma if math.isfinite(sigma) else sensor, source)
    if args.temperature is not None:
        return Temperature(args.temperature, args.temperature_sigma, "measured")
    th = settings.thermal
    return Temperature(th.ambient, math.hypot(th.ambient_sigma, th.initial_sigma), "assumed")


def _summary(fit, record: CheckRecord, result, settings: HealthSettings, count: int) -> list[str]:
    t = record.temperature
    lines = [f"check: {fit.points} steady points, {fit.rig_time:.1f} s of them; speeds "
             + ", ".join(f"{k} {v[0]:.0f}..{v[1]:.0f} rad/s" for k, v in fit.speeds.items())
             + f"; loads {fit.loads[0]:+.3f}..{fit.loads[1]:+.3f} N m; oil {t.value:.1f} +- {Z95 * t.sigma:.1f} degC "
               f"({t.source})",
             f"fit: RMS residual {1e3 * fit.rms:.3f} mN m, reduced chi-square {fit.chi2_red:.2f} "
             "(intervals of the absolute values are widened by its root where > 1)"]
    for name in NAMES:
        value, ci = getattr(fit.parameters, name), Z95 * fit.interval(name)
        note = "" if fit.identified[name] else "  (not identified by this run: the prior's)"
        lines.append(f"  {name:18s} {value:+.5g} +- {ci:.2g} {UNITS[name]}{note}")
    if math.isfinite(fit.backlash):
        lines.append(f"  {'backlash':18s} {math.degrees(fit.backlash) * 60:.2f} +- "
                     f"{math.degrees(Z95 * fit.backlash_sigma) * 60:.2f} arcmin")
    lines.append(f"  {'wheel runout':18s} {1e3 * fit.runout:.2f} mN m once per gear turn (nuisance)")
    n = settings.limits.baseline_checks
    if result is None:
        lines.append(f"baseline: check {count} of {n}; alarms start with check {n + 1}")
    else:
        lines += [f"  {f.text}" for f in result.findings]
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
