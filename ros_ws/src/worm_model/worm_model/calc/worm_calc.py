"""worm_calc: internal forces or efficiencies of a worm gear set, from the command line.

    ros2 run worm_model worm_calc --tau-in 0.02 --tau-load 0.3 --omega 150
    ros2 run worm_model worm_calc --mu 0.05 --lead-angle-deg 5.71 --json

Thin shell over :mod:`worm_model.calc.calculator`; every number is SI.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

from worm_model.calc.calculator import efficiencies, forces, make_gearbox, to_json_ready
from worm_model.errors import CalculatorError, ParameterError
from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, existing_file, number
from worm_model.physics.parameters import load_rig

#: what the calculator takes: bounds far beyond any worm gear set (the largest make ~1e5 N m), so that a
#: typo or an overflow is refused instead of computed
MAX_RADIUS = 10.0  # [m]
MAX_TORQUE = 1e6  # [N m]
MAX_SPEED = 1e5  # [rad/s]
MAX_ACCELERATION = 1e8  # [rad/s^2]
MAX_INERTIA = 1e4  # [kg m^2]

FORCE_OPTIONS = ("tau_in", "tau_load", "omega", "alpha_worm", "worm_inertia", "gear_inertia", "switching_torque")

#: (key, label, unit) of the text output, in order; keys missing from a result are skipped
TEXT_ROWS = (
    ("worm_pitch_radius", "worm pitch radius r_w", "m"),
    ("gear_pitch_radius", "gear pitch radius r_g", "m"),
    ("lead_angle_deg", "lead angle lambda", "deg"),
    ("normal_pressure_angle_deg", "normal pressure angle phi_n", "deg"),
    ("speed_ratio", "speed ratio i = r_w tan(lambda)/r_g", ""),
    ("tau_in", "input torque tau_in", "N m"),
    ("tau_d", "load torque tau_d", "N m"),
    ("omega_worm", "worm speed", "rad/s"),
    ("alpha_worm", "worm acceleration", "rad/s^2"),
    ("normal_force", "normal force N", "N"),
    ("friction_force", "friction force F_f", "N"),
    ("mu", "friction coefficient mu = F_f/N", ""),
    ("mode", "mode", ""),
    ("flank", "engaged flank", ""),
    ("worm_tangential_force", "worm tangential = gear axial force", "N"),
    ("gear_tangential_force", "gear tangential = worm axial force", "N"),
    ("radial_force", "radial (separating) force", "N"),
    ("sliding_velocity", "sliding velocity v_s", "m/s"),
    ("input_power", "power into the mesh", "W"),
    ("output_power", "power to the gear", "W"),
    ("friction_power", "friction power F_f v_s", "W"),
    ("friction_angle_deg", "friction angle rho' = atan(mu/cos(phi_n))", "deg"),
    ("efficiency_forward", "forward efficiency (worm drives)", ""),
    ("efficiency_backward", "back-driving efficiency (gear drives)", ""),
    ("self_locking", "self-locking", ""),
    ("self_locking_mu", "self-locking above mu =", ""),
    ("mu_max", "engagement bound mu_max (Remark 4)", ""),
)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
        prog="worm_calc",
        description="Internal forces (paper Eqs 21-23) of a worm gear set from its torques, or its "
                    "forward/back-driving efficiencies and self-locking from a friction coefficient. "
                    "Give either --tau-in and --tau-load (forces) or --mu (efficiencies). SI units. "
                    "Sign convention: tau_in > 0 drives the worm in + direction; tau_load > 0 opposes it.",
        epilog="Geometry options left out are taken from the rig file (default: the bundled "
               "NMRV030 rig: r_w 7.5 mm, r_g 22.5 mm, lambda 5.71 deg, phi_n 20 deg). The speed ratio "
               "used is the one the geometry implies, i = r_w tan(lambda)/r_g. Exit code 2 on bad input.")
    g = p.add_argument_group("geometry (defaults: the rig file)")
    g.add_argument("--rig", type=existing_file, default=None,
                   help="rig parameter YAML the defaults come from (default: the bundled NMRV030 rig)")
    g.add_argument("--r-worm", type=number("m", 0, MAX_RADIUS, open_low=True, what="worm pitch radius"), default=None,
                   metavar="M", help="worm pitch radius r_w [m], > 0")
    g.add_argument("--r-gear", type=number("m", 0, MAX_RADIUS, open_low=True, what="gear pitch radius"), default=None,
                   metavar="M", help="gear pitch radius r_g [m], > 0")
    g.add_argument("--lead-angle-deg", type=number("deg", 0, 90, open_low=True, open_high=True, what="lead angle"),
                   default=None, metavar="DEG",
                   help="worm lead angle lambda at the pitch radius [deg], in (0, 90)")
    g.add_argument("--pressure-angle-deg", type=number("deg", 0, 90, open_high=True, what="pressure angle"),
                   default=None, metavar="DEG",
                   help="normal pressure angle phi_n [deg], in [0, 90)")
    f = p.add_argument_group("forces from torques (needs --tau-in and --tau-load)")
    f.add_argument("--tau-in", type=number("N m", -MAX_TORQUE, MAX_TORQUE, what="input torque"),
                   default=None, metavar="NM",
                   help="torque on the worm shaft [N m], + drives + worm rotation")
    f.add_argument("--tau-load", type=number("N m", -MAX_TORQUE, MAX_TORQUE, what="load torque"),
                   default=None, metavar="NM",
                   help="load torque on the gear shaft [N m], + opposes the motion that + worm rotation drives")
    f.add_argument("--omega", type=number("rad/s", -MAX_SPEED, MAX_SPEED, what="worm speed"),
                   default=None, metavar="RAD_S",
                   help="worm speed [rad/s]; its sign is the direction of motion and its size gives the "
                        "sliding velocity and powers (default: direction of --tau-in, no powers); 0 = standstill")
    f.add_argument("--alpha-worm", type=number("rad/s^2", -MAX_ACCELERATION, MAX_ACCELERATION,
                                                      what="worm acceleration"), default=None, metavar="RAD_S2",
                   help="worm angular acceleration [rad/s^2] (default 0, quasi-static); the gear's is i times it")
    f.add_argument("--worm-inertia", type=number("kg m^2", 0, MAX_INERTIA, what="worm inertia"),
                   default=None, metavar="KGM2",
                   help="inertia on the worm side of the measured tau_in [kg m^2] (default: the rig's worm shaft)")
    f.add_argument("--gear-inertia", type=number("kg m^2", 0, MAX_INERTIA, what="gear inertia"),
                   default=None, metavar="KGM2",
                   help="inertia on the gear side of the measured tau_load [kg m^2] (default: the rig's gear shaft)")
    f.add_argument("--switching-torque", type=number("N m", 0, MAX_TORQUE, what="switching torque"),
                   default=None, metavar="NM",
                   help="switching torque tau_sw >= 0 [N m] for the mode (pseudo-resistive band); default 0")
    e = p.add_argument_group("efficiencies from a friction coefficient")
    e.add_argument("--mu", type=number("", 0, what="mu"), default=None,
                   help="tooth-thread friction coefficient, >= 0 and below the Remark-4 bound "
                        "mu_max = cos(phi_n) cot(lambda) of the geometry")
    p.add_argument("--json", action="store_true", help="print one JSON object (snake_case keys, SI) instead of text")
    return p


def _format(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.6g}"
    return str(value)


def render_text(result: dict[str, Any]) -> str:
    rows = [(label, result[key], unit) for key, label, unit in TEXT_ROWS if result.get(key) is not None]
    width = max(len(label) for label, _, _ in rows)
    return "\n".join(f"{label:<{width}}  {_format(value)}{' ' + unit if unit else ''}" for label, value, unit in rows)


def main(argv: list[str] | None = None) -> int:
    return run_tool("worm_calc", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    given = [name for name in FORCE_OPTIONS if getattr(args, name) is not None]
    if args.mu is not None and given:
        parser.error("--mu (efficiencies) cannot be combined with "
                     + ", ".join("--" + n.replace("_", "-") for n in given) + " (forces); give one or the other")
    if args.mu is None and (args.tau_in is None or args.tau_load is None):
        missing = [f"--{n.replace('_', '-')}" for n in ("tau_in", "tau_load") if getattr(args, n) is None]
        parser.error("give --tau-in and --tau-load (forces) or --mu (efficiencies); missing " + " and ".join(missing))
    try:
        rig = load_rig(args.rig)
        base = rig.gearbox
        gearbox = make_gearbox(
            base,
            base.worm_pitch_radius if args.r_worm is None else args.r_worm,
            base.gear_pitch_radius if args.r_gear is None else args.r_gear,
            base.lead_angle if args.lead_angle_deg is None else math.radians(args.lead_angle_deg),
            base.normal_pressure_angle if args.pressure_angle_deg is None else math.radians(args.pressure_angle_deg),
            args.worm_inertia, args.gear_inertia,
        )
        if args.mu is not None:
            result = efficiencies(gearbox, args.mu)
        else:
            result = forces(gearbox, args.tau_in, args.tau_load, args.omega,
                            0.0 if args.alpha_worm is None else args.alpha_worm,
                            0.0 if args.switching_torque is None else args.switching_torque)
    except CalculatorError as err:
        parser.error(str(err))
    except ParameterError as err:
        print(f"worm_calc: --rig {err}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(to_json_ready(result), allow_nan=False))
    else:
        print(render_text(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
