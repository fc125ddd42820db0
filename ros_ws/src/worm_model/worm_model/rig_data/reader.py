"""The one reader of rig data: a ``worm_rig_data`` CSV file or a rosbag2 bag, chosen by the path.

Every tool that takes measured rig data (``residuals``, ``replay``'s CSV mode,
tests) reads it here, so a bag and its CSV export give the same
:class:`~worm_model.rig_data.schema.MeasuredData`.
"""
from __future__ import annotations

from pathlib import Path

from worm_model.bags.typestore import BagRecordingError
from worm_model.rig_data.bags import bag_to_measured
from worm_model.rig_data.schema import MeasuredData, RigDataError, read_rig_csv

#: file suffixes read as a bag (besides a directory)
BAG_SUFFIXES = (".mcap", ".db3")


def is_bag(path: str | Path) -> bool:
    """True for a bag directory or a single ``.mcap`` / ``.db3`` storage file."""
    p = Path(path)
    return p.is_dir() or p.suffix in BAG_SUFFIXES


def read_rig_data(path: str | Path, topic: str | None = None) -> MeasuredData:
    """Measured data from a CSV file, or from a rosbag2 directory / .mcap / .db3 file.

    Args:
        topic: the RigSample topic of a bag (default: the only one, or ``/rig/sample``).

    Raises:
        RigDataError: no such file, a bad CSV (see :func:`~worm_model.rig_data.schema.read_rig_csv`),
            or a bag that cannot be read; the message names the file.
    """
    p = Path(path)
    if not p.exists():
        raise RigDataError(str(p), "no such file or directory")
    if not is_bag(p):
        return read_rig_csv(p)
    try:
        return bag_to_measured(p, topic)
    except RigDataError:
        raise  # already names the bag and topic
    except (ValueError, OSError, BagRecordingError) as err:
        raise RigDataError(str(p), f"cannot read the bag: {err}") from err
