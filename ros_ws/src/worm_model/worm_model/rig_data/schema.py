"""Measured rig data: the ``worm_rig_data`` CSV schema, its in-memory form, reader and writer.

The one definition of the schema: the residual analysis (``residuals``) reads it, and
worm_rig_driver's ``bag export``/``bag import`` convert RigSample bags to and from it
(worm_model.rig_data.bags, which imports everything here).

CSV schema ``worm_rig_data`` (one header row, then one row per sample, comma separated)
-------------------------------------------------------------------------------------
Required columns (finite numbers in every row):

==================  =======  ==========================================================
``t``               s        sample time, strictly increasing
``current_drive``   A        drive-motor armature current
``omega_worm``      rad/s    worm (= drive motor) speed, + is the reference rotation
``theta_worm``      rad      worm angle, unwrapped
``tau_load``        N m      known load torque on the gear shaft, + opposes + rotation
==================  =======  ==========================================================

Optional columns (empty cells allowed, read as NaN; a column with no value at all is
read as absent):

==================  =======  ==========================================================
``voltage_drive``   V        mean drive-motor voltage
``theta_gear``      rad      gear angle, unwrapped, + with + worm rotation
``current_load``    A        load-motor current, both load motors summed
``temperature``     degC     oil or housing temperature
==================  =======  ==========================================================

Columns may come in any order; unknown columns are ignored (and listed in
:attr:`MeasuredData.ignored_columns`).  A gap in ``t`` longer than
:data:`RUN_GAP_PERIODS` median sample periods starts a new *run* (a separate
recording): filters restart there and no derivative is taken across it.

:func:`write_rig_csv` writes floats as Python's shortest round-trip ``repr`` (an empty
cell for NaN), so write -> read gives the same numbers bit for bit, and read -> write
the same file.

Every problem raises :class:`RigDataError` whose message names the file, the line
(1 = the header) and the column: ``data.csv: line 17, column 'omega_worm': 'abc'
is not a number``.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Final

import numpy as np

from worm_model.errors import InputError, RigDataError
from worm_model.files.reading import check_input
from worm_model.physics.units import FloatArray

REQUIRED_COLUMNS: Final[dict[str, str]] = {
    "t": "s",
    "current_drive": "A",
    "omega_worm": "rad/s",
    "theta_worm": "rad",
    "tau_load": "N m",
}
"""Required column -> unit, in the order written."""
OPTIONAL_COLUMNS: Final[dict[str, str]] = {
    "voltage_drive": "V",
    "theta_gear": "rad",
    "current_load": "A",
    "temperature": "degC",
}
"""Optional column -> unit, in the order written."""
RUN_GAP_PERIODS: Final[float] = 5.0
"""A time step longer than this many median sample periods starts a new run."""


@dataclass
class MeasuredData:
    """One data set in SI units, arrays of shape (n,); optional channels are None when absent."""

    t: FloatArray
    current_drive: FloatArray
    omega_worm: FloatArray
    theta_worm: FloatArray
    tau_load: FloatArray
    voltage_drive: FloatArray | None = None
    theta_gear: FloatArray | None = None
    current_load: FloatArray | None = None
    temperature: FloatArray | None = None
    source: str = "<memory>"
    ignored_columns: tuple[str, ...] = ()
    """Columns of the file outside the schema (not read)."""
    skipped: dict[str, int] = field(default_factory=dict)
    """Samples left out on conversion (e.g. from a bag), by reason."""
    run: np.ndarray = field(default=None)  # type: ignore[assignment]  # run index per sample (int)
    lines: np.ndarray | None = None
    """Line of the CSV file each sample came from (None for other sources)."""
    damage: tuple[str, ...] = ()
    """Storage files read although truncated (messages lost), and what was lost."""
    notes: tuple[str, ...] = ()
    """What the reader derived or tolerated and the user should know (rows skipped, channels derived)."""
    run_sources: tuple[str, ...] = ()
    """The file each run came from, when the runs are several files (a folder of exports); else empty."""
    current_from_torque: bool = False
    """``current_drive`` is a motor torque the drive reported, divided by K_t (an EPOS export's torque
    channel): K_t x current is what was measured, so nothing in it can tell K_t."""

    def __post_init__(self) -> None:
        n = len(self.t)
        for name in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.asarray(value, dtype=float)
            if value.shape != (n,):
                raise RigDataError(self.source, f"has shape {value.shape}, expected ({n},)", column=name)
            setattr(self, name, value)
        if self.run is None:
            self.run = split_runs(self.t)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def names(self) -> list[str]:
        """Columns present, in schema order (the order :func:`write_rig_csv` writes)."""
        return [c for c in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if getattr(self, c) is not None]

    @property
    def sample_period(self) -> float:
        """Median sample period [s]."""
        return float(np.median(np.diff(self.t))) if len(self.t) > 1 else math.nan

    def subset(self, index: np.ndarray) -> MeasuredData:
        """The samples selected by a boolean mask or index array (runs kept)."""
        kwargs = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS, "run", "lines"):
            if kwargs[name] is not None:
                kwargs[name] = np.asarray(kwargs[name])[index]
        return MeasuredData(**kwargs)


def split_runs(t: FloatArray) -> np.ndarray:
    """Run index per sample: a new run starts after a gap > RUN_GAP_PERIODS median periods."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        return np.zeros(len(t), dtype=int)
    steps = np.diff(t)
    gap = steps > RUN_GAP_PERIODS * np.median(steps)
    return np.concatenate([[0], np.cumsum(gap)]).astype(int)


def _parse(cell: str, source: str, line: int, column: str, required: bool) -> float:
    text = cell.strip()
    if not text:
        if required:
            raise RigDataError(source, "empty cell in a required column", line, column)
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise RigDataError(source, f"{text!r} is not a number", line, column) from None
    if required and not math.isfinite(value):
        raise RigDataError(source, f"{text!r} is not finite (required columns must be finite)", line, column)
    return value


def read_rig_csv(path: str | Path) -> MeasuredData:
    """Read a ``worm_rig_data`` CSV file (schema in the module docstring).

    Raises:
        RigDataError: unreadable file or not UTF-8 text, no header, a required column
            missing, a duplicate column, a row with the wrong number of cells, a cell that
            is not a number (or not finite in a required column), ``t`` not strictly
            increasing, or no data row.  The message names the file, the line
            (1 = header) and the column.
    """
    source = str(path)
    try:
        check_input(path, "worm_rig_data CSV file")  # a FIFO or a device is refused before it is opened
        handle = Path(path).open(newline="", encoding="utf-8-sig")  # -sig: a byte-order mark is dropped
    except InputError as err:
        raise RigDataError(source, err.what) from None
    except OSError as err:
        raise RigDataError(source, f"cannot read: {err.strerror or err}") from err
    with handle:
        reader = csv.reader(handle)
        try:
            try:
                header = [h.strip() for h in next(reader)]
            except StopIteration:
                raise RigDataError(source, "empty file (expected a header row)", 1) from None
            seen: set[str] = set()
            for name in header:
                if name in seen:
                    raise RigDataError(source, "duplicate column in the header", 1, name)
                seen.add(name)
            missing = [c for c in REQUIRED_COLUMNS if c not in seen]
            if missing:
                raise RigDataError(source, f"missing required column(s) {missing} in the header "
                                           f"(required: {', '.join(REQUIRED_COLUMNS)})", 1, missing[0])
            index = {c: header.index(c) for c in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if c in seen}
            values: dict[str, list[float]] = {c: [] for c in index}
            t = values["t"]
            lines: list[int] = []
            for row in reader:
                line = reader.line_num
                if not row or all(not cell.strip() for cell in row):
                    continue  # blank line
                lines.append(line)
                if len(row) != len(header):
                    raise RigDataError(source, f"{len(row)} cells, the header has {len(header)}", line)
                for name, i in index.items():
                    values[name].append(_parse(row[i], source, line, name, name in REQUIRED_COLUMNS))
                if len(t) > 1 and not t[-1] > t[-2]:
                    raise RigDataError(source, f"time {t[-1]!r} is not after the previous row's {t[-2]!r} "
                                               "(t must increase strictly)", line, "t")
        except csv.Error as err:
            raise RigDataError(source, f"not CSV: {err}", max(reader.line_num, 1)) from None
        except UnicodeDecodeError as err:
            # decoded in blocks: the line reached so far is not where the bad byte is
            raise RigDataError(source, f"not UTF-8 text ({err.reason})") from None
        except OSError as err:  # e.g. a folder
            raise RigDataError(source, f"cannot read: {err.strerror or err}") from None
    if not t:
        raise RigDataError(source, "no data rows after the header")
    arrays = {name: np.asarray(v, dtype=float) for name, v in values.items()}
    for name in OPTIONAL_COLUMNS:
        if name in arrays and np.all(np.isnan(arrays[name])):
            del arrays[name]  # an all-empty optional column is an absent one
    ignored = tuple(n for n in header if n not in REQUIRED_COLUMNS and n not in OPTIONAL_COLUMNS)
    return MeasuredData(**arrays, source=source, ignored_columns=ignored, lines=np.asarray(lines))


def csv_header(path: str | Path) -> list[str]:
    """The column names of a CSV file's first line ([] when it has none or cannot be read as text)."""
    try:
        with Path(path).open(newline="", encoding="utf-8-sig") as handle:
            return [h.strip() for h in next(csv.reader([handle.readline(1 << 16)]), [])]
    except (OSError, UnicodeDecodeError, csv.Error):
        return []


def is_rig_csv(path: str | Path) -> bool:
    """``path`` is a CSV whose header holds the required columns of the schema (what ``bag export`` writes)."""
    return set(REQUIRED_COLUMNS) <= set(csv_header(path))


def _cell(value: float) -> str:
    return "" if math.isnan(value) else repr(value)


def write_rig_csv(path: str | Path, data: MeasuredData) -> None:
    """Write ``data`` in the ``worm_rig_data`` schema: the columns present, shortest round-trip floats.

    Raises:
        RigDataError: the file cannot be written.
    """
    names = data.names
    try:
        with Path(path).open("w", newline="", encoding="utf-8") as handle:
            handle.write(",".join(names) + "\n")
            columns = [getattr(data, c).tolist() for c in names]  # Python floats: repr is the shortest form
            for row in zip(*columns, strict=True):
                handle.write(",".join(_cell(v) for v in row) + "\n")
    except OSError as err:
        raise RigDataError(str(path), f"cannot write: {err.strerror or err}") from err
