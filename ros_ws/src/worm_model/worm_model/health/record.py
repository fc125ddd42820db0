"""A health check's record and the gearbox's trend: the file every check appends to, over its life.

File format ``worm_gearbox_health_trend`` (JSON Lines, UTF-8)
------------------------------------------------------------
version 1 (current). Line 1 is the header ``{"format": "worm_gearbox_health_trend", "version": 1,
"gearbox": "<name>"}``; every further line is one check, oldest first::

    {"date": "2026-03-01T08:00:00+00:00", "hours": 1520.0, "source": "live rig",
     "temperature": {"value": 41.2, "sigma": 0.5, "source": "measured"},
     "parameters": {"mu_scale": 0.97, ...},            # SI, mu_scale at that oil temperature
     "sigma": {"mu_scale": 0.014, ...}, "covariance": [[...8 x 8...]], "identified": {...},
     "runout": 0.0098, "backlash": 0.00436, "backlash_sigma": 2e-05,
     "points": 30, "rig_time": 21.0, "rms": 0.00011, "chi2_red": 1.8,
     "speeds": {"forward": [60, 300], "backward": [60, 300]}, "loads": [-0.25, 0.25],
     "level": "OK", "findings": ["mu scale +1.2 % +- 3.4 % (95 %) of the baseline"],
     "steady_points": {"omega": [...], "tau_load": [...], "torque": [...], ...}}

``steady_points`` is the evidence: the run's steady points (worm_model.health.points.Points, SI), so
that a later baseline can fit the check again. ``hours`` is null where unknown, ``backlash`` null
without a gear encoder. The file is rewritten whole and atomically on every append (it is small: a
line per check), so a crash leaves the old file or the new one. Every problem reading it raises
:class:`TrendError` naming the file and the
line (``trend.jsonl: line 4: parameters.mu_scale: expected a finite number``).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from worm_model.errors import InputError, TrendError
from worm_model.files.reading import read_text
from worm_model.files.writing import write_text_atomically
from worm_model.health.fit import FitResult, Temperature
from worm_model.health.model import NAMES, HealthParameters
from worm_model.health.points import Points

FORMAT_NAME = "worm_gearbox_health_trend"
FORMAT_VERSION = 1
LEVELS = ("OK", "WARN", "ERROR")


def _number(raw, where: str, allow_none: bool = False) -> float:
    if raw is None and allow_none:
        return math.nan
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
        raise ValueError(f"{where}: expected a finite number, got {raw!r}")
    return float(raw)


def _points(doc) -> Points | None:
    """steady_points of a record: None, or every Points field as a list of numbers (null: NaN) of one length."""
    if doc is None:
        return None
    if not isinstance(doc, dict):
        raise ValueError("steady_points: expected an object of equal-length lists")
    columns = {}
    for f in fields(Points):
        values = doc.get(f.name)
        if not isinstance(values, list):
            raise ValueError(f"steady_points.{f.name}: expected a list")
        columns[f.name] = np.array([math.nan if v is None else _number(v, f"steady_points.{f.name}") for v in values])
    if len({len(v) for v in columns.values()}) != 1:
        raise ValueError("steady_points: the lists differ in length")
    return Points(**columns)


@dataclass
class CheckRecord:
    """One health check as the trend keeps it (module docstring); SI and degC, NaN where unknown."""

    date: str
    hours: float
    source: str
    temperature: Temperature
    parameters: HealthParameters
    sigma: dict[str, float]
    covariance: np.ndarray
    identified: dict[str, bool]
    runout: float
    backlash: float
    backlash_sigma: float
    points: int
    rig_time: float
    rms: float
    chi2_red: float
    speeds: dict[str, list[float]] = field(default_factory=dict)
    loads: list[float] = field(default_factory=list)
    level: str = "OK"
    findings: list[str] = field(default_factory=list)
    steady_points: Points | None = None
    #: fits of the points done by the assessment, by the shape they were centred on (not stored)
    cache: dict = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def from_fit(cls, fit: FitResult, temperature: Temperature, date: str, hours: float | None,
                 source: str, points: Points | None = None) -> "CheckRecord":
        return cls(date=date, hours=math.nan if hours is None else float(hours), source=source,
                   temperature=temperature, parameters=fit.parameters, sigma=dict(fit.sigma),
                   covariance=np.asarray(fit.covariance, dtype=float), identified=dict(fit.identified),
                   runout=fit.runout, backlash=fit.backlash, backlash_sigma=fit.backlash_sigma, points=fit.points,
                   rig_time=fit.rig_time, rms=fit.rms, chi2_red=fit.chi2_red, speeds=dict(fit.speeds),
                   loads=list(fit.loads), steady_points=points)

    def to_dict(self) -> dict:
        def nan_none(x: float):
            return None if math.isnan(x) else x

        return {"date": self.date, "hours": nan_none(self.hours), "source": self.source,
                "temperature": self.temperature.to_dict(), "parameters": self.parameters.to_dict(),
                "sigma": dict(self.sigma), "covariance": np.asarray(self.covariance).tolist(),
                "identified": dict(self.identified), "runout": self.runout, "backlash": nan_none(self.backlash),
                "backlash_sigma": nan_none(self.backlash_sigma), "points": self.points, "rig_time": self.rig_time,
                "rms": self.rms, "chi2_red": self.chi2_red, "speeds": self.speeds, "loads": self.loads,
                "level": self.level, "findings": list(self.findings),
                "steady_points": None if self.steady_points is None else
                {f.name: [None if math.isnan(v) else float(v) for v in getattr(self.steady_points, f.name)]
                 for f in fields(Points)}}

    @classmethod
    def from_dict(cls, doc: dict) -> "CheckRecord":
        """The inverse of :meth:`to_dict`. Raises ValueError naming the key."""
        if not isinstance(doc, dict):
            raise ValueError("expected a JSON object")
        t = doc.get("temperature")
        if not isinstance(t, dict) or t.get("source") not in ("measured", "estimated", "assumed"):
            raise ValueError("temperature: expected {value, sigma, source: measured|estimated|assumed}")
        temperature = Temperature(_number(t.get("value"), "temperature.value"),
                                  _number(t.get("sigma"), "temperature.sigma"), t["source"])
        params = HealthParameters.from_dict(doc.get("parameters"), "parameters")
        sigma = doc.get("sigma")
        if not isinstance(sigma, dict):
            raise ValueError("sigma: expected an object")
        sigma = {name: _number(sigma.get(name), f"sigma.{name}") for name in NAMES}
        cov = np.asarray(doc.get("covariance"), dtype=float) if isinstance(doc.get("covariance"), list) else None
        if cov is None or cov.shape != (len(NAMES), len(NAMES)) or not np.all(np.isfinite(cov)):
            raise ValueError(f"covariance: expected a {len(NAMES)} x {len(NAMES)} array of finite numbers")
        level = doc.get("level", "OK")
        if level not in LEVELS:
            raise ValueError(f"level: expected one of {', '.join(LEVELS)}, got {level!r}")
        date = doc.get("date")
        if not isinstance(date, str) or not date:
            raise ValueError("date: expected an ISO 8601 date")
        identified = doc.get("identified") if isinstance(doc.get("identified"), dict) else {}
        speeds = doc.get("speeds") if isinstance(doc.get("speeds"), dict) else {}
        speeds = {k: [_number(v, f"speeds.{k}") for v in vals] for k, vals in speeds.items()
                  if k in ("forward", "backward") and isinstance(vals, list) and len(vals) == 2}
        loads = doc.get("loads")
        loads = [_number(v, "loads") for v in loads] if isinstance(loads, list) and len(loads) == 2 else []
        findings = doc.get("findings", [])
        return cls(steady_points=_points(doc.get("steady_points")), date=date,
                   hours=_number(doc.get("hours"), "hours", allow_none=True),
                   source=str(doc.get("source", "")), temperature=temperature, parameters=params, sigma=sigma,
                   covariance=cov, identified={name: bool(identified.get(name, False)) for name in NAMES},
                   runout=_number(doc.get("runout", 0.0), "runout"),
                   backlash=_number(doc.get("backlash"), "backlash", allow_none=True),
                   backlash_sigma=_number(doc.get("backlash_sigma"), "backlash_sigma", allow_none=True),
                   points=int(_number(doc.get("points"), "points")), rig_time=_number(doc.get("rig_time"), "rig_time"),
                   rms=_number(doc.get("rms"), "rms"), chi2_red=_number(doc.get("chi2_red"), "chi2_red"),
                   speeds=speeds, loads=loads, level=level,
                   findings=[str(f) for f in findings] if isinstance(findings, list) else [])


@dataclass
class Trend:
    """A gearbox's checks, oldest first (module docstring)."""

    gearbox: str
    records: list[CheckRecord] = field(default_factory=list)
    source: str = "<memory>"

    def __len__(self) -> int:
        return len(self.records)

    def to_text(self) -> str:
        lines = [json.dumps({"format": FORMAT_NAME, "version": FORMAT_VERSION, "gearbox": self.gearbox})]
        lines += [json.dumps(r.to_dict()) for r in self.records]
        return "\n".join(lines) + "\n"


def read_trend(path: str | os.PathLike[str]) -> Trend:
    """Read a trend file.

    Raises:
        TrendError: unreadable, not this format or version, or a line that is not a valid record;
            the message names the file and the line.
    """
    origin = str(path)
    try:
        text = read_text(path, "trend file")
    except InputError as err:
        raise TrendError(err.where, err.what) from None
    lines = text.splitlines()
    if not lines:
        raise TrendError(origin, "empty file (expected a header line)")
    try:
        header = json.loads(lines[0])
    except json.JSONDecodeError as err:
        raise TrendError(f"{origin}: line 1", f"not JSON: {err.msg}") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        raise TrendError(f"{origin}: line 1", f"expected a {FORMAT_NAME!r} header")
    if header.get("version") != FORMAT_VERSION:
        raise TrendError(f"{origin}: line 1", f"unsupported version {header.get('version')!r}")
    trend = Trend(str(header.get("gearbox", "")), source=origin)
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        try:
            trend.records.append(CheckRecord.from_dict(json.loads(line)))
        except json.JSONDecodeError as err:
            raise TrendError(f"{origin}: line {number}", f"not JSON: {err.msg}") from None
        except (ValueError, TypeError) as err:
            raise TrendError(f"{origin}: line {number}", str(err)) from None
    return trend


def write_trend(path: str | os.PathLike[str], trend: Trend) -> None:
    """Write the whole trend atomically (module docstring)."""
    write_text_atomically(Path(path), trend.to_text())


__all__ = ["CheckRecord", "FORMAT_NAME", "FORMAT_VERSION", "LEVELS", "Trend", "read_trend",
           "write_trend"]
