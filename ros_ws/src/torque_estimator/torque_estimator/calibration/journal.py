"""The journal that makes a calibration resumable: what was measured so far, and under which settings.

A calibration (`calibrate`, batch on the simulator or live on the graph) runs
the grid's points in a fixed order, the *plan*: ``CalibrationGrid.points()``,
speed-major, plan index i = speed index x (number of torques) + torque index.
After every measured point (live) or batch of points (simulator) the journal
is rewritten atomically (write to a temporary file, fsync, rename), so a run
stopped at any instant, by Ctrl-C or by SIGKILL, leaves a journal holding
every point finished before it. ``calibrate --resume`` reads it back, checks
that the run's settings are the same ones, and measures only the points still
missing. The finished database is built from the journal's points in plan
order, so a resumed calibration gives the same database as an uninterrupted
one (on the deterministic simulator: the very same numbers).

File format ``worm_torque_calibration_journal`` (UTF-8 JSON)::

    {"format": "worm_torque_calibration_journal", "version": 1,
     "started": "2021-05-01T12:00:00+00:00", "resumed": 0,
     "settings": {...everything that decides the measured values...},
     "units": {"omega_worm": "rad/s", ...},
     "points": {"plan_index": [...], "omega_worm": [...], "omega_std": [...],
                "current_drive": [...], "current_std": [...], "tau_load": [...],
                "tau_std": [...], "samples": [...], "settled": [...]}}

Units and signs as in :mod:`torque_estimator.estimation.database`. NaN is
written as ``null``. ``settings`` holds the grid, the steady-state criterion,
the rig parameter set and the source (simulator: seed, PI gains, batch size;
live: the topics); a journal resumes only under equal settings.

Version history:

- 1: first version.
"""
from __future__ import annotations

import json
import math
import os
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Final

import numpy as np

from worm_model.errors import InputError
from worm_model.files.reading import load_json
from worm_model.files.writing import write_text_atomically

from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.errors import JournalError
from torque_estimator.session.resume import normalised, settings_problem

FORMAT: Final = "worm_torque_calibration_journal"
VERSION: Final = 1

#: Per-point journal columns: name -> unit ("1" for counts and booleans).
COLUMNS: Final[dict[str, str]] = {
    "omega_worm": "rad/s",
    "omega_std": "rad/s",
    "current_drive": "A",
    "current_std": "A",
    "tau_load": "N·m",
    "tau_std": "N·m",
    "samples": "1",
    "settled": "1",
}


def default_journal_path(database_path: str | os.PathLike[str]) -> Path:
    """Where a calibration writing ``database_path`` keeps its journal: ``<database_path>.partial``."""
    path = Path(database_path)
    return path.with_name(path.name + ".partial")


def _point_problem(point: dict[str, Any]) -> str:
    """What is wrong with one journal point ("" if nothing)."""
    for name, unit in COLUMNS.items():
        value = point[name]
        if name == "settled":
            if not isinstance(value, bool):
                return f"field 'settled' is {value!r}, not true or false"
            continue
        if value is None and name.endswith("_std"):
            continue  # a spread may be unknown
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            return f"field '{name}' is {'null' if value is None else repr(value)}, not a finite number [{unit}]"
        if (name.endswith("_std") or name == "samples") and value < 0:
            return f"field '{name}' is {value!r}, negative"
        if name == "samples" and value != int(value):
            return f"field 'samples' is {value!r}, not a whole number"
    return ""


class CalibrationJournal:
    """Points measured so far (by plan index) under one set of settings; see the module docstring.

    Args:
        path: the journal file; None keeps the journal in memory only (no resume).
        settings: JSON-able description of the run (compared on resume).
        n_points: number of points of the plan.
    """

    def __init__(self, path: Path | None, settings: dict[str, Any], n_points: int,
                 started: str | None = None, resumed: int = 0) -> None:
        self.path = path
        self.settings = normalised(settings)
        self.n_points = n_points
        self.started = started or datetime.now(timezone.utc).isoformat(timespec="seconds")
        self.resumed = resumed
        self.points: dict[int, dict[str, float]] = {}
        #: points a resumed journal held with bad values and left out (measured again), described
        self.dropped: list[str] = []

    # --- opening --------------------------------------------------------------------------------
    @classmethod
    def open(cls, path: Path | None, settings: dict[str, Any], n_points: int,
             resume: bool, drop_bad_points: bool = False) -> "CalibrationJournal":
        """A fresh journal, or (resume) the one at ``path`` if there is one.

        Args:
            drop_bad_points: leave out points the journal holds with a missing or non-finite
                value (they are measured again) instead of refusing the journal.

        Raises:
            JournalError: a journal exists and resume is False (it would be
                overwritten); or it cannot be read, holds a bad point, or was taken
                with other settings (the message names the first differing setting).
        """
        if path is None or not path.exists():
            return cls(path, settings, n_points)
        if not resume:
            raise JournalError(f"{path} holds an interrupted calibration: pass --resume to continue it, "
                               "or delete it to start over")
        journal = cls.load(path, n_points, drop_bad_points)
        differs = settings_problem(journal.settings, normalised(settings))
        if differs:
            raise JournalError(f"journal {path} was taken with other settings: {differs}; "
                               "repeat the interrupted command's options, or delete the journal to start over")
        journal.resumed += 1
        return journal

    @classmethod
    def load(cls, path: Path, n_points: int, drop_bad_points: bool = False) -> "CalibrationJournal":
        """Read a journal file (settings are not checked here; see :meth:`open`).

        Every point must have finite means (``omega_worm``, ``current_drive``, ``tau_load``), spreads
        that are null or >= 0, a whole ``samples`` >= 0 and a boolean ``settled``: a journal holding
        another point could be resumed but never finished. Such points are refused, naming the file,
        the point and the way out, or with ``drop_bad_points`` left out (listed in :attr:`dropped`)
        so that they are measured again.
        """
        try:
            doc = load_json(path, "calibration journal")
        except InputError as err:
            raise JournalError(f"journal {err}") from None
        if not isinstance(doc, dict) or doc.get("format") != FORMAT:
            raise JournalError(f"journal {path}: field 'format' is not {FORMAT!r}")
        if doc.get("version") != VERSION:
            raise JournalError(f"journal {path}: field 'version': unsupported version {doc.get('version')!r} "
                               f"(supported: {VERSION})")
        for key in ("settings", "points", "started"):
            if key not in doc:
                raise JournalError(f"journal {path}: missing field {key!r}")
        journal = cls(path, doc["settings"], n_points, started=doc["started"], resumed=int(doc.get("resumed", 0)))
        points = doc["points"]
        try:
            indices = [int(i) for i in points["plan_index"]]
            columns = {name: points[name] for name in COLUMNS}
        except (KeyError, TypeError, ValueError) as err:
            raise JournalError(f"journal {path}: bad field 'points': {err!r}") from None
        for name, values in columns.items():
            if len(values) != len(indices):
                raise JournalError(f"journal {path}: field 'points.{name}' has {len(values)} values, "
                                   f"expected {len(indices)}")
        for row, index in enumerate(indices):
            if not 0 <= index < n_points:
                raise JournalError(f"journal {path}: field 'points.plan_index' at row {row}: {index} is not "
                                   f"a point of this run's plan (0..{n_points - 1})")
            point = {name: columns[name][row] for name in COLUMNS}
            problem = _point_problem(point)
            if problem:
                if drop_bad_points:
                    journal.dropped.append(f"point {index} ({problem})")
                    continue
                raise JournalError(
                    f"journal {path}: point {index} (row {row}): {problem}, so this calibration cannot be finished "
                    "from it; resume with --drop-bad-points to measure that point again, or delete the journal "
                    "to start over")
            journal.points[index] = {name: (math.nan if v is None else v) for name, v in point.items()}
        return journal

    # --- progress -------------------------------------------------------------------------------
    def pending(self) -> np.ndarray:
        """Plan indices not measured yet, in plan order."""
        return np.array([i for i in range(self.n_points) if i not in self.points], dtype=int)

    @property
    def complete(self) -> bool:
        return len(self.points) == self.n_points

    def record(self, plan_indices, measured) -> None:
        """Add measured points and rewrite the journal file atomically.

        Args:
            plan_indices: plan index of each measured point, shape (m,).
            measured: an operating_points.OperatingPoints of the same m points.
        """
        for row, index in enumerate(np.asarray(plan_indices, dtype=int)):
            self.points[int(index)] = {
                "omega_worm": float(measured.omega_worm[row]), "omega_std": float(measured.omega_std[row]),
                "current_drive": float(measured.current_drive[row]),
                "current_std": float(measured.current_std[row]),
                "tau_load": float(measured.tau_load[row]), "tau_std": float(measured.tau_std[row]),
                "samples": int(measured.samples[row]), "settled": bool(measured.settled[row])}
        self.save()

    def save(self) -> None:
        """Write the journal file atomically (nothing for an in-memory journal)."""
        if self.path is None:
            return
        order = sorted(self.points)

        def column(name: str) -> list:
            values = [self.points[i][name] for i in order]
            return [None if isinstance(v, float) and math.isnan(v) else v for v in values]

        doc = {"format": FORMAT, "version": VERSION, "started": self.started, "resumed": self.resumed,
               "settings": self.settings, "units": dict(COLUMNS),
               "points": {"plan_index": order, **{name: column(name) for name in COLUMNS}}}
        write_text_atomically(self.path, json.dumps(doc, indent=1, ensure_ascii=False, allow_nan=False) + "\n")

    def remove(self) -> None:
        """Delete the journal file (after the database is written)."""
        if self.path is not None:
            self.path.unlink(missing_ok=True)

    # --- the result -----------------------------------------------------------------------------
    def database(self, setpoint_index: np.ndarray, speed_setpoints, torque_setpoints, rig: dict[str, Any],
                 criterion: dict[str, Any], notes: str) -> CalibrationDatabase:
        """The calibration database of a complete journal, points in plan order.

        Args:
            setpoint_index: (speed index, torque index) of every plan point, shape (n_points, 2).

        Raises:
            JournalError: points are still missing.
        """
        if not self.complete:
            raise JournalError(f"journal has {len(self.points)} of {self.n_points} points; cannot finish")
        rows = [self.points[i] for i in range(self.n_points)]

        def col(name: str) -> np.ndarray:
            return np.array([r[name] for r in rows])

        settled = col("settled").astype(bool)
        resumed = f"; resumed {self.resumed} time(s)" if self.resumed else ""
        return CalibrationDatabase(
            omega_worm=col("omega_worm"), current_drive=col("current_drive"), tau_load=col("tau_load"),
            omega_std=col("omega_std"), current_std=col("current_std"), tau_std=col("tau_std"),
            samples=col("samples").astype(int), speed_setpoints=speed_setpoints, torque_setpoints=torque_setpoints,
            setpoint_index=setpoint_index, rig=rig,
            created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            steady_state={**criterion, "unsettled_points": np.flatnonzero(~settled).tolist()},
            notes=f"{notes}; started {self.started}{resumed}",
        )


__all__ = ["FORMAT", "VERSION", "COLUMNS", "CalibrationJournal", "default_journal_path"]
