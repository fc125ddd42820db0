"""The command-line options of every tool that reads EPOS Studio exports: the load they do not carry.

A tool adds them with :func:`add_epos_arguments` and turns them into the reader's
:class:`~worm_model.rig_data.epos.EposSettings` with :func:`epos_settings`, which takes what
100 % torque is (the nominal current) and the encoder's counts per turn from the rig file.
For a CSV file or a bag the options are not read.
"""
from __future__ import annotations

import argparse

from worm_model.errors import InputError
from worm_model.cli.options import number
from worm_model.physics.parameters import Rig
from worm_model.rig_data.epos import STANDARD_GRAVITY, EposSettings, hanging_load


def add_epos_arguments(parser: argparse.ArgumentParser) -> None:
    """The options (module docstring), in a group of their own."""
    group = parser.add_argument_group(
        "EPOS Studio exports (a file or a folder of them: the export carries no load, so give it)")
    group.add_argument("--load-torque", type=number("N m", -1e3, 1e3), default=None,
                       help="the load on the gear (output) shaft [N m], + where it opposes the export's + velocity")
    group.add_argument("--load-mass", type=number("kg", 0.0, 1e4, open_low=True), default=None,
                       help="a mass hanging from a pulley on the output [kg] (with --pulley-radius): m g r")
    group.add_argument("--pulley-radius", type=number("m", 0.0, 10.0, open_low=True), default=None,
                       help="the radius of that pulley [m]")
    group.add_argument("--lifting", choices=("positive", "negative"), default="positive",
                       help="which sign of the export's velocity lifts the hanging mass (the load opposes it)")
    group.add_argument("--gravity", type=number("m/s^2", 0.0, 100.0, open_low=True), default=STANDARD_GRAVITY,
                       help="the local gravity for --load-mass [m/s^2]")
    group.add_argument("--skip-bad-rows", action="store_true",
                       help="leave out dirty rows (a stray note, a trailing separator, a spike) and list them with "
                            "their count, instead of refusing the file")


def epos_settings(args: argparse.Namespace, rig: Rig) -> EposSettings:
    """The reader's settings from the options and the rig file (drive_motor.rated_current is 100 % torque).

    Raises:
        InputError: both a torque and a mass, or a mass without its pulley radius (or the reverse).
    """
    load = args.load_torque
    if args.load_mass is not None or args.pulley_radius is not None:
        if load is not None:
            raise InputError("--load-torque", "give the load as a torque or as --load-mass with --pulley-radius, "
                                              "not both")
        if args.load_mass is None or args.pulley_radius is None:
            missing = "--pulley-radius" if args.load_mass is not None else "--load-mass"
            raise InputError(missing, "a hanging load needs both --load-mass and --pulley-radius")
        load = hanging_load(args.load_mass, args.pulley_radius, args.gravity)
        load = load if args.lifting == "positive" else -load
    sensors = rig.sensors
    return EposSettings(load_torque=load, nominal_current=rig.drive_motor.rated_current,
                        counts_per_turn=float(sensors.encoder_pulses_per_rev * sensors.encoder_decoding),
                        skip_bad_rows=bool(args.skip_bad_rows))
