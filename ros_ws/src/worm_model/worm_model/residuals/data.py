"""The residual analysis' input: rig data from a ``worm_rig_data`` CSV file or a rosbag2 bag.

The schema, :class:`~worm_model.rig_data.MeasuredData`, the reader and the writer are
worm_model.rig_data; this module only chooses the reader and asks for what the analysis
needs beyond the schema (at least 2 samples).
"""

from __future__ import annotations

from pathlib import Path

from worm_model.rig_data import MeasuredData, RigDataError, read_rig_csv

#: the analysis takes derivatives and sample periods: fewer samples is no data set
MIN_ROWS = 2


def load_data(path: str | Path) -> MeasuredData:
    """Measured data from a CSV file, or from a rosbag2 directory / .mcap / .db3 file.

    Bags are converted with worm_rig_driver's exporter, imported here at run time:
    worm_rig_driver depends on worm_model, so worm_model cannot declare the reverse.

    Raises:
        RigDataError: bad file (see :func:`worm_model.rig_data.read_rig_csv`), a bag
            without the exporter installed, or fewer than :data:`MIN_ROWS` samples.
    """
    p = Path(path)
    if not p.exists():
        raise RigDataError(str(p), "no such file or directory")
    data = _load_bag(p) if p.is_dir() or p.suffix in (".mcap", ".db3") else read_rig_csv(p)
    if len(data) < MIN_ROWS:
        raise RigDataError(data.source, f"{len(data)} sample(s); the residual analysis needs at least {MIN_ROWS}")
    return data


def _load_bag(path: Path) -> MeasuredData:
    try:
        from worm_rig_driver import rig_csv  # type: ignore[import-not-found]
    except ImportError:
        raise RigDataError(str(path), "reading a bag needs worm_rig_driver's bag exporter (worm_rig_driver.rig_csv), "
                                      "which is not installed; export the bag to CSV with `bag export` on a machine "
                                      "that has it, or source a workspace with worm_rig_driver") from None
    from worm_rig_driver.bag_types import BagRecordingError  # type: ignore[import-not-found]

    try:
        return rig_csv.bag_to_measured(path)
    except RigDataError:
        raise  # already names the bag and topic
    except (ValueError, OSError, BagRecordingError) as err:
        raise RigDataError(str(path), f"cannot read the bag: {err}") from err
