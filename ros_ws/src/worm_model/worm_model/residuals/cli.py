"""``residuals``: close the loop between the gearbox model and measured data.

    residuals <data.csv | bag directory> --out <dir> [--rig rig.yaml] [options]

Fits the declared model (paper Eqs 28-30 with the motor; the parameters the rig file's
``free:`` list names, plus a standard set refitted always, ``--refit``) to part of the data,
ranks the candidate effects of physics.md section 9 by how much of the residual each
explains on held-out data, adds the significant ones, drops any that no longer earn their
keep, and writes <dir>/report.json, <dir>/extended_rig.yaml (the extended model: rig file +
``effects:``) and PNG plots.  It estimates the current's noise floor from the data; when
the held-out RMS stays above 1.3x that floor it reports an unexplained residual and what
it goes with.  The last console line is
``found: <name,name|none> rms_before=<x> rms_after=<y> A[ unexplained=<z> A]``.
Exit codes: 0 done, 2 bad input (the message names the file, line/field and column).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from worm_model.physics.parameters import default_rig_path, load_rig
from worm_model.errors import ParameterError
from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, existing_file, integer, number, output_path
from worm_model.files.writing import Output, atomic_dir, check_output

from worm_model.residuals.analysis import Problem, Settings, analyse, extended_effects, make_split
from worm_model.residuals.data import load_data
from worm_model.rig_data.epos_options import add_epos_arguments, epos_settings
from worm_model.residuals.effects import EFFECTS
from worm_model.residuals.extended import ExtendedModel, write_parameter_file
from worm_model.residuals.free import FREE_PARAMETERS, STANDARD_REFIT, check_free, read_free, resolve_parameters
from worm_model.residuals.model import ALPHA_TIME_CONSTANT, prepare_signals
from worm_model.cli.progress import Progress
from worm_model.residuals.report import build_report, console_summary, windowed_rms, write_json, write_plots

#: what residuals writes into --out; --force replaces only a folder it wrote (worm_model.files.writing)
OUTPUT = Output("residuals", names=("report.json", "extended_rig.yaml", "*.png"))
#: the motor constant a torque channel cannot tell (the export measured K_t x current)
KT = "drive_motor.torque_constant"
MIN_SAMPLES = 200  # per set: fewer cannot rank the 14 candidates (effects.EFFECTS)


def _names(text: str, known, what: str, parser: argparse.ArgumentParser) -> list[str]:
    if text.strip().lower() in ("", "none"):
        return []
    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in known]
    if bad:
        parser.error(f"unknown {what} {bad[0]!r} (known: {', '.join(known)})")
    return names


def build_parser() -> argparse.ArgumentParser:
    d = Settings()
    p = Parser(
        prog="residuals",
        description="Fit the declared gearbox + motor model to measured data, rank the effects the model lacks "
                    "(physics.md section 9) by the held-out residual each explains, add the significant ones and "
                    "report the error before and after. The fitted signal is the drive current [A]; with a "
                    "theta_gear column also the transmission error ratio*theta_worm - theta_gear [rad], where "
                    "backlash shows.",
        epilog="CSV schema: header row; required columns t [s], current_drive [A], omega_worm [rad/s], "
               "theta_worm [rad], tau_load [N m] (+ opposes + rotation); optional voltage_drive [V], "
               "theta_gear [rad], current_load [A], temperature [degC]. See docs/bags-and-tools.md.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("data", help="measured data: a CSV file in the worm_rig_data schema, or a rosbag2 directory "
                                "(converted with worm_rig_driver's bag exporter, which must be installed)")
    p.add_argument("--out", required=True, type=output_path,
                   help="output directory (created; an existing one is replaced only with --force): report.json, "
                        "extended_rig.yaml, PNG plots")
    p.add_argument("--force", action="store_true", help="replace an existing --out directory")
    p.add_argument("--rig", type=existing_file, default=None,
                   help=f"rig parameter file (worm_rig_parameters); its optional 'free:' list names the parameters "
                        f"to fit. Default: the bundled {default_rig_path().name}")
    p.add_argument("--free", default=None,
                   help="comma-separated parameters to fit, overriding the file's 'free:' list ('none' for none); "
                        f"allowed: {', '.join(FREE_PARAMETERS)}")
    p.add_argument("--refit", default=",".join(STANDARD_REFIT),
                   help="comma-separated parameters refitted always, on top of the free list ('none' for none): "
                        "the declared numbers a rig file typically gets wrong, whatever their source: or assumption: "
                        "(worm_model.residuals.free explains the choice; friction.mu is the friction model's mu "
                        "parameter, friction.scale under agma, friction.mu_constant under constant); a deviation "
                        "beyond a parameter's tolerance that an effect is an alias of (K_t: sensor_gain, drags: "
                        "bearing_coulomb/viscous_drag, rotor inertia: inertia_error) is named as that effect; drags, "
                        "mu and inertias are never fitted below 0")
    p.add_argument("--candidates", default=",".join(EFFECTS),
                   help="comma-separated candidate effects to consider")
    p.add_argument("--holdout-fraction", type=number("", 0, 1, open_low=True, open_high=True),
                   default=d.holdout_fraction,
                   help="share of the time blocks held out (never fitted; used to rank and accept effects)")
    p.add_argument("--block", type=number("s", 0, 3600, open_low=True), default=d.block_seconds,
                   help="length of one block of the interleaved train/held-out split [s]")
    p.add_argument("--guard", type=number("s", 0, 3600), default=d.guard_seconds,
                   help="samples this close to a block edge [s] are in neither set (no filter crosses sets)")
    p.add_argument("--min-speed", type=number("rad/s", 0, 1e4), default=d.min_speed,
                   help="samples with |omega_worm| below this [rad/s] are not used (the model is kinetic); default: "
                        "the rig file's own, 5 x its speed noise (sensors: tacho_noise_std, tacho_drive_lsb)")
    p.add_argument("--min-improvement", type=number("", 0, 1, open_high=True), default=d.min_improvement,
                   help="relative held-out RMS improvement an effect must bring (besides a lower BIC) to be added")
    p.add_argument("--max-effects", type=integer(0, len(EFFECTS)), default=d.max_effects,
                   help="stop after this many effects")
    p.add_argument("--alpha-filter", type=number("s", 0, 10, open_low=True), default=ALPHA_TIME_CONSTANT,
                   help="time constant [s] of the zero-phase low-pass around the derivative of omega_worm "
                        "that gives the acceleration of the inertia term")
    p.add_argument("--reference-temperature", type=number("degC", -60, 250), default=d.reference_temperature,
                   help="oil temperature [degC] at which the rig file's mu holds: the oil_temperature effect scales "
                        "mu by 1 + mu_per_kelvin (T - this) when the data has a temperature column")
    p.add_argument("--confidence", type=number("", 0, 1, open_low=True, open_high=True), default=d.confidence,
                   help="level of the confidence intervals")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_epos_arguments(p)
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool("residuals", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    candidates = tuple(_names(args.candidates, EFFECTS, "effect", parser))
    if 2 * args.guard >= args.block:
        parser.error(f"--guard {args.guard:g} s must be below half of --block {args.block:g} s")
    settings = Settings(holdout_fraction=args.holdout_fraction, block_seconds=args.block, guard_seconds=args.guard,
                        min_speed=args.min_speed, min_improvement=args.min_improvement, max_effects=args.max_effects,
                        alpha_time_constant=args.alpha_filter, confidence=args.confidence, candidates=candidates,
                        reference_temperature=args.reference_temperature,
                        refit=tuple(check_free(_names(args.refit, FREE_PARAMETERS, "refit parameter", parser))))
    progress = Progress(enabled=not args.quiet)
    try:
        rig = load_rig(args.rig)
        free = check_free(_names(args.free, FREE_PARAMETERS, "free parameter", parser)) if args.free is not None \
            else read_free(args.rig)
        # a friction parameter the rig's friction model does not read would be a correction that cannot move
        resolve_parameters(rig, free, "--free" if args.free is not None else str(args.rig or default_rig_path()))
        resolve_parameters(rig, settings.refit, "--refit")
        progress.stage("reading data", 1)
        data = load_data(args.data, rig, epos_settings(args, rig))  # its units checked against the rig
        for note in data.notes:
            print(f"residuals: note: {note}")
        if data.current_from_torque and KT in (*free, *settings.refit):
            # K_t x current is what a torque channel measured: the fit would trade K_t against K_e for nothing
            free = [p for p in free if p != KT]
            settings = replace(settings, refit=tuple(p for p in settings.refit if p != KT))
            print(f"residuals: note: {KT} held at its declared value: the record's current is the drive's torque "
                  "channel over K_t (K_t x current is what was measured)")
        progress.update_to(1)
        check_output(args.out, args.force, folder=True, inputs=[args.data, args.rig], output=OUTPUT)
    finally:
        progress.close()
    settings = settings.for_rig(rig)
    signals = prepare_signals(rig, data, settings.alpha_time_constant, settings.reference_temperature)
    split = make_split(signals, settings, np.isfinite(data.current_drive))
    for name, mask in (("training", split.train), ("held-out", split.held_out)):
        if mask.sum() < MIN_SAMPLES:
            progress.close()
            print(f"residuals: {data.source}: only {int(mask.sum())} {name} samples with |omega_worm| >= "
                  f"{settings.min_speed} rad/s (need {MIN_SAMPLES}); record longer or lower --block / --min-speed",
                  file=sys.stderr)
            return 2
    with atomic_dir(args.out, args.force, inputs=[args.data, args.rig], output=OUTPUT) as folder:
        return _analyse(args, rig, free, data, signals, split, settings, progress, folder, Path(args.out))


def _analyse(args, rig, free, data, signals, split, settings, progress, out: Path, final: Path) -> int:
    """The analysis proper; writes into ``out``, the temporary folder that becomes ``final``."""
    print(f"data: {data.source}: {len(data)} samples, {len(np.unique(data.run))} run(s), "
          f"{data.t[-1] - data.t[0]:.1f} s; training {int(split.train.sum())}, held out {int(split.held_out.sum())}"
          + (f"; ignored columns {', '.join(data.ignored_columns)}" if data.ignored_columns else ""))
    problem = Problem(rig, free, signals, data.current_drive, split, settings)
    print(f"declared model: {rig.name}; fitted parameters: {', '.join(problem.free) or 'none'} "
          f"(free list: {', '.join(free) or 'none'}; refitted always: {', '.join(settings.refit) or 'none'})")

    def on_progress(label: str, done: int, total: int) -> None:
        if progress.name != label:
            progress.stage(label, total)
        progress.update_to(done)

    result = analyse(problem, on_progress)

    # tau_d from the current, by the declared and by the extended model, on held-out samples
    progress.stage("tau_d estimates", 2)
    before = ExtendedModel(result.declared.rig, [], settings.alpha_time_constant)
    after = ExtendedModel(*extended_effects(result), settings.alpha_time_constant)
    tau_d = {}
    for k, (key, model) in enumerate((("before", before), ("after", after))):
        error = model.estimate_load_torque(signals, data.current_drive) - data.tau_load
        held = error[split.held_out]
        held = held[np.isfinite(held)]
        tau_d[key] = float(np.sqrt(np.mean(held**2))) if len(held) else float("nan")
        window = max(1, int(round(0.02 / data.sample_period)))
        tau_d[key + "_20ms"] = windowed_rms(error, split.held_out, data.run, window)
        progress.update_to(k + 1)

    params_out = out / "extended_rig.yaml"
    write_parameter_file(params_out, args.rig or default_rig_path(), after,
                         [p for p in problem.free if p not in result.aliased_parameters], result.final.free_ci,
                         f"identified by residuals from {Path(data.source).name}",
                         {"backlash": "angle identified from the transmission error (theta_gear); see report.json"}
                         if "backlash" in after.names else None)
    try:  # a file the next tool cannot read is never written (atomic_dir drops the folder)
        load_rig(params_out)
        ExtendedModel.load(params_out)
    except ParameterError as err:
        problem_text = str(err).split(": ", 1)[1] if ": " in str(err) else str(err)
        raise ParameterError(str(final / params_out.name), "",
                             f"the fitted model is not a rig file the tools can read ({problem_text}); fit fewer "
                             "parameters (--free) or record more speeds and loads") from None
    files = {"data": data.source, "report": str(final / "report.json"), "parameters": str(final / params_out.name)}
    plots = []
    if not args.no_plots:
        progress.stage("plots", 2 + len(result.final.effects))
        plots = write_plots(out, problem, result, progress.update_to)
    files["plots"] = ", ".join(plots)
    write_json(out / "report.json", build_report(problem, result, tau_d, files))
    progress.close()
    lines = console_summary(problem, result, tau_d)
    print("\n".join(lines[:-1]))
    print(f"wrote {final / 'report.json'}, {final / params_out.name}" + (f", {len(plots)} plots" if plots else ""))
    print(lines[-1])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
