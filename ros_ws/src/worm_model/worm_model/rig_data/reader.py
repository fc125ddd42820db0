"""The one reader of rig data: a ``worm_rig_data`` CSV file, a rosbag2 bag, or EPOS Studio exports.

Every tool that takes measured rig data (``residuals``, ``identify --from``, ``estimate``,
``replay``'s CSV mode, tests) reads it here, so a bag and its CSV export give the same
:class:`~worm_model.rig_data.schema.MeasuredData`, checked alike against the rig it comes from
(:mod:`~worm_model.rig_data.plausibility`: sample rate, units, angle). Which reader is chosen by the
path: a ``.mcap``/``.db3`` file or a folder with a bag is a bag; a file that starts like an EPOS
Studio export (``Date:;...``), or a folder of them, is read by :mod:`~worm_model.rig_data.epos` with
the :class:`~worm_model.rig_data.epos.EposSettings` the caller gives (the load, what 100 % torque is);
any other file is a ``worm_rig_data`` CSV.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from worm_model.errors import BagRecordingError, InputError, RigDataError
from worm_model.files.reading import check_input
from worm_model.physics.parameters import load_rig
from worm_model.physics.envelope import Envelope
from worm_model.rig_data.plausibility import check_rig_data, envelope_problem
from worm_model.rig_data.bags import bag_to_measured
from worm_model.rig_data.epos import EposSettings, is_epos_export, is_epos_folder, read_epos_data
from worm_model.rig_data.schema import MeasuredData, read_rig_csv

#: file suffixes read as a bag (besides a directory)
BAG_SUFFIXES = (".mcap", ".db3")


def is_bag(path: str | Path) -> bool:
    """True for a bag directory or a single ``.mcap`` / ``.db3`` storage file."""
    p = Path(path)
    return p.is_dir() or p.suffix in BAG_SUFFIXES


def read_rig_data(path: str | Path, topic: str | None = None, rig: Any = None, *, check: bool = True,
                  epos: EposSettings | None = None) -> MeasuredData:
    """Measured data from a CSV file, a rosbag2 directory / .mcap / .db3 file, or EPOS Studio exports, checked
    against the rig.

    Args:
        topic: the RigSample topic of a bag (default: the only one, or ``/rig/sample``).
        rig: the rig the data comes from (worm_model.physics.parameters.Rig; default: the bundled rig):
            the sample rate, the channels' magnitudes and the angle against the speed are checked against
            it (worm_model.rig_data.plausibility.check_rig_data). EPOS exports are averages at the
            recorder's own period with no angle, so only their magnitudes are checked.
        check: False reads the file as it is (for tools that only convert or show it).
        epos: what an EPOS export does not carry (its load, what 100 % torque is) and whether to
            skip dirty rows; without it an EPOS export is still read (a bad one refused) and then
            refused for want of the load.

    Raises:
        RigDataError: no such file, not a regular file or folder (a FIFO is refused, never opened), a bad
            CSV (see :func:`~worm_model.rig_data.schema.read_rig_csv`), a bag that cannot be read, a bad
            EPOS export or a dirty row in one (:func:`~worm_model.rig_data.epos.read_epos`), or data whose
            units do not fit the rig; the message names the file.
    """
    p = Path(path)
    try:
        check_input(p, "worm_rig_data CSV file or bag", folder=True)
    except InputError as err:
        raise RigDataError(str(p), err.what) from None
    if is_epos_export(p) or is_epos_folder(p):
        data = read_epos_data(p, epos)
        if check:
            error = envelope_problem(data, Envelope.of(rig if rig is not None else load_rig()))
            if error is not None:
                raise error
        return data
    if not is_bag(p):
        data = read_rig_csv(p)
    else:
        try:
            data = bag_to_measured(p, topic)
        except RigDataError:
            raise  # already names the bag and topic
        except (ValueError, OSError, BagRecordingError) as err:
            raise RigDataError(str(p), f"cannot read the bag: {err}") from err
    if check:
        check_rig_data(data, rig if rig is not None else load_rig())
    return data
