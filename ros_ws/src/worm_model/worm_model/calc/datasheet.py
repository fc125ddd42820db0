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
those leaves gets ``source:`` the text of ``--source`` with what was computed from what. Every
other leaf (friction, the drags, the gear side's inertias, the sensors, the load side) is the
base rig file's value (``--base``, default the bundled NMRV030 rig), marked ``assumption:`` with
that file's own source or assumption quoted: not this drive's number, to be identified
(``identify`` refits the assumptions it can tell apart from data) or replaced by a measured one
(edit the leaf, give it a source). The back-EMF constant is K_t (SI, an ideal PMDC motor).

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

from worm_model.cli.errors import InputError, run_tool
from worm_model.cli.options import Parser, existing_file, integer, number
from worm_model.files.reading import load_yaml
from worm_model.files.writing import check_output, write_text_atomically
from worm_model.physics.parameters import ParameterError, default_rig_path, load_rig

PROG = "rig_from_datasheet"


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


def rig_document(base: Mapping[str, Any], base_name: str, args: Any) -> dict[str, Any]:
    """The rig file's document: the base's leaves as assumptions, the datasheet's with their source."""
    doc = copy.deepcopy(dict(base))
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
    return doc


def build_parser() -> Parser:
    p = Parser(prog=PROG, description=__doc__.split("\n\n")[0], epilog="\n\n".join(__doc__.split("\n\n")[1:]),
               formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True, help="rig file to write (YAML, worm_rig_parameters)")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")
    p.add_argument("--base", type=existing_file, default=None,
                   help="rig file whose values stand in for what the datasheet does not give, each marked "
                        "assumption: (default: the bundled NMRV030 rig)")
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
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool(PROG, lambda: _main(argv), (ParameterError,))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    out = check_output(args.out, args.force)
    if (args.centre_distance_mm is None) == (args.worm_diameter_mm is None):
        raise InputError("--centre-distance-mm / --worm-diameter-mm", "give one of them")
    base_path = args.base or default_rig_path()
    base = load_yaml(base_path, "rig parameter file")
    try:
        document = rig_document(base, Path(base_path).name, args)
    except ValueError as err:
        raise InputError("--ratio / --starts / geometry", str(err)) from None
    text = (f"# {args.name}: written by {PROG} from {args.source}.\n# Leaves with source: are this drive's "
            f"datasheet values; those with assumption: stand in from {Path(base_path).name} until identified "
            "or measured.\n" + yaml.safe_dump(document, sort_keys=False, allow_unicode=True, width=120))
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
