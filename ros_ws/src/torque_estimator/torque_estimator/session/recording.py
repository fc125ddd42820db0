"""Recording an excitation, sample by sample, resumably: the run's core and its journal (no ROS).

:class:`ExcitationRun` walks the timeline on the rig's own sample clock: it tells the shell
the set-points in force for the next sample (:meth:`ExcitationRun.setpoints`) and takes
every sample the rig sends (:meth:`ExcitationRun.add`).  Segment k lasts
round(end_k / T) - round(start_k / T) samples (T the sample period), so the timeline's
rig time is the same whoever drives it: the simulator in this process
(``identification.simulated``) or the ROS shell over the graph (``recording_node``, for ``identify``
and the health check's live reference run alike).

Journal (resumable like ``calibrate``): after every finished segment its samples are
appended to ``<out>.partial.csv`` (the ``worm_rig_data`` CSV schema, worm_model.rig_data)
and synced, then ``<out>.partial.json`` is rewritten atomically with the settings (the
timeline, the rig file's values, the source), the segments done and the CSV's length in
bytes at that point.  A run stopped at any instant (Ctrl-C, SIGTERM, SIGKILL) leaves every
finished segment; ``--resume`` checks the settings (session.resume), cuts the CSV back to the
committed length (a half-written segment is dropped) and goes on with the next segment.  Its
samples continue the time axis after a gap of RESUME_GAP, so the reader sees a new *run*
there (filters restart, no derivative across it).  Samples with a NaN/inf required channel
are skipped and counted (they still count as rig time).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from worm_model.rig_data.schema import MeasuredData, read_rig_csv
from worm_model.errors import RigDataError
from worm_model.files.writing import write_text_atomically
from torque_estimator.errors import JournalError
from torque_estimator.session.resume import normalised, settings_problem

FORMAT: Final = "worm_torque_identification_journal"
VERSION: Final = 1
#: the CSV columns recorded (worm_rig_data schema), in order
COLUMNS: Final[tuple[str, ...]] = ("t", "current_drive", "omega_worm", "theta_worm", "tau_load", "voltage_drive",
                                   "theta_gear", "current_load")
#: the channels a sample must have finite to be kept
REQUIRED: Final[tuple[str, ...]] = ("current_drive", "omega_worm", "theta_worm", "tau_load")
#: gap [s] in the time axis where a resumed run continues
RESUME_GAP: Final = 1.0


def journal_paths(out: str | os.PathLike[str]) -> tuple[Path, Path]:
    """(state JSON, samples CSV) of the journal of a run writing ``out``."""
    path = Path(out)
    return path.with_name(path.name + ".partial.json"), path.with_name(path.name + ".partial.csv")


def _cell(value: float) -> str:
    return "" if math.isnan(value) else repr(float(value))


@dataclass
class Journal:
    """The journal of one run (module docstring); ``state`` None: in memory only (no files)."""

    settings: dict
    state_path: Path | None = None
    csv_path: Path | None = None
    segments_done: int = 0
    rows: int = 0
    size: int = 0  # bytes of the CSV committed
    t_next: float = 0.0  # [s] time of the next sample
    resumed: int = 0

    def __post_init__(self) -> None:
        self._memory: list[list[float]] = []

    @classmethod
    def open(cls, out: str | os.PathLike[str] | None, settings: dict, resume: bool) -> "Journal":
        """The journal for ``out`` (None: in memory); resumes an existing one if ``resume``.

        Raises:
            JournalError: a journal exists and resume is False, it cannot be read, or its settings differ.
        """
        settings = normalised(settings)
        if out is None:
            return cls(settings)
        state_path, csv_path = journal_paths(out)
        if not state_path.exists():
            journal = cls(settings, state_path, csv_path)
            csv_path.write_text(",".join(COLUMNS) + "\n", encoding="utf-8")
            journal.size = csv_path.stat().st_size
            journal._write_state()
            return journal
        if not resume:
            raise JournalError(f"{state_path}: an interrupted identification exists; pass --resume to continue it "
                               f"or delete {state_path} and {csv_path}")
        try:
            doc = json.loads(state_path.read_text(encoding="utf-8"))
            if doc.get("format") != FORMAT or doc.get("version") != VERSION:
                raise ValueError(f"not a {FORMAT} v{VERSION} file")
            if differs := settings_problem(doc["settings"], settings):
                raise ValueError(f"taken with other settings: {differs}; repeat the interrupted command's "
                                 "options, or delete the journal to start afresh")
            journal = cls(settings, state_path, csv_path, int(doc["segments_done"]), int(doc["rows"]),
                          int(doc["size"]), float(doc["t_next"]), int(doc.get("resumed", 0)) + 1)
            with csv_path.open("r+b") as handle:  # drop a half-written segment
                handle.truncate(journal.size)
        except (OSError, ValueError, KeyError, TypeError) as err:
            raise JournalError(f"{state_path}: cannot resume: {err}") from None
        journal.t_next += RESUME_GAP if journal.rows else 0.0
        journal._write_state()
        return journal

    def _write_state(self) -> None:
        if self.state_path is None:
            return
        write_text_atomically(self.state_path, json.dumps(
            {"format": FORMAT, "version": VERSION, "settings": self.settings, "segments_done": self.segments_done,
             "rows": self.rows, "size": self.size, "t_next": self.t_next, "resumed": self.resumed}, indent=1))

    def commit(self, rows: list[list[float]], t_next: float) -> None:
        """One finished segment: its rows (COLUMNS order) and the time of the next sample."""
        if self.csv_path is None:
            self._memory.extend(rows)
        else:
            with self.csv_path.open("a", encoding="utf-8", newline="") as handle:
                handle.write("".join(",".join(_cell(v) for v in row) + "\n" for row in rows))
                handle.flush()
                os.fsync(handle.fileno())
            self.size = self.csv_path.stat().st_size
        self.rows += len(rows)
        self.segments_done += 1
        self.t_next = t_next
        self._write_state()

    def data(self, source: str) -> MeasuredData:
        """Everything recorded, as rig data."""
        if self.csv_path is None:
            table = np.array(self._memory, dtype=float).reshape(-1, len(COLUMNS))
            return MeasuredData(**{c: table[:, k] for k, c in enumerate(COLUMNS)}, source=source)
        try:
            return read_rig_csv(self.csv_path)
        except RigDataError as err:
            raise JournalError(str(err)) from None

    def remove(self) -> None:
        """Delete the journal's files (after the result is written)."""
        for path in (self.state_path, self.csv_path):
            if path is not None:
                path.unlink(missing_ok=True)


class ExcitationRun:
    """Walks a timeline on the rig's sample clock and records every sample (module docstring).

    Args:
        timeline: the segments (excitation.Ramp).
        journal: where finished segments go (its ``segments_done`` are skipped).
        sample_period: the rig's sample period [s].
    """

    def __init__(self, timeline, journal: Journal, sample_period: float) -> None:
        if sample_period <= 0:
            raise ValueError(f"sample_period must be > 0, got {sample_period}")
        self.timeline = tuple(timeline)
        self.journal = journal
        self.period = sample_period
        edges = np.rint(np.cumsum([0.0] + [s.duration for s in self.timeline]) / sample_period).astype(int)
        #: samples of each segment
        self.lengths = np.diff(edges)
        self.count = 0  # samples of the current segment taken
        self._rows: list[list[float]] = []
        #: samples skipped because a required channel was NaN/inf
        self.skipped_samples = 0

    @property
    def segment(self) -> int | None:
        """Index of the segment being recorded; None when every segment is done."""
        k = self.journal.segments_done
        return k if k < len(self.timeline) else None

    @property
    def finished(self) -> bool:
        return self.segment is None

    @property
    def total_samples(self) -> int:
        return int(self.lengths.sum())

    @property
    def samples_done(self) -> int:
        """Samples of the timeline taken so far (finished segments and the current one)."""
        return int(self.lengths[:self.journal.segments_done].sum()) + self.count

    def setpoints(self) -> tuple[float, float] | None:
        """(worm speed [rad/s], load torque [N m]) for the next sample; None when finished."""
        k = self.segment
        if k is None:
            return None
        return self.timeline[k].at(self.count * self.period)

    def add(self, sample: dict[str, Any]) -> bool:
        """Take one rig sample (mapping with the COLUMNS but ``t``; ``current_load`` may be missing).

        Returns True when it finished a segment (then in the journal). Ignored when finished.
        """
        k = self.segment
        if k is None:
            return False
        t = self.journal.t_next + self.count * self.period
        row = [t] + [float(sample.get(c, math.nan)) for c in COLUMNS[1:]]
        if all(math.isfinite(float(sample.get(c, math.nan))) for c in REQUIRED):
            self._rows.append(row)
        else:
            self.skipped_samples += 1
        self.count += 1
        if self.count < self.lengths[k]:
            return False
        self.journal.commit(self._rows, t + self.period)
        self._rows, self.count = [], 0
        return True


def run_settings(timeline, rig_values: dict, source: str, **extra: Any) -> dict:
    """What decides a run's samples (checked on --resume): the timeline, the rig file's values, the source."""
    return {"timeline": [s.to_dict() for s in timeline], "rig": rig_values, "source": source, **extra}


__all__ = ["COLUMNS", "ExcitationRun", "FORMAT", "Journal", "RESUME_GAP", "VERSION",
           "journal_paths", "run_settings"]
