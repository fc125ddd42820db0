"""The one reader of rig data: a ``worm_rig_data`` CSV file or a rosbag2 bag, chosen by the path.

Every tool that takes measured rig data (``residuals``, ``identify --from``,
``estimate``, tests) reads it here, so a bag and its CSV export give the same
:class:`~worm_model.rig_data.schema.MeasuredData`, checked alike against the rig it
comes from (:mod:`~worm_model.rig_data.plausibility`: sample rate, units, angle).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from worm_model.bags.typestore import BagRecordingError
from worm_model.cli.errors import InputError
from worm_model.files.reading import check_input
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.plausibility import check_rig_data
from worm_model.rig_data.bags import bag_to_measured
from worm_model.rig_data.schema import MeasuredData, RigDataError, read_rig_csv

#: file suffixes read as a bag (besides a directory)
BAG_SUFFIXES = (".mcap", ".db3")


def is_bag(path: str | Path) -> bool:
    """True for a bag directory or a single ``.mcap`` / ``.db3`` storage file."""
    p = Path(path)
    return p.is_dir() or p.suffix in BAG_SUFFIXES


def read_rig_data(path: str | Path, topic: str | None = None, rig: Any = None, *, check: bool = True) -> MeasuredData:
    """Measured data from a CSV file, or from a rosbag2 directory / .mcap / .db3 file, checked against the rig.

    Args:
        topic: the RigSample topic of a bag (default: the only one, or ``/rig/sample``).
        rig: the rig the data comes from (worm_model.physics.parameters.Rig; default: the bundled rig):
            the sample rate, the channels' magnitudes and the angle against the speed are checked against
            it (worm_model.rig_data.plausibility.check_rig_data).
        check: False reads the file as it is (for tools that only convert or show it).

    Raises:
        RigDataError: no such file, not a regular file or folder (a FIFO is refused, never opened), a bad
            CSV (see :func:`~worm_model.rig_data.schema.read_rig_csv`), a bag that cannot be read, or data
            whose units do not fit the rig; the message names the file.
    """
    p = Path(path)
    try:
        check_input(p, "worm_rig_data CSV file or bag", folder=True)
    except InputError as err:
        raise RigDataError(str(p), err.what) from None
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
