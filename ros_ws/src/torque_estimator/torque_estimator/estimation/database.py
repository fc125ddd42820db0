"""Calibration database of the (ω_w, i) ↦ τ_d map and its JSON file format.

The paper (§3.3, physics.md §8) measures the steady-state map on a grid of
constant worm speeds × constant load torques, in both directions, and stores
one averaged point per grid cell. The k-NN estimator looks τ_d up in it.

Units and signs, used by every field of this module:

- ``omega_worm`` [rad/s]: worm (drive motor) speed, positive in the rig's
  positive direction.
- ``current_drive`` [A]: drive motor armature current, same sign convention.
- ``tau_load`` [N·m]: load torque on the gear (wheel) shaft, positive when it
  opposes positive worm rotation. This is the absolute frame, not the frame
  of motion: a resistive load at negative speed has ``tau_load < 0``.

File format ``worm_torque_calibration`` (UTF-8 JSON, never pickle)::

    {"format": "worm_torque_calibration", "version": 1,
     "created": "2021-05-01T12:00:00+00:00", "notes": "...",
     "units": {"omega_worm": "rad/s", ...every field below...},
     "grid": {"speed_setpoints": [...], "torque_setpoints": [...]},
     "rig": {...}, "steady_state": {...},
     "points": {"omega_worm": [...], "current_drive": [...], "tau_load": [...],
                "omega_std": [...], "current_std": [...], "tau_std": [...],
                "samples": [...], "setpoint_index": [[speed_i, torque_j], ...]}}

NaN (only allowed in the ``*_std`` columns, e.g. a one-sample point) is
written as ``null``. Floats are written with Python's shortest round-trip
repr, so save → load is exact.

Version history:

- 1: first version.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, replace
from datetime import datetime
from pathlib import Path
from typing import Any, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from worm_model.errors import InputError
from worm_model.files.reading import load_json
from worm_model.files.writing import write_text_atomically
from worm_model.physics.parameters import Rig
from worm_model.rig_data.plausibility import calibration_problem
from torque_estimator.errors import CalibrationError

FORMAT: Final = "worm_torque_calibration"
VERSION: Final = 1

#: Per-point columns: name → (unit, kind). Kinds: "mean" finite float,
#: "std" float ≥ 0 or NaN, "count" int ≥ 0, "index" int pair into the grid.
POINT_COLUMNS: Final[dict[str, tuple[str, str]]] = {
    "omega_worm": ("rad/s", "mean"),
    "current_drive": ("A", "mean"),
    "tau_load": ("N·m", "mean"),
    "omega_std": ("rad/s", "std"),
    "current_std": ("A", "std"),
    "tau_std": ("N·m", "std"),
    "samples": ("1", "count"),
    "setpoint_index": ("1", "index"),
}
#: Grid columns: name → unit.
GRID_COLUMNS: Final[dict[str, str]] = {
    "speed_setpoints": "rad/s",
    "torque_setpoints": "N·m",
}
#: Unit of every array field, as written in the file's "units" object.
UNITS: Final[dict[str, str]] = {
    **{name: unit for name, (unit, _) in POINT_COLUMNS.items()},
    **GRID_COLUMNS,
}


def _as_float(name: str, value: ArrayLike) -> NDArray[np.float64]:
    try:
        return np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise CalibrationError(f"field {name!r} must hold numbers: {err}") from None


def _as_int(name: str, value: ArrayLike) -> NDArray[np.int64]:
    arr = _as_float(name, value)
    if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
        raise CalibrationError(f"field {name!r} must hold integers")
    return arr.astype(np.int64)


def _first_bad(name: str, bad: NDArray[np.bool_], arr: NDArray[Any], what: str) -> None:
    if np.any(bad):
        index = int(np.flatnonzero(bad.reshape(len(bad), -1).any(axis=1))[0])
        raise CalibrationError(
            f"field {name!r} {what} at point {index} (value {arr[index]!r})"
        )


def _check_column(name: str, kind: str, value: ArrayLike, n_grid: tuple[int, int]) -> NDArray[Any]:
    """Coerce one per-point column and check it; raise CalibrationError naming it."""
    qualified = f"points.{name}"
    if kind == "index":
        arr = _as_int(qualified, value)
        if arr.size == 0:
            arr = arr.reshape(0, 2)
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise CalibrationError(f"field {qualified!r} must be a list of [speed, torque] pairs")
        _first_bad(qualified, (arr < 0) | (arr >= np.array(n_grid)), arr, "is outside the grid")
        return arr
    arr = _as_int(qualified, value) if kind == "count" else _as_float(qualified, value)
    if arr.ndim != 1:
        raise CalibrationError(f"field {qualified!r} must be a flat list")
    if kind == "mean":
        _first_bad(qualified, ~np.isfinite(arr), arr, "is not finite")
    elif kind == "std":
        _first_bad(qualified, np.isinf(arr) | (arr < 0), arr, "is not NaN or a finite value ≥ 0")
    else:
        _first_bad(qualified, arr < 0, arr, "is negative")
    return arr


@dataclass(frozen=True, eq=False)
class CalibrationDatabase:
    """The measured steady-state map, one entry per grid point, stored as arrays.

    All per-point arrays have the same length n; arrays are read-only copies.
    Construction validates: the mean columns must be finite (drop points that
    did not settle first), ``*_std`` NaN or ≥ 0, ``samples`` integers ≥ 0,
    ``setpoint_index`` inside the grid, ``created`` parseable ISO-8601.

    Raises:
        CalibrationError: the message names the field (and the point index).

    Attributes:
        omega_worm: mean worm speed over the averaging window [rad/s].
        current_drive: mean drive armature current [A].
        tau_load: mean load torque on the gear shaft [N·m], positive opposing
            positive worm rotation.
        omega_std, current_std, tau_std: standard deviation of each point's
            samples [rad/s], [A], [N·m]; NaN if unknown.
        samples: number of samples averaged per point.
        speed_setpoints: the grid's speeds [rad/s].
        torque_setpoints: the grid's load torques [N·m].
        setpoint_index: shape (n, 2), the (speed, torque) grid index of each point.
        rig: rig parameter set (JSON-able, opaque here).
        created: creation time, ISO-8601 UTC.
        steady_state: the steady-state criterion used (JSON-able, opaque here).
        notes: free text.
    """

    omega_worm: NDArray[np.float64]
    current_drive: NDArray[np.float64]
    tau_load: NDArray[np.float64]
    omega_std: NDArray[np.float64]
    current_std: NDArray[np.float64]
    tau_std: NDArray[np.float64]
    samples: NDArray[np.int64]
    speed_setpoints: NDArray[np.float64]
    torque_setpoints: NDArray[np.float64]
    setpoint_index: NDArray[np.int64]
    rig: dict[str, Any]
    created: str
    steady_state: dict[str, Any]
    notes: str = ""

    def __post_init__(self) -> None:
        grid = {}
        for name in GRID_COLUMNS:
            arr = _as_float(f"grid.{name}", getattr(self, name))
            if arr.ndim != 1 or not np.all(np.isfinite(arr)):
                raise CalibrationError(f"field 'grid.{name}' must be a flat list of finite numbers")
            grid[name] = arr
        n_grid = (len(grid["speed_setpoints"]), len(grid["torque_setpoints"]))
        columns = {
            name: _check_column(name, kind, getattr(self, name), n_grid)
            for name, (_, kind) in POINT_COLUMNS.items()
        }
        n = len(columns["omega_worm"])
        for name, arr in columns.items():
            if len(arr) != n:
                raise CalibrationError(
                    f"field 'points.{name}' has {len(arr)} values, expected {n} "
                    "(the length of 'points.omega_worm')"
                )
        for name, arr in {**grid, **columns}.items():
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        for name in ("rig", "steady_state"):
            if not isinstance(getattr(self, name), dict):
                raise CalibrationError(f"field {name!r} must be an object")
        try:
            datetime.fromisoformat(self.created)
        except (TypeError, ValueError):
            raise CalibrationError(
                f"field 'created' is not an ISO-8601 time: {self.created!r}"
            ) from None
        if not isinstance(self.notes, str):
            raise CalibrationError("field 'notes' must be a string")

    def __len__(self) -> int:
        """Number of calibration points."""
        return len(self.omega_worm)

    @property
    def torque_range(self) -> float:
        """max(tau_load) − min(tau_load) [N·m]; 0 for an empty database."""
        return float(np.ptp(self.tau_load)) if len(self) else 0.0

    def subset(self, mask: ArrayLike) -> CalibrationDatabase:
        """The points selected by a boolean mask (length n) or an index array.

        Grid, rig, steady-state criterion, created and notes are kept, so a
        held-out evaluation trains on ``db.subset(~test)`` and tests on
        ``db.subset(test)``.
        """
        select = np.asarray(mask)
        return replace(self, **{name: getattr(self, name)[select] for name in POINT_COLUMNS})


def _encode(arr: NDArray[Any]) -> list[Any]:
    """Array → JSON list, NaN → null."""
    values = arr.tolist()
    if arr.dtype.kind != "f":
        return values
    return [None if math.isnan(v) else v for v in values]


def _to_document(db: CalibrationDatabase) -> dict[str, Any]:
    return {
        "format": FORMAT,
        "version": VERSION,
        "created": db.created,
        "notes": db.notes,
        "units": dict(UNITS),
        "grid": {name: _encode(getattr(db, name)) for name in GRID_COLUMNS},
        "rig": db.rig,
        "steady_state": db.steady_state,
        "points": {name: _encode(getattr(db, name)) for name in POINT_COLUMNS},
    }


def save_database(db: CalibrationDatabase, path: str | os.PathLike[str]) -> None:
    """Write ``db`` to ``path`` as a version-1 JSON file, atomically.

    The document is written to a temporary file in the same directory, synced,
    then moved over ``path`` with :func:`os.replace`, so an interrupted write
    leaves either the old file or the new one, never half a file.

    Raises:
        CalibrationError: rig or steady_state is not JSON-serialisable.
        OSError: the directory is not writable.
    """
    target = Path(path)
    try:
        text = json.dumps(_to_document(db), indent=1, ensure_ascii=False, allow_nan=False)
    except (TypeError, ValueError) as err:
        raise CalibrationError(f"calibration file {target}: cannot encode: {err}") from None
    write_text_atomically(target, text + "\n")


def _require(obj: dict[str, Any], key: str, where: str = "") -> Any:
    if key not in obj:
        raise CalibrationError(f"missing field {where + key!r}")
    return obj[key]


def _from_document(doc: Any) -> CalibrationDatabase:
    if not isinstance(doc, dict):
        raise CalibrationError("top level must be a JSON object")
    fmt = _require(doc, "format")
    if fmt != FORMAT:
        raise CalibrationError(f"field 'format' is {fmt!r}, expected {FORMAT!r}")
    version = _require(doc, "version")
    if version != VERSION:
        raise CalibrationError(f"field 'version': unsupported version {version!r} (supported: {VERSION})")
    sections = {key: _require(doc, key) for key in ("units", "grid", "points")}
    for key, section in sections.items():
        if not isinstance(section, dict):
            raise CalibrationError(f"field {key!r} must be an object")
    for name, unit in UNITS.items():
        found = _require(sections["units"], name, "units.")
        if found != unit:
            raise CalibrationError(f"field 'units.{name}' is {found!r}, expected {unit!r}")
    return CalibrationDatabase(
        **{name: _require(sections["grid"], name, "grid.") for name in GRID_COLUMNS},
        **{name: _require(sections["points"], name, "points.") for name in POINT_COLUMNS},
        rig=_require(doc, "rig"),
        created=_require(doc, "created"),
        steady_state=_require(doc, "steady_state"),
        notes=doc.get("notes", ""),
    )


def load_database(path: str | os.PathLike[str], rig: Rig | None = None) -> CalibrationDatabase:
    """Read and validate a calibration file written by :func:`save_database`.

    Raises:
        CalibrationError: the file is missing or unreadable, is not JSON (the
            message gives line and column), has the wrong format or an
            unsupported version, lacks a field, has columns of unequal length,
            has a non-finite mean value, spans no torque range or holds one point repeated,
            or (``rig`` given) has a point far outside what that rig can do (speeds in rpm:
            worm_model.rig_data.plausibility.calibration_problem); the message names the file
            and the field (and the point index where relevant).
    """
    source = Path(path)
    try:
        doc = load_json(source, "calibration file")
    except InputError as err:
        raise CalibrationError(f"calibration file {err}") from None
    try:
        db = _from_document(doc)
        problem = calibration_problem(db.omega_worm, db.current_drive, db.tau_load, rig)  # what every reader checks
        if problem:
            raise CalibrationError(problem)
    except CalibrationError as err:
        raise CalibrationError(f"calibration file {source}: {err}") from None
    return db


__all__ = [
    "FORMAT",
    "VERSION",
    "UNITS",
    "POINT_COLUMNS",
    "GRID_COLUMNS",
    "CalibrationDatabase",
    "save_database",
    "load_database",
    "write_text_atomically",
]
