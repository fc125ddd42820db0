"""The residual analysis' input: rig data from a ``worm_rig_data`` CSV file or a rosbag2 bag.

Read through :func:`worm_model.rig_data.read_rig_data` (CSV or bag); this module only asks for
what the analysis needs beyond the schema (at least 2 samples).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from worm_model.rig_data.epos import EposSettings
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData
from worm_model.errors import RigDataError

#: the analysis takes derivatives and sample periods: fewer samples is no data set
MIN_ROWS = 2


def load_data(path: str | Path, rig: Any = None, epos: EposSettings | None = None) -> MeasuredData:
    """Measured data from a CSV file, a rosbag2 directory / .mcap / .db3 file, or EPOS Studio exports
    (``epos``: the load they do not carry, from the tool's options), checked against ``rig`` (default: the
    bundled rig) as every reader of rig data checks it.

    Raises:
        RigDataError: bad file (see :func:`worm_model.rig_data.reader.read_rig_data`), or
            fewer than :data:`MIN_ROWS` samples.
    """
    data = read_rig_data(path, rig=rig, epos=epos)
    if len(data) < MIN_ROWS:
        raise RigDataError(data.source, f"{len(data)} sample(s); the residual analysis needs at least {MIN_ROWS}")
    return data
