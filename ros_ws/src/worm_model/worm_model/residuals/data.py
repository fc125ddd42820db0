"""Measured rig data for the residual analysis: the CSV schema, its reader and writer.

CSV schema ``worm_rig_data`` (one header row, then one row per sample, comma separated)
-------------------------------------------------------------------------------------
Required columns:

==================  =======  ==========================================================
``t``               s        sample time, strictly increasing
``current_drive``   A        drive-motor armature current (the fitted signal)
``omega_worm``      rad/s    worm (= drive motor) speed, + is the reference rotation
``theta_worm``      rad      worm angle, unwrapped
``tau_load``        N m      known load torque on the gear shaft, + opposes + rotation
==================  =======  ==========================================================

Optional columns (empty cells allowed, read as NaN):
``voltage_drive`` [V], ``theta_gear`` [rad, unwrapped, + with + worm rotation],
``current_load`` [A], ``temperature`` [degC, oil or housing].  With ``theta_gear`` the
transmission error ratio * theta_worm - theta_gear is fitted too (backlash shows there);
with ``temperature`` the oil-temperature effect uses it instead of a thermal model.

Columns may come in any order; unknown columns are ignored (and listed in
:attr:`MeasuredData.ignored_columns`).  A gap in ``t`` longer than
:data:`RUN_GAP_PERIODS` median sample periods starts a new *run* (a separate
recording): filters restart there and no derivative is taken across it.

Every problem raises :class:`DataError` whose message names the file, the line
(1 = the header) and the column: ``data.csv: line 17, column 'omega_worm': 'abc'
is not a number``.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from worm_model.units import FloatArray

#: column -> unit, in the order written by :func:`write_csv`
REQUIRED_COLUMNS: dict[str, str] = {
    "t": "s",
    "current_drive": "A",
    "omega_worm": "rad/s",
    "theta_worm": "rad",
    "tau_load": "N m",
}
OPTIONAL_COLUMNS: dict[str, str] = {
    "voltage_drive": "V",
    "theta_gear": "rad",
    "current_load": "A",
    "temperature": "degC",
}
#: a time step longer than this many median periods starts a new run
RUN_GAP_PERIODS = 5.0


class DataError(ValueError):
    """Unreadable or inconsistent measured data.

    Attributes:
        source: the file (or other origin).
        line: 1-based line of the file (1 = header), 0 if not about one line.
        column: the offending column ("" if not about one column).
    """

    def __init__(self, source: str, problem: str, line: int = 0, column: str = "") -> None:
        self.source = str(source)
        self.line = line
        self.column = column
        super().__init__(f"{_where(self.source, line, column)}: {problem}")


def _where(source: str, line: int, column: str) -> str:
    parts = []
    if line:
        parts.append(f"line {line}")
    if column:
        parts.append(f"column {column!r}")
    return f"{source}: {', '.join(parts)}" if parts else source


@dataclass
class MeasuredData:
    """One data set, SI units, arrays of shape (n,).  Optional channels are None when absent."""

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
    run: np.ndarray = field(default=None)  # type: ignore[assignment]  # run index per sample (int)

    def __post_init__(self) -> None:
        n = len(self.t)
        for name in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.asarray(value, dtype=float)
            if value.shape != (n,):
                raise DataError(self.source, f"has shape {value.shape}, expected ({n},)", column=name)
            setattr(self, name, value)
        if self.run is None:
            self.run = split_runs(self.t)

    def __len__(self) -> int:
        return len(self.t)

    @property
    def sample_period(self) -> float:
        """Median sample period [s]."""
        return float(np.median(np.diff(self.t))) if len(self.t) > 1 else math.nan

    def subset(self, index: np.ndarray) -> "MeasuredData":
        """The samples selected by a boolean mask or index array (runs kept)."""
        kwargs = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS, "run"):
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
            raise DataError(source, "empty cell in a required column", line, column)
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise DataError(source, f"{text!r} is not a number", line, column) from None
    if required and not math.isfinite(value):
        raise DataError(source, f"{text!r} is not finite (required columns must be finite)", line, column)
    return value


def read_csv(path: str | Path) -> MeasuredData:
    """Read a ``worm_rig_data`` CSV file (schema in the module docstring).

    Raises:
        DataError: unreadable file, missing header or required column, duplicate column,
            a row with the wrong number of cells, a non-numeric or non-finite value,
            ``t`` not strictly increasing, fewer than 2 rows.  The message names the
            file, the line (1 = header) and the column.
    """
    source = str(path)
    try:
        handle = open(path, newline="", encoding="utf-8")
    except OSError as err:
        raise DataError(source, f"cannot read: {err.strerror or err}") from err
    with handle:
        reader = csv.reader(handle)
        try:
            header = next(reader)
        except StopIteration:
            raise DataError(source, "empty file (expected a header row)", 1) from None
        except csv.Error as err:
            raise DataError(source, f"not CSV: {err}", 1) from None
        names = [h.strip() for h in header]
        seen: set[str] = set()
        for name in names:
            if name in seen:
                raise DataError(source, "duplicate column in the header", 1, name)
            seen.add(name)
        missing = [c for c in REQUIRED_COLUMNS if c not in seen]
        if missing:
            raise DataError(source, f"missing required column(s) {missing} in the header "
                                    f"(required: {', '.join(REQUIRED_COLUMNS)})", 1, missing[0])
        wanted = {c: names.index(c) for c in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if c in seen}
        columns: dict[str, list[float]] = {c: [] for c in wanted}
        line = 1
        try:
            for row in reader:
                line = reader.line_num
                if not row or all(not cell.strip() for cell in row):
                    continue  # blank line
                if len(row) != len(names):
                    raise DataError(source, f"{len(row)} cells, the header has {len(names)}", line)
                for name, index in wanted.items():
                    columns[name].append(_parse(row[index], source, line, name, name in REQUIRED_COLUMNS))
                if len(columns["t"]) > 1 and not columns["t"][-1] > columns["t"][-2]:
                    raise DataError(source, f"time {columns['t'][-1]!r} is not after the previous "
                                            f"row's {columns['t'][-2]!r} (t must increase strictly)", line, "t")
        except csv.Error as err:
            raise DataError(source, f"not CSV: {err}", reader.line_num) from None
    if len(columns["t"]) < 2:
        raise DataError(source, "fewer than 2 data rows")
    arrays = {name: np.asarray(values, dtype=float) for name, values in columns.items()}
    for name in OPTIONAL_COLUMNS:
        if name in arrays and np.all(np.isnan(arrays[name])):
            del arrays[name]  # an all-empty optional column is an absent one
    ignored = tuple(n for n in names if n not in REQUIRED_COLUMNS and n not in OPTIONAL_COLUMNS)
    return MeasuredData(**arrays, source=source, ignored_columns=ignored)


def write_csv(path: str | Path, data: MeasuredData) -> None:
    """Write ``data`` in the ``worm_rig_data`` schema (optional columns only if present)."""
    names = list(REQUIRED_COLUMNS) + [c for c in OPTIONAL_COLUMNS if getattr(data, c) is not None]
    table = np.column_stack([getattr(data, c) for c in names])
    with open(path, "w", newline="", encoding="utf-8") as handle:
        handle.write(",".join(names) + "\n")
        np.savetxt(handle, table, delimiter=",", fmt="%.10g")


def load_data(path: str | Path) -> MeasuredData:
    """Measured data from a CSV file, or from a rosbag2 directory / .mcap file.

    Bags are converted with worm_rig_driver's exporter, imported here at run time:
    worm_rig_driver depends on worm_model, so worm_model cannot declare the reverse.

    Raises:
        DataError: bad file (see :func:`read_csv`), or a bag without the exporter installed.
    """
    p = Path(path)
    if not p.exists():
        raise DataError(str(p), "no such file or directory")
    if p.is_dir() or p.suffix in (".mcap", ".db3"):
        return _load_bag(p)
    return read_csv(p)


def _load_bag(path: Path) -> MeasuredData:
    try:
        from worm_rig_driver import rig_csv  # type: ignore[import-not-found]
    except ImportError:
        raise DataError(str(path), "reading a bag needs worm_rig_driver's bag exporter (worm_rig_driver.rig_csv), "
                                   "which is not installed; export the bag to CSV with `bag export` on a machine "
                                   "that has it, or source a workspace with worm_rig_driver") from None
    from worm_rig_driver.bag_types import BagRecordingError  # type: ignore[import-not-found]

    try:
        return rig_csv.bag_to_measured(path)
    except (ValueError, OSError, BagRecordingError) as err:  # RigCsvError is a ValueError
        raise DataError(str(path), f"cannot read the bag: {err}") from err
