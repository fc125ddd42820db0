"""EPOS Studio data-recorder exports (Maxon EPOS motor controllers), read as they come.

Format (as EPOS Studio 3.6 writes it; ``worm_model/data/tro2021/`` holds 48 real ones)
--------------------------------------------------------------------------------------
Text, ``;``-separated, one header block, then one row per recorded sample::

    Date:;2020-07-06 15:47:42
    Firmware Version:;0x0120;0x6150;0x0000;0x0000
    EPOS Studio Version:;3.6.1.0
    Index:;0x30D3;0x30D2;0x0000;0x0000          object dictionary entries recorded
    Subindex:;0x01;0x01;0x00;0x00
    Max. samples:;500
    Recorded samples:;500                       the number of rows that follow
    Sampling period:;51.200                     [ms]
    Scale:;...  Trigger:;...  TriggerAttributes:;...   (display settings, not read)
    ;Velocity actual value averaged;Torque actual value averaged     channel names
    ms;rpm;%                                                          units
    0.000;-15;-10.6                                                   time;channel;channel

The channels are a table (:data:`CHANNELS`): each known EPOS channel name gives the
quantity it measures and the factor of each unit it may come in; adding a channel is
adding a row. Velocity is the motor shaft's [rpm]; torque is in % (or per mille) of the
motor's *nominal torque* (the EPOS computes it from the measured current and its
configured torque constant, so % of nominal torque is % of nominal current); current
in mA or A; position in encoder counts (quadcounts). What the file does not carry is
given by the caller (:class:`EposSettings`): the load on the output, what 100 % torque
is, the encoder's counts per turn.

Dirty rows, never silently dropped or kept
------------------------------------------
A row is dirty when it has the wrong number of cells (a trailing ``;``), a cell that is
not a number, text after the values (a note typed into a spreadsheet column), a time not
after the previous row's, or a value that is a *spike*: farther than
:data:`SPIKE_FACTOR` times the channel's row-to-row spread (robust: 1.4826 x the median
absolute deviation of the first differences, at least the channel's resolution) from both
neighbours, on the same side of both. The EPOS's channels are averaged and cannot jump
away and back within one sample; on the 48 files of drive No. 3 the largest such excursion
of a real sample is 7 x the spread, and the three edited values (-1200, -800, -400 %)
are 950-2008 x. By default a dirty row is refused: :class:`RigDataError` naming
``file: line N: what``. With ``skip_bad_rows`` the rows are left out and each is reported
in :attr:`EposExport.dirty` (the tools print them and their count).

A file re-saved by a spreadsheet as comma-separated text (every line ends in ``,,``, the
EPOS text in the first column; a quoted trigger line) is read; the empty extra cells are
ignored and said so in :attr:`EposExport.notes`; a non-empty one in a data row is dirty.

A bad file (binary, not ``;``-separated, no unit row, no velocity or torque/current
channel, fewer or more rows than the header's recorded samples, a sampling period the time
column contradicts) raises :class:`RigDataError` with one line naming the file.

Signs are kept as recorded (the authors of the T-RO data negate both columns in their
MATLAB reader; this project does not).
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Final

import numpy as np

from worm_model.physics.units import FloatArray
from worm_model.rig_data.schema import MeasuredData
from worm_model.errors import DirtyRowsError, RigDataError

RPM: Final = 2.0 * math.pi / 60.0
"""rad/s per rev/min."""
STANDARD_GRAVITY: Final = 9.80665
"""[m/s^2] (the default of a hanging load; the T-RO scripts use their local 9.812)."""
SPIKE_FACTOR: Final = 50.0
"""A value this many row-to-row spreads away from both neighbours is a spike (module docstring)."""
SNIFF_BYTES: Final = 4096
#: at most this many header lines before the unit row
MAX_HEADER_LINES: Final = 40
#: the time column's median step may differ from the header's sampling period by this fraction
PERIOD_TOLERANCE: Final = 0.01


@dataclass(frozen=True)
class Channel:
    """One row of :data:`CHANNELS`: what an EPOS channel measures and its units' factors to SI.

    ``quantity``: ``velocity`` [rad/s], ``torque`` [fraction of the nominal torque, 1 = 100 %],
    ``current`` [A] or ``position`` [counts]. ``resolution``: the smallest step the export
    writes, in the unit given (a floor for the spread of the spike test).
    """

    quantity: str
    units: dict[str, float]
    resolution: dict[str, float]


_VELOCITY = Channel("velocity", {"rpm": RPM}, {"rpm": 1.0})
_TORQUE = Channel("torque", {"%": 0.01, "‰": 0.001, "per mille": 0.001}, {"%": 0.1, "‰": 1.0, "per mille": 1.0})
_CURRENT = Channel("current", {"mA": 1e-3, "A": 1.0}, {"mA": 1.0, "A": 1e-3})
_POSITION = Channel("position", {"inc": 1.0, "qc": 1.0, "counts": 1.0}, {"inc": 1.0, "qc": 1.0, "counts": 1.0})

#: EPOS Studio channel name (lower case) -> what it is. Where a quantity is recorded twice (averaged
#: and not), the first in this order is used: the averaged value, which the recorder's rows were taken of.
CHANNELS: dict[str, Channel] = {
    "velocity actual value averaged": _VELOCITY,
    "velocity actual value": _VELOCITY,
    "torque actual value averaged": _TORQUE,
    "torque actual value": _TORQUE,
    "current actual value averaged": _CURRENT,
    "current actual value": _CURRENT,
    "position actual value": _POSITION,
}


@dataclass(frozen=True)
class EposHeader:
    """The header block. ``sampling_period`` [s]; ``channels``: (name, unit) as written, time excluded."""

    date: str
    studio_version: str
    recorded_samples: int
    sampling_period: float
    channels: tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class DirtyRow:
    """A row left out (``skip_bad_rows``) and why; ``str()`` is ``file: line N: what``."""

    source: str
    line: int
    what: str

    def __str__(self) -> str:
        return f"{self.source}: line {self.line}: {self.what}"


@dataclass
class EposExport:
    """One export in SI. ``values``: quantity -> samples (units of :class:`Channel`), the rows kept.

    ``lines``: the file line of each kept row. ``channel``: quantity -> the EPOS channel read.
    """

    source: str
    header: EposHeader
    t: FloatArray
    lines: np.ndarray
    values: dict[str, FloatArray]
    channel: dict[str, str]
    dirty: tuple[DirtyRow, ...] = ()
    notes: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True)
class SteadyPoint:
    """An export held at one speed, as one point: means and sample spreads of its rows.

    ``speed`` [rad/s] and ``torque`` [fraction of the nominal torque] are means over the ``n`` rows;
    ``*_sd`` their sample standard deviations (the standard error of a mean is sd / sqrt(n) only
    for independent rows: the EPOS's averaging correlates neighbours, see ``torque_sem``).
    """

    source: str
    n: int
    speed: float
    speed_sd: float
    torque: float
    torque_sd: float
    torque_sem: float  # standard error of the mean torque from the mean of 10 consecutive blocks [fraction]


@dataclass(frozen=True)
class EposSettings:
    """What an EPOS export does not carry, given by the user.

    ``load_torque`` [N m]: the load on the gear (output) shaft, + opposes + rotation of the
    export's velocity (worm-referenced, as the ``worm_rig_data`` schema's tau_load);
    ``nominal_current`` [A]: the current at 100 % torque (the motor's nominal current,
    nominal torque / K_t), needed when the export has torque and no current channel;
    ``counts_per_turn``: the encoder's counts per motor turn (position channels only);
    ``skip_bad_rows``: leave dirty rows out (and report them) instead of refusing the file.
    """

    load_torque: float | None = None
    nominal_current: float | None = None
    counts_per_turn: float | None = None
    skip_bad_rows: bool = False


def hanging_load(mass: float, pulley_radius: float, gravity: float = STANDARD_GRAVITY) -> float:
    """Torque [N m] of a mass [kg] hanging from a pulley of radius [m]: m g r (a magnitude)."""
    return mass * gravity * pulley_radius


# --------------------------------------------------------------------------- sniffing
def _head(path: Path) -> bytes:
    try:
        with path.open("rb") as handle:
            return handle.read(SNIFF_BYTES)
    except OSError:
        return b""


def is_epos_export(path: str | Path) -> bool:
    """True for a file that starts like an EPOS Studio export (a ``Date:`` line or its studio version
    line), whatever its separator: a wrong one is then refused by :func:`read_epos` with its reason."""
    p = Path(path)
    if not p.is_file():
        return False
    head = _head(p).lstrip(b"\xef\xbb\xbf").lstrip(b'"')
    return head.startswith(b"Date:") or b"EPOS Studio Version" in head


def epos_files(folder: str | Path) -> list[Path]:
    """The EPOS exports directly in ``folder``, in natural order of their names (2 before 10)."""
    def key(p: Path) -> list[object]:
        return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", p.name)]

    return sorted((p for p in Path(folder).iterdir() if p.suffix.lower() == ".csv" and is_epos_export(p)), key=key)


def is_epos_folder(path: str | Path) -> bool:
    """True for a folder holding EPOS exports and no bag (no ``metadata.yaml``)."""
    p = Path(path)
    return p.is_dir() and not (p / "metadata.yaml").exists() and bool(epos_files(p))


# --------------------------------------------------------------------------- reading
def _text(path: Path) -> str:
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise RigDataError(str(path), f"cannot read: {err.strerror or err}") from err
    if b"\x00" in raw[:SNIFF_BYTES]:
        raise RigDataError(str(path), "binary data, not an EPOS Studio text export")
    for encoding in ("utf-8-sig", "cp1252"):  # EPOS Studio writes the Windows code page
        try:
            return raw.decode(encoding)
        except UnicodeDecodeError:
            continue
    raise RigDataError(str(path), "not text (neither UTF-8 nor Windows-1252): not an EPOS Studio export")


def _split_wrapper(line: str) -> tuple[str, list[str]]:
    """(the EPOS text, the extra cells) of a line a spreadsheet re-saved as comma-separated text."""
    cells = next(csv.reader([line]), [""])
    return (cells[0] if cells else ""), cells[1:]


def _unquote(line: str) -> str:
    """A line a spreadsheet quoted (a trigger line ``"Trigger:;1;""Parameter values""..."``) as its text."""
    if line.startswith('"'):
        return next(csv.reader([line]), [""])[0]
    return line


def _number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def read_epos(path: str | Path, skip_bad_rows: bool = False) -> EposExport:
    """Read one EPOS Studio export (module docstring: format, dirty rows, bad files).

    Raises:
        RigDataError: a bad file, or (unless ``skip_bad_rows``) its first dirty row, as
            ``file: line N: what``; the message counts the dirty rows of the file.
    """
    p = Path(path)
    source = str(p)
    lines = _text(p).splitlines()
    if not lines or not lines[0].strip():
        raise RigDataError(source, "empty file (expected an EPOS Studio export: a 'Date:;...' header)")
    wrapped = len(_split_wrapper(lines[0])[1]) > 0 and ";" in _split_wrapper(lines[0])[0]
    texts, extras = [], []
    for line in lines:
        if wrapped:
            text, extra = _split_wrapper(line)
        else:
            text, extra = _unquote(line), []
        texts.append(text)
        extras.append(extra)
    unit_row = next((k for k, text in enumerate(texts[:MAX_HEADER_LINES]) if text.split(";")[0].strip() == "ms"), None)
    if unit_row is None:
        first = texts[0]
        for sep, name in ((",", "','"), ("\t", "tabs")):
            if sep in first and ";" not in first:
                raise RigDataError(source, f"separated by {name}, not ';': EPOS Studio writes ';' "
                                           f"(line 1 is {first[:40]!r})", 1)
        raise RigDataError(source, f"no unit row ('ms;<unit>;...') in the first {MAX_HEADER_LINES} lines: "
                                   "not an EPOS Studio data-recorder export")
    if unit_row == 0 or not texts[unit_row - 1].startswith(";"):
        raise RigDataError(source, "no channel-name row (';<name>;<name>') above the unit row", unit_row + 1)
    names = [c.strip() for c in texts[unit_row - 1].split(";")[1:]]
    units = [c.strip() for c in texts[unit_row].split(";")[1:]]
    while names and not names[-1] and units and not units[-1]:
        names.pop()
        units.pop()
    if len(names) != len(units):
        raise RigDataError(source, f"{len(names)} channel names but {len(units)} units", unit_row + 1)
    keys = {}
    for text in texts[:unit_row - 1]:
        key, _, rest = text.partition(";")
        keys[key.strip().rstrip(":").lower()] = rest.strip()
    header = _header(source, keys, tuple(zip(names, units)))
    columns = _columns(source, header, unit_row + 1)

    notes = []
    if wrapped:
        width = max(len(e) for e in extras)
        notes.append(f"{source}: every line carries up to {width} extra comma-separated cell(s) (the export was "
                     "re-saved by a spreadsheet); the empty ones are ignored")
    rows, kept_lines, dirty = [], [], []
    for k in range(unit_row + 1, len(texts)):
        text, line = texts[k], k + 1
        if not text.strip() and not any(c.strip() for c in extras[k]):
            continue  # blank line
        problems = []
        stray = [c.strip() for c in extras[k] if c.strip()]
        if stray:
            problems.append(f"stray text {', '.join(repr(s) for s in stray)} after the values")
        cells = text.split(";")
        values = None
        if len(cells) == len(names) + 2 and not cells[-1].strip():
            problems.append("trailing separator ';'")
        elif len(cells) != len(names) + 1:
            problems.append(f"{len(cells)} cells, the header has {len(names) + 1} (time and {len(names)} channel(s))")
        else:
            values = [_number(c) for c in cells]
            bad = [(c, (["ms"] + units)[j]) for j, c in enumerate(cells) if values[j] is None]
            if bad:
                problems.append(", ".join(f"{c.strip()!r} is not a number ({u})" for c, u in bad))
                values = None
        rows.append(values)
        kept_lines.append(line)
        dirty.append(problems)
    if len(rows) != header.recorded_samples:
        what = "truncated: " if len(rows) < header.recorded_samples else ""
        raise RigDataError(source, f"{what}the header says {header.recorded_samples} recorded samples, the file has "
                                   f"{len(rows)} data rows")
    _check_time(rows, kept_lines, dirty)
    _check_spikes(rows, dirty, header, columns)
    bad_rows = [DirtyRow(source, kept_lines[j], "; ".join(d)) for j, d in enumerate(dirty) if d]
    if bad_rows and not skip_bad_rows:
        raise DirtyRowsError(bad_rows)
    keep = [j for j, d in enumerate(dirty) if not d]
    if not keep:
        raise RigDataError(source, "no clean data row")
    table = np.array([rows[j] for j in keep], dtype=float)
    period = header.sampling_period
    t = table[:, 0] * 1e-3
    steps = np.diff(t)
    if len(steps) and abs(float(np.median(steps)) - period) > PERIOD_TOLERANCE * period:
        raise RigDataError(source, f"the time column steps by {1e3 * float(np.median(steps)):g} ms, the header's "
                                   f"sampling period is {1e3 * period:g} ms")
    values, chosen = {}, {}
    for quantity, (j, name, factor) in columns.items():
        values[quantity] = table[:, 1 + j] * factor
        chosen[quantity] = name
    return EposExport(source, header, t, np.asarray([kept_lines[j] for j in keep]), values, chosen,
                      tuple(bad_rows), tuple(notes))


def _header(source: str, keys: dict[str, str], channels: tuple[tuple[str, str], ...]) -> EposHeader:
    def need(key: str) -> str:
        if key not in keys:
            raise RigDataError(source, f"header line '{key.capitalize()}:' missing: not an EPOS Studio export")
        return keys[key].split(";")[0].strip()

    samples = _number(need("recorded samples"))
    if samples is None or samples < 1 or not float(samples).is_integer():
        raise RigDataError(source, f"'Recorded samples:' is {need('recorded samples')!r}, not a count")
    period = _number(need("sampling period"))
    if period is None or period <= 0:
        raise RigDataError(source, f"'Sampling period:' is {need('sampling period')!r}, not a period in ms")
    return EposHeader(keys.get("date", "").split(";")[0].strip(), keys.get("epos studio version", ""),
                      int(samples), period * 1e-3, channels)


def _columns(source: str, header: EposHeader, line: int) -> dict[str, tuple[int, str, float]]:
    """quantity -> (channel index, channel name, factor to SI) of the channels used (:data:`CHANNELS`)."""
    found: dict[str, tuple[int, str, float, int]] = {}
    order = list(CHANNELS)
    for j, (name, unit) in enumerate(header.channels):
        channel = CHANNELS.get(name.lower())
        if channel is None:
            continue
        if unit not in channel.units:
            raise RigDataError(source, f"channel {name!r} in {unit!r}: known units {', '.join(channel.units)}", line)
        rank = order.index(name.lower())
        if channel.quantity not in found or rank < found[channel.quantity][3]:
            found[channel.quantity] = (j, name, channel.units[unit], rank)
    known = ", ".join(repr(n) for n, _ in header.channels) or "none"
    if "velocity" not in found:
        raise RigDataError(source, f"no velocity channel ('Velocity actual value [averaged]' in rpm); the export has "
                                   f"{known}", line)
    if "torque" not in found and "current" not in found:
        raise RigDataError(source, f"no torque or current channel ('Torque actual value [averaged]' in %, "
                                   f"'Current actual value [averaged]' in mA); the export has {known}", line)
    return {q: (j, n, f) for q, (j, n, f, _) in found.items()}


def _check_time(rows: list, lines: list[int], dirty: list[list[str]]) -> None:
    previous = None
    for j, values in enumerate(rows):
        if values is None:
            continue
        if previous is not None and not values[0] > previous:
            dirty[j].append(f"time {values[0]:g} ms is not after the previous row's {previous:g} ms")
            continue
        previous = values[0]


def _check_spikes(rows: list, dirty: list[list[str]], header: EposHeader,
                  columns: dict[str, tuple[int, str, float]]) -> None:
    """Mark values that jump away from both neighbours and back (module docstring)."""
    valid = [j for j, v in enumerate(rows) if v is not None]
    if len(valid) < 3:
        return
    table = np.array([rows[j] for j in valid], dtype=float)
    for quantity, (j, name, _factor) in columns.items():
        if quantity == "position":
            continue  # counts integrate: a jump there is a different fault
        unit = header.channels[j][1]
        x = table[:, 1 + j]
        d = np.diff(x)
        moving = d[d != 0.0]  # a standstill's repeated values say nothing of the spread while the drive moves
        d = moving if len(moving) >= 10 else d
        spread = max(1.4826 * float(np.median(np.abs(d - np.median(d)))), CHANNELS[name.lower()].resolution[unit])
        limit = SPIKE_FACTOR * spread
        for k in range(len(x)):
            if k == 0:
                jumps, shape = [x[0] - x[1]], abs(x[1] - x[2]) < limit
            elif k == len(x) - 1:
                jumps, shape = [x[k] - x[k - 1]], abs(x[k - 1] - x[k - 2]) < limit
            else:
                jumps = [x[k] - x[k - 1], x[k] - x[k + 1]]
                shape = np.sign(jumps[0]) == np.sign(jumps[1])
            if shape and min(abs(v) for v in jumps) > limit:
                neighbours = [x[i] for i in (k - 1, k + 1) if 0 <= i < len(x)]
                dirty[valid[k]].append(
                    f"{name} {x[k]:g} {unit} is a spike: {min(abs(v) for v in jumps) / spread:.0f} x the row-to-row "
                    f"spread ({spread:.3g} {unit}) away from its neighbour(s) "
                    f"{', '.join(f'{v:g}' for v in neighbours)}")


def read_epos_folder(folder: str | Path, skip_bad_rows: bool = False) -> list[EposExport]:
    """Every EPOS export in a folder (:func:`epos_files` order).

    Raises:
        RigDataError: no export in the folder, or the first bad file / refused dirty row; when
            refusing, the message also counts the dirty rows of the whole folder.
    """
    files = epos_files(folder)
    if not files:
        raise RigDataError(str(folder), "no EPOS Studio export (*.csv starting with 'Date:;') in this folder")
    exports, refused = [], []
    for path in files:
        try:
            exports.append(read_epos(path, skip_bad_rows))
        except DirtyRowsError as err:
            refused.append(err)  # read on: the message counts the folder's dirty rows
    if refused:
        raise DirtyRowsError([row for err in refused for row in err.rows], len(refused), len(files))
    return exports


# --------------------------------------------------------------------------- what the tools use
def steady_point(export: EposExport, blocks: int = 10) -> SteadyPoint:
    """The export as one steady operating point (:class:`SteadyPoint`); needs a torque channel."""
    w, q = export.values["velocity"], export.values["torque"]
    n = len(w)
    parts = np.array_split(q, blocks)
    means = np.array([np.mean(p) for p in parts])
    return SteadyPoint(export.source, n, float(np.mean(w)), float(np.std(w, ddof=1)), float(np.mean(q)),
                       float(np.std(q, ddof=1)), float(np.std(means, ddof=1) / math.sqrt(blocks)))


def _integrate(t: FloatArray, w: FloatArray) -> FloatArray:
    out = np.zeros(len(t))
    out[1:] = np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))
    return out


def to_measured(exports: list[EposExport], settings: EposSettings, source: str) -> MeasuredData:
    """EPOS exports as one ``worm_rig_data`` data set: one run per export, in order.

    omega_worm: the motor's velocity (the motor drives the worm directly); current_drive:
    the current channel, or torque x ``nominal_current``; theta_worm: the position channel
    x 2 pi / ``counts_per_turn``, or the velocity integrated per run (said in ``notes``);
    tau_load: ``load_torque``. Runs are 1 s apart in ``t``.

    Raises:
        RigDataError: the load (or what 100 % torque is, or the counts per turn) not given.
    """
    if settings.load_torque is None:
        raise RigDataError(source, "an EPOS Studio export does not carry the load on the output: give it "
                                   "(--load-torque N_M, or --load-mass KG with --pulley-radius M)")
    parts: dict[str, list[FloatArray]] = {k: [] for k in ("t", "current_drive", "omega_worm", "theta_worm", "run",
                                                          "lines")}
    notes, skipped, offset = [], 0, 0.0
    for k, ex in enumerate(exports):
        notes.extend(ex.notes)
        notes.extend(f"skipped: {row}" for row in ex.dirty)
        skipped += len(ex.dirty)
        if "current" in ex.values:
            current = ex.values["current"]
        else:
            if settings.nominal_current is None:
                raise RigDataError(ex.source, "the torque is in % of the motor's nominal torque: say what 100 % is "
                                              "(the rig file's drive_motor.rated_current, the nominal current)")
            current = ex.values["torque"] * settings.nominal_current
        if "position" in ex.values and settings.counts_per_turn:
            theta = ex.values["position"] * 2.0 * math.pi / settings.counts_per_turn
        else:
            theta = _integrate(ex.t, ex.values["velocity"])
        parts["t"].append(ex.t - ex.t[0] + offset)
        parts["current_drive"].append(current)
        parts["omega_worm"].append(ex.values["velocity"])
        parts["theta_worm"].append(theta)
        parts["run"].append(np.full(len(ex), k))
        parts["lines"].append(ex.lines)
        offset = float(parts["t"][-1][-1]) + 1.0
    if any("position" not in ex.values or not settings.counts_per_turn for ex in exports):
        notes.append("theta_worm: the velocity integrated per file (the export has no position channel, or no "
                     "counts per turn were given): good for nothing finer than a turn")
    joined = {k: np.concatenate(v) for k, v in parts.items()}
    return MeasuredData(t=joined["t"], current_drive=joined["current_drive"], omega_worm=joined["omega_worm"],
                        theta_worm=joined["theta_worm"], tau_load=np.full(len(joined["t"]), settings.load_torque),
                        source=source, run=joined["run"].astype(int), lines=joined["lines"],
                        skipped={"dirty rows": skipped} if skipped else {}, notes=tuple(notes),
                        run_sources=tuple(ex.source for ex in exports),
                        current_from_torque=any("current" not in ex.values for ex in exports))


def read_epos_data(path: str | Path, settings: EposSettings | None) -> MeasuredData:
    """An EPOS export or a folder of them as ``worm_rig_data`` (:func:`to_measured`).

    The files are read (and refused) first, so a bad file is named before a missing load.
    """
    p = Path(path)
    settings = settings or EposSettings()
    exports = read_epos_folder(p, settings.skip_bad_rows) if p.is_dir() else [read_epos(p, settings.skip_bad_rows)]
    return to_measured(exports, settings, str(p))
