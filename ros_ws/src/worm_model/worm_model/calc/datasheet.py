"""rig_from_datasheet: a rig file for your worm drive from its gear catalogue and motor datasheet.

    ros2 run worm_model rig_from_datasheet --out my_rig.yaml --name "my drive" --source "catalogue p. 12" \\
        --ratio 40 --centre-distance-mm 40 --lead-angle-deg 4.09 --pressure-angle-deg 20 \\
        --torque-constant 0.0302 --resistance 1.06 --rotor-inertia-gcm2 33.5

The catalogue gives the gear set: the reduction i' = Z_g / n (``--ratio``; n = ``--starts``,
1 by default), the centre distance a (or the worm's pitch diameter d_w), the lead angle lambda
and the normal pressure angle phi_n. The geometry follows from the model's own relations
(physics.md §1): the speed ratio i = n / Z_g = r_w tan(lambda) / r_g, and a = r_w + r_g, so

    r_g = a / (1 + i / tan(lambda)),  r_w = a - r_g        (from the centre distance), or
    r_w = d_w / 2,                    r_g = r_w tan(lambda) / i   (from the worm's diameter).

The motor's datasheet gives K_t [N m/A], the terminal resistance R [ohm] and the rotor inertia
[g cm^2] (and, where it has them, the inductance, the rated current and voltage). Every one of
those leaves gets ``source:`` the text of ``--source`` with what was computed from what. The back-EMF
constant is K_t (SI, an ideal PMDC motor).

What a datasheet does not give is a stand-in, marked ``assumption:`` with its rule. By default
(no ``--base``) the drive is one on a robot (the bundled ``drive_template.yaml``): nothing on the output
but the load and the output shaft's supports, the motor's current and an encoder as its sensors, and
every stand-in scaled to this drive: the motor's drags a typical brushed motor's (5 % of its rated
torque), the output supports' 0.5 % of the rated output torque, the worm's inertia a steel worm's of its
pitch diameter, the output's inertia (``--output-inertia-gcm2`` when you know it) a bronze gear disc's
until ``identify`` fits it, a constant mu, the sensors' noise placeholders that ``identify`` measures on
the recording, the encoder's counts and the sample rate (``--encoder-counts``, ``--sample-rate-hz``), and
the estimators' load scale the rated output torque K_t x rated current / i. ``--base FILE`` takes every
other leaf from that rig file instead, each marked ``assumption:`` with that file's own citation quoted
(a test bench with load motors: the bundled NMRV030 rig).

The result is loaded and checked (worm_model.physics.parameters.load_rig: units, ranges, the
geometry's consistency) before it is written; a check that fails is one line naming the field,
exit 2, nothing written. An existing --out is kept unless --force. No ROS.
"""
from __future__ import annotations

import copy
import math
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from worm_model.cli.errors import run_tool
from worm_model.errors import InputError
from worm_model.cli.options import Parser, existing_file, integer, number
from worm_model.files.reading import load_yaml
from worm_model.files.writing import Output, check_output, write_text_atomically
from worm_model.physics.parameters import load_rig

PROG = "rig_from_datasheet"
def _is_ours(path: Path) -> bool:
    """``path`` is a rig file this tool wrote (its first line says so)."""
    with path.open(encoding="utf-8", errors="replace") as handle:
        return f"written by {PROG} from" in handle.readline()


#: what rig_from_datasheet writes; --force replaces only its own earlier output (worm_model.files.writing)
OUTPUT = Output(PROG, recognise=_is_ours)
#: densities [kg/m^3] of the stand-in worm (steel) and gear (bronze)
STEEL, BRONZE = 7850.0, 8800.0
#: a typical brushed motor's Coulomb drag, as a share of its rated torque (a no-load current of 3-10 %)
DRAG_SHARE = 0.05
#: the output shaft's supports' drag, as a share of the rated output torque
SUPPORT_SHARE = 0.005


def gear_geometry(ratio: float, starts: int, lead_angle_deg: float, centre_distance_mm: float | None = None,
                  worm_diameter_mm: float | None = None) -> dict[str, float]:
    """Pitch radii [mm] of a worm gear set from its catalogue data (module docstring).

    Args:
        ratio: the reduction i' = Z_g / n (> 1); starts: n; lead_angle_deg: lambda;
        centre_distance_mm: a; or worm_diameter_mm: d_w (exactly one of the two).

    Returns:
        worm_pitch_radius, gear_pitch_radius [mm] and gear_teeth (n i', rounded: a catalogue ratio is a
        whole number of teeth per start).

    Raises:
        ValueError: both or neither of a and d_w, a ratio that gives no whole tooth count, or a geometry
            with no positive radii.
    """
    if (centre_distance_mm is None) == (worm_diameter_mm is None):
        raise ValueError("give the centre distance or the worm's pitch diameter (one of them)")
    teeth = ratio * starts
    if abs(teeth - round(teeth)) > 1e-6:
        raise ValueError(f"ratio {ratio:g} with {starts} start(s) gives {teeth:g} teeth, not a whole number")
    i = starts / round(teeth)
    tan_lead = math.tan(math.radians(lead_angle_deg))
    if centre_distance_mm is not None:
        r_g = centre_distance_mm / (1.0 + i / tan_lead)
        r_w = centre_distance_mm - r_g
    else:
        r_w = worm_diameter_mm / 2.0
        r_g = r_w * tan_lead / i
    if not (r_w > 0 and r_g > 0):
        raise ValueError(f"no positive pitch radii from these values (r_w {r_w:g} mm, r_g {r_g:g} mm)")
    return {"worm_pitch_radius": r_w, "gear_pitch_radius": r_g, "gear_teeth": round(teeth)}


def _leaf(value: Any, unit: str, source: str) -> dict[str, Any]:
    return {"value": value, "unit": unit, "source": source}


def _borrowed(leaf: Mapping[str, Any], base: str) -> dict[str, Any]:
    """A base file's leaf as an assumption of this drive, its own citation quoted."""
    why = leaf.get("source") or leaf.get("assumption") or ""
    if "source" in leaf:
        why = f"source there: {why}"
    return {"value": leaf["value"], "unit": leaf["unit"],
            "assumption": f"not from this drive's datasheet: the value of {base} ({why})"}


def template_path() -> Path:
    """The bundled template of a drive on a robot (module docstring)."""
    return Path(__file__).resolve().parent.parent / "data" / "drive_template.yaml"


#: a rig file's analogue channels are 10-bit, zero at mid-scale (worm_rig_driver.sim.sensors): +-512 steps
ADC_HALF_SCALE = 512


def _stand_in(value: float, unit: str, rule: str) -> dict[str, Any]:
    return {"value": float(f"{value:.6g}"), "unit": unit, "assumption": rule}


def scaled_stand_ins(doc: dict[str, Any], geometry: Mapping[str, float], args: Any) -> None:
    """The template's stand-ins scaled to this drive (module docstring), each with its rule; SI in, the
    template's units out."""
    r_w, r_g = geometry["worm_pitch_radius"] * 1e-3, geometry["gear_pitch_radius"] * 1e-3
    kt = args.torque_constant
    rated = args.rated_current if args.rated_current is not None else doc["drive_motor"]["rated_current"]["value"]
    volts = args.max_voltage if args.max_voltage is not None else doc["drive_motor"]["max_voltage"]["value"]
    ratio = args.ratio  # Z_g / n: the output turns this many times slower and carries as many times the torque
    motor_torque = kt * rated
    output_torque = motor_torque * ratio
    gear = doc["gearbox"]
    gear["worm_inertia"] = _stand_in(0.5 * math.pi * STEEL * 6.0 * r_w * r_w ** 4 * 1e7, "g cm^2",
                                     "a steel worm (7850 kg/m^3) of the pitch diameter, three diameters long: "
                                     "(pi/2) rho L r_w^4")
    if args.output_inertia_gcm2 is not None:
        gear["gear_inertia"] = _leaf(args.output_inertia_gcm2, "g cm^2", f"{args.source}: the output's inertia "
                                     "(gear, output shaft and the load's rigid mass)")
    else:
        width = 2.0 / 3.0 * r_g
        gear["gear_inertia"] = _stand_in(0.5 * math.pi * BRONZE * width * r_g ** 4 * 1e7, "g cm^2",
                                         "unknown: the output's inertia is not in a catalogue; a bronze disc "
                                         "(8800 kg/m^3) of the pitch diameter, 2/3 of its radius wide, stands in "
                                         "until identify fits it from the recording's accelerations")
    motor = doc["drive_motor"]
    motor["coulomb_drag"] = _stand_in(DRAG_SHARE * motor_torque * 1e3, "mN m",
                                      "a typical brushed motor's: 5 % of its rated torque (a no-load current of "
                                      "3-10 % of the rated one); identify fits it")
    motor["viscous_drag"] = _stand_in(DRAG_SHARE * motor_torque * kt / volts, "N m s/rad",
                                      "a typical brushed motor's: its Coulomb drag again at its no-load speed; "
                                      "identify fits it")
    load = doc["load_motor"]
    load["coulomb_drag"] = _stand_in(SUPPORT_SHARE * output_torque * 1e3, "mN m",
                                     "the output shaft's supports (bearings, seal): 0.5 % of the rated output "
                                     "torque; identify fits it")
    load["rated_current"] = _stand_in(output_torque, "A",
                                      f"placeholder: the rated output torque K_t x rated current x {ratio:g} [N m] "
                                      "at 1 N m/A (the estimators' load scale)")
    load["max_voltage"] = _stand_in(volts, "V", "placeholder: no load motor")
    doc["supply_voltage"] = _leaf(volts, "V", f"{args.source}: the motor's nominal voltage")
    sensors = doc["sensors"]
    sensors["current_noise_std"] = _stand_in(0.01 * rated, "A", "unknown until measured: 1 % of the rated "
                                             "current stands in; identify measures it on the recording")
    stall = volts / args.resistance
    sensors["current_lsb"] = _stand_in(max(0.001 * rated, stall / ADC_HALF_SCALE), "A",
                                       "unknown until measured: 0.1 % of the rated current, or the stall current "
                                       f"over {ADC_HALF_SCALE} where more (a 10-bit channel's half scale spans it), "
                                       "stands in; identify measures it on the recording")
    counts = (args.encoder_counts if args.encoder_counts is not None else
              sensors["encoder_pulses_per_rev"]["value"] * sensors["encoder_decoding"]["value"])
    rate = args.sample_rate_hz if args.sample_rate_hz is not None else sensors["sample_rate_hz"]["value"]
    speed_step = 2.0 * math.pi * rate / counts
    sensors["tacho_drive_lsb"] = _stand_in(speed_step, "rad/s",
                                           "no tacho: the speed is the encoder's count difference a sample, in steps "
                                           "of 2 pi x rate / counts; identify measures it on the recording")
    sensors["tacho_load_lsb"] = _stand_in(speed_step / ratio, "rad/s",
                                          "no load tacho: the worm's speed step through the ratio")
    if args.encoder_counts is not None:
        sensors["encoder_pulses_per_rev"] = _leaf(args.encoder_counts, "1", f"{args.source}: encoder counts a turn "
                                                  "(after decoding)")
        sensors["encoder_decoding"] = _leaf(1, "1", f"{args.source}: the counts a turn given after decoding")
    if args.sample_rate_hz is not None:
        sensors["sample_rate_hz"] = _leaf(args.sample_rate_hz, "Hz", f"{args.source}: the controller's sample rate")


def rig_document(base: Mapping[str, Any], base_name: str, args: Any, template: bool = False) -> dict[str, Any]:
    """The rig file's document: the datasheet's leaves with their source; the rest the template's stand-ins scaled
    to the drive (``template``), or the base's leaves as assumptions quoting the base's citation."""
    doc = copy.deepcopy(dict(base))
    if not template:
        for section, body in doc.items():
            if isinstance(body, dict) and "value" in body:
                doc[section] = _borrowed(body, base_name)
            elif isinstance(body, dict):
                for key, leaf in body.items():
                    if isinstance(leaf, dict) and "value" in leaf:
                        body[key] = _borrowed(leaf, base_name)
    doc.pop("free", None)
    doc["name"] = args.name
    where = "centre distance a = %g mm" % args.centre_distance_mm if args.centre_distance_mm is not None \
        else "worm pitch diameter d_w = %g mm" % args.worm_diameter_mm
    geometry = gear_geometry(args.ratio, args.starts, args.lead_angle_deg, args.centre_distance_mm,
                             args.worm_diameter_mm)
    given = f"{args.source}: ratio {args.ratio:g}, {args.starts} start(s), {where}, lead angle " \
            f"{args.lead_angle_deg:g} deg"
    formula = ("r_g = a / (1 + i / tan(lambda))" if args.centre_distance_mm is not None
               else "r_g = r_w tan(lambda) / i")
    gear = doc["gearbox"]
    gear["worm_starts"] = _leaf(args.starts, "1", f"{args.source}: {args.starts} start(s)")
    gear["gear_teeth"] = _leaf(geometry["gear_teeth"], "1", f"{given}: Z_g = n x ratio")
    gear["worm_pitch_radius"] = _leaf(round(geometry["worm_pitch_radius"], 6), "mm",
                                      f"{given}: " + ("r_w = a - r_g" if args.centre_distance_mm is not None
                                                      else "r_w = d_w / 2"))
    gear["gear_pitch_radius"] = _leaf(round(geometry["gear_pitch_radius"], 6), "mm", f"{given}: {formula}, "
                                      "i = n / Z_g (physics.md section 1)")
    gear["lead_angle"] = _leaf(args.lead_angle_deg, "deg", f"{args.source}: lead angle")
    gear["normal_pressure_angle"] = _leaf(args.pressure_angle_deg, "deg", f"{args.source}: normal pressure angle")
    gear["hand"] = _leaf(1 if args.hand == "right" else -1, "1", f"{args.source}: {args.hand}-hand worm")
    motor = doc["drive_motor"]
    motor["torque_constant"] = _leaf(args.torque_constant, "N m/A", f"{args.source}: torque constant")
    motor["back_emf_constant"] = _leaf(args.torque_constant, "V s/rad",
                                       f"{args.source}: torque constant (K_e = K_t in SI, an ideal PMDC motor)")
    motor["resistance"] = _leaf(args.resistance, "ohm", f"{args.source}: terminal resistance")
    motor["rotor_inertia"] = _leaf(args.rotor_inertia_gcm2, "g cm^2", f"{args.source}: rotor inertia")
    for name, unit, value in (("inductance", "mH", args.inductance_mh), ("rated_current", "A", args.rated_current),
                              ("max_voltage", "V", args.max_voltage)):
        if value is not None:
            motor[name] = _leaf(value, unit, f"{args.source}: {name.replace('_', ' ')}")
    if template:
        scaled_stand_ins(doc, geometry, args)
    elif any(v is not None for v in (args.output_inertia_gcm2, args.encoder_counts, args.sample_rate_hz)):
        raise ValueError("--output-inertia-gcm2, --encoder-counts and --sample-rate-hz apply to a drive on a robot "
                         "(no --base); edit those leaves of the base's copy instead")
    return doc


def build_parser() -> Parser:
    p = Parser(prog=PROG, description=__doc__.split("\n\n")[0], epilog="\n\n".join(__doc__.split("\n\n")[1:]),
               formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True, help="rig file to write (YAML, worm_rig_parameters)")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")
    p.add_argument("--base", type=existing_file, default=None,
                   help="rig file whose values stand in for what the datasheet does not give, each marked "
                        "assumption: (e.g. a test bench's with load motors: package://worm_model/"
                        "data/nmrv030_rig.yaml); default: a drive on a robot, the stand-ins scaled to this drive "
                        "(the bundled drive_template.yaml)")
    p.add_argument("--name", required=True, help="the drive's name in the file")
    p.add_argument("--source", required=True,
                   help="where the datasheet values come from (catalogue, page, motor datasheet): each such leaf's "
                        "source:")
    gear = p.add_argument_group("gear catalogue")
    gear.add_argument("--ratio", type=number("", 1.0, 1000.0), required=True, help="reduction Z_g / n (e.g. 30)")
    gear.add_argument("--starts", type=integer(1, 8), default=1, help="worm starts n (default 1)")
    gear.add_argument("--centre-distance-mm", type=number("mm", 0.0, 2000.0, open_low=True), default=None,
                      help="centre distance a [mm] (or --worm-diameter-mm)")
    gear.add_argument("--worm-diameter-mm", type=number("mm", 0.0, 2000.0, open_low=True), default=None,
                      help="worm pitch diameter d_w [mm] (or --centre-distance-mm)")
    gear.add_argument("--lead-angle-deg", type=number("deg", 0.0, 45.0, open_low=True), required=True,
                      help="lead angle lambda at the worm's pitch diameter [deg]")
    gear.add_argument("--pressure-angle-deg", type=number("deg", 0.0, 45.0, open_low=True), required=True,
                      help="normal pressure angle phi_n [deg]")
    gear.add_argument("--hand", choices=("right", "left"), default="right", help="worm hand (default right)")
    motor = p.add_argument_group("motor datasheet")
    motor.add_argument("--torque-constant", type=number("N m/A", 0.0, 100.0, open_low=True), required=True,
                       help="torque constant K_t [N m/A] (the back-EMF constant in SI)")
    motor.add_argument("--resistance", type=number("ohm", 0.0, 1000.0, open_low=True), required=True,
                       help="terminal resistance R [ohm]")
    motor.add_argument("--rotor-inertia-gcm2", type=number("g cm^2", 0.0, 1e7, open_low=True), required=True,
                       help="rotor inertia [g cm^2]")
    motor.add_argument("--inductance-mh", type=number("mH", 0.0, 1000.0, open_low=True), default=None,
                       help="terminal inductance [mH] (default: the base file's)")
    motor.add_argument("--rated-current", type=number("A", 0.0, 1000.0, open_low=True), default=None,
                       help="continuous current [A] (default: the base file's)")
    motor.add_argument("--max-voltage", type=number("V", 0.0, 1000.0, open_low=True), default=None,
                       help="nominal voltage [V] (default: the base file's)")
    drive = p.add_argument_group("the drive on its robot (what neither sheet gives; without --base)")
    drive.add_argument("--output-inertia-gcm2", type=number("g cm^2", 0.0, 1e9, open_low=True), default=None,
                       help="the output's inertia [g cm^2]: gear, output shaft and the load's rigid mass (default: "
                            "unknown, a gear disc stands in and identify fits it)")
    drive.add_argument("--encoder-counts", type=integer(4, 10_000_000), default=None,
                       help="the encoder's counts per motor turn after decoding (default: 2000, identify reads it "
                            "off the recorded angle)")
    drive.add_argument("--sample-rate-hz", type=number("Hz", 1.0, 1e6), default=None,
                       help="the drive controller's sample rate [Hz] (default 1000)")
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool(PROG, lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    out = check_output(args.out, args.force, inputs=[args.base], output=OUTPUT)
    if (args.centre_distance_mm is None) == (args.worm_diameter_mm is None):
        raise InputError("--centre-distance-mm / --worm-diameter-mm", "give one of them")
    base_path = args.base or template_path()
    base = load_yaml(base_path, "rig parameter file")
    try:
        document = rig_document(base, Path(base_path).name, args, template=args.base is None)
    except ValueError as err:
        where = "--base" if "apply to a drive" in str(err) else "--ratio / --starts / geometry"
        raise InputError(where, str(err)) from None
    stand_ins = (f"stand in from {Path(base_path).name}" if args.base is not None
                 else "are stand-ins scaled to this drive (their rule says how)")
    text = (f"# {args.name}: written by {PROG} from {args.source}.\n# Leaves with source: are this drive's "
            f"datasheet values; those with assumption: {stand_ins} until identified or measured.\n"
            + yaml.safe_dump(document, sort_keys=False, allow_unicode=True, width=120))
    with tempfile.TemporaryDirectory() as folder:  # checked as the loader reads it, before anything is written
        trial = Path(folder) / out.name
        trial.write_text(text, encoding="utf-8")
        rig = load_rig(trial)
    write_text_atomically(out, text)
    gb = rig.gearbox
    print(f"{PROG}: {rig.name}: i = {gb.ratio:.6g} (r_w tan(lambda)/r_g = {gb.geometric_ratio:.6g}), r_w "
          f"{gb.worm_pitch_radius * 1e3:.4g} mm, r_g {gb.gear_pitch_radius * 1e3:.4g} mm, K_t "
          f"{rig.drive_motor.torque_constant:g} N m/A -> {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
