"""What the paper's Figures 6-11 plot, computed from a calibration dataset (paper section 3.2).

The calibration runs the rig at constant worm speeds against constant load torques and
stores one steady point per (speed, torque) cell: worm speed omega [rad/s], drive current
i [A] and load torque tau_d [N m] (file format ``worm_torque_calibration`` v1, written by
``torque_estimator``'s ``calibrate``; read here with plain :mod:`json` so that worm_model
does not depend on that package).  Every point is quasi-static (a_w = 0), so Eqs 21-23 give
the contact forces from the input torque T and the load D in the frame of motion:

  Fig. 6  N vs tau_d, one line per speed (Eq. 21)
  Fig. 7  F_f vs tau_d, one line per speed (Eq. 22)
  Fig. 8  switching torque tau_sw vs speed: the load along the motion at which N changes
          sign (interpolated between grid torques), tau_sw = -D at s N = 0
  Fig. 9  mu = F_f / N vs tau_d, one line per speed (Eq. 23), unfiltered
  Fig. 10 mu kept only inside [0, mu_max], mu_max = cos(phi_n) cot(lambda) (Remark 4)
  Fig. 11 filtered mu vs speed, one line per load torque

Input torque (``drag``):
  "none"      (the paper's method) T = K_t i, the motor's torque from Eq. 29.  Bearing,
              brush and churning drag are then read into F_f, which is what makes tau_sw
              non-zero and mu blow up near switching (reference section 5).
  "declared"  T = K_t i - b omega - c sign(omega) (motor.shaft_torque) and the load motors'
              declared drag added to tau_d (gear_side.gear_side_load), as model_node does:
              F_f is then the mesh friction alone.

Signs: fixed frame as in :mod:`worm_model.physics.internal_forces` (tau_d > 0 opposes + worm
rotation); D = sign(omega) tau_d > 0 is a resistive load.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from worm_model.errors import InputError, ParameterError, ReportError
from worm_model.files.reading import load_json
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.internal_forces import internal_forces
from worm_model.physics.modes import Mode, classify_mode
from worm_model.physics.motor import electromagnetic_torque, shaft_torque
from worm_model.physics.parameters import Rig, load_rig, rig_from_dict
from worm_model.rig_data.plausibility import calibration_problem

FORMAT = "worm_torque_calibration"
VERSION = 1
DRAG_MODELS = ("none", "declared")
#: point columns read from the file
COLUMNS = ("omega_worm", "current_drive", "tau_load")


@dataclass(frozen=True)
class CalibrationPoints:
    """The steady points of a calibration file (SI, fixed frame)."""

    omega_worm: np.ndarray  # [rad/s]
    current_drive: np.ndarray  # [A]
    tau_load: np.ndarray  # [N m], + opposes + worm rotation
    speed_index: np.ndarray  # index into speed_setpoints
    torque_index: np.ndarray  # index into torque_setpoints
    speed_setpoints: np.ndarray  # [rad/s]
    torque_setpoints: np.ndarray  # [N m]
    rig: dict[str, Any] | None  # rig the file was measured on (SI dict), if present
    source: str

    def __len__(self) -> int:
        return len(self.omega_worm)


def _column(doc: dict[str, Any], section: str, name: str, origin: str) -> np.ndarray:
    block = doc.get(section)
    if not isinstance(block, dict) or name not in block:
        raise ReportError(f"{origin}: missing field '{section}.{name}'")
    try:
        values = np.array(block[name], dtype=float)
    except (TypeError, ValueError):
        raise ReportError(f"{origin}: field '{section}.{name}' must hold numbers") from None
    if values.ndim != 1 and name != "setpoint_index":
        raise ReportError(f"{origin}: field '{section}.{name}' must be a flat list")
    return values


def read_calibration(path: str | os.PathLike[str]) -> CalibrationPoints:
    """Read the points of a ``worm_torque_calibration`` v1 JSON file.

    Raises:
        ReportError: unreadable, not JSON (line/column given), wrong format or version, a
            missing or non-numeric field, columns of unequal length, a non-finite value,
            or a grid index outside the grid; the message names the file, field and point.
    """
    origin = str(path)
    try:
        doc = load_json(path, "calibration file")
    except InputError as err:
        raise ReportError(str(err)) from None
    if not isinstance(doc, dict):
        raise ReportError(f"{origin}: top level must be a JSON object")
    if doc.get("format") != FORMAT:
        raise ReportError(f"{origin}: field 'format' is {doc.get('format')!r}, expected {FORMAT!r}")
    if doc.get("version") != VERSION:
        raise ReportError(f"{origin}: field 'version': unsupported version {doc.get('version')!r} "
                          f"(supported: {VERSION})")
    cols = {name: _column(doc, "points", name, origin) for name in COLUMNS}
    index = _column(doc, "points", "setpoint_index", origin)
    speeds = _column(doc, "grid", "speed_setpoints", origin)
    torques = _column(doc, "grid", "torque_setpoints", origin)
    n = len(cols["omega_worm"])
    if n == 0:
        raise ReportError(f"{origin}: field 'points.omega_worm' is empty: no calibration points")
    if index.size == 0 or index.ndim != 2 or index.shape[1] != 2:
        raise ReportError(f"{origin}: field 'points.setpoint_index' must be a list of [speed, torque] pairs")
    for name, arr in {**cols, "setpoint_index": index}.items():
        if len(arr) != n:
            raise ReportError(f"{origin}: field 'points.{name}' has {len(arr)} values, expected {n} "
                              "(the length of 'points.omega_worm')")
        bad = ~np.isfinite(arr.reshape(n, -1)).all(axis=1)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise ReportError(f"{origin}: field 'points.{name}' is not finite at point {k}")
    outside = (index < 0) | (index >= np.array([len(speeds), len(torques)])) | (index != np.round(index))
    if outside.any():
        k = int(np.flatnonzero(outside.any(axis=1))[0])
        raise ReportError(f"{origin}: field 'points.setpoint_index' is outside the grid "
                          f"at point {k}: {index[k].tolist()}")
    rig = doc.get("rig")
    return CalibrationPoints(
        omega_worm=cols["omega_worm"], current_drive=cols["current_drive"], tau_load=cols["tau_load"],
        speed_index=index[:, 0].astype(int), torque_index=index[:, 1].astype(int),
        speed_setpoints=speeds, torque_setpoints=torques,
        rig=rig if isinstance(rig, dict) and rig else None, source=origin,
    )


def rig_for(points: CalibrationPoints, rig_file: str | os.PathLike[str] | None) -> Rig:
    """The rig to analyse with: ``rig_file`` if given, else the rig embedded in the calibration file.

    The points are then checked as every reader of a calibration checks them (a torque range, not one point
    repeated, inside what the rig can do: worm_model.rig_data.plausibility.calibration_problem).

    Raises:
        ReportError: the rig file or the embedded rig is invalid (message from load_rig); the
            calibration holds no rig and none is given (the bundled one would be a guess); a point
            far outside the rig's envelope (file, point and field named), no torque range.
    """
    try:
        if rig_file is not None:
            rig = load_rig(rig_file)
        elif points.rig is not None:
            rig = rig_from_dict(points.rig, f"{points.source}: rig")
        else:
            raise ReportError(f"{points.source}: field 'rig': missing, so the rig these points were measured on "
                              "is unknown; pass --rig RIG_FILE")
    except ParameterError as err:
        raise ReportError(str(err)) from None
    problem = calibration_problem(points.omega_worm, points.current_drive, points.tau_load, rig)
    if problem:
        raise ReportError(f"{points.source}: {problem}")
    return rig


@dataclass(frozen=True)
class PaperFigures:
    """Everything Figures 6-11 plot.  Per-point arrays have the calibration's length n;
    per-speed arrays the length of ``speed_setpoints``."""

    drag: str
    omega_worm: np.ndarray  # [rad/s] measured
    tau_load: np.ndarray  # [N m] measured, fixed frame (x axis of Figs 6, 7, 9, 10)
    load_along_motion: np.ndarray  # D = sign(omega) tau_d [N m], > 0 resistive
    input_torque: np.ndarray  # T used in Eqs 21-23, fixed frame [N m]
    normal_force: np.ndarray  # N >= 0 [N] (Fig. 6)
    signed_normal_force: np.ndarray  # s N [N]: + driving flank, - coast flank
    friction_force: np.ndarray  # F_f [N] (Fig. 7)
    mu: np.ndarray  # F_f / N, unfiltered (Fig. 9)
    mu_filtered: np.ndarray  # mu inside [0, mu_max], NaN elsewhere (Figs 10, 11)
    mode: np.ndarray  # Mode, classified with the measured tau_sw of the point's speed
    speed_index: np.ndarray
    torque_index: np.ndarray
    speed_setpoints: np.ndarray  # [rad/s]
    torque_setpoints: np.ndarray  # [N m]
    switching_torque: np.ndarray  # per speed setpoint, tau_sw >= 0 where found [N m] (Fig. 8)
    mu_max: float  # Remark 4 bound

    def per_speed(self, k: int) -> np.ndarray:
        """Indices of the points at speed setpoint k, sorted by tau_load."""
        idx = np.flatnonzero(self.speed_index == k)
        return idx[np.argsort(self.tau_load[idx], kind="stable")]

    def per_torque(self, j: int) -> np.ndarray:
        """Indices of the points at torque setpoint j, sorted by omega."""
        idx = np.flatnonzero(self.torque_index == j)
        return idx[np.argsort(self.omega_worm[idx], kind="stable")]


def zero_crossing(d: np.ndarray, signed_n: np.ndarray) -> float:
    """D at which s N passes from <= 0 to > 0, linear between neighbouring grid torques [N m].

    ``d`` sorted ascending.  NaN if s N does not change sign over the grid.  If it changes
    sign more than once (noise), the crossing closest to D = 0 is taken.
    """
    up = np.flatnonzero((signed_n[:-1] <= 0.0) & (signed_n[1:] > 0.0))
    if up.size == 0:
        return math.nan
    d0, d1, n0, n1 = d[up], d[up + 1], signed_n[up], signed_n[up + 1]
    crossings = d0 + (d1 - d0) * (-n0) / (n1 - n0)
    return float(crossings[np.argmin(np.abs(crossings))])


def compute(points: CalibrationPoints, rig: Rig, drag: str = "none") -> PaperFigures:
    """Eqs 21-23 on every calibration point and the switching torque per speed.

    Args:
        points: the calibration (steady, so a_w = 0).
        rig: gearbox geometry, drive-motor K_t and (for drag "declared") the drags.
        drag: "none" (paper: T = K_t i) or "declared" (drags taken out, see module docstring).
    Raises:
        ReportError: unknown drag model.
    """
    if drag not in DRAG_MODELS:
        raise ReportError(f"unknown drag model {drag!r} (known: {', '.join(DRAG_MODELS)})")
    w, i, tau = points.omega_worm, points.current_drive, points.tau_load
    if drag == "none":
        t_in, t_d = electromagnetic_torque(rig.drive_motor, i), tau
    else:
        t_in, t_d = shaft_torque(rig.drive_motor, i, w), gear_side_load(rig, tau, w)
    f = internal_forces(rig.gearbox, t_in, t_d, w, 0.0)
    sigma = np.where(w < 0.0, -1.0, 1.0)
    d = sigma * tau
    d_mesh = sigma * t_d
    signed_n = f.flank * f.normal_force
    n_speeds = len(points.speed_setpoints)
    tsw = np.full(n_speeds, math.nan)
    for k in range(n_speeds):
        idx = np.flatnonzero(points.speed_index == k)
        if idx.size >= 2:
            order = idx[np.argsort(d_mesh[idx], kind="stable")]
            crossing = zero_crossing(d_mesh[order], signed_n[order])
            # report it in terms of the external load: D_mesh - D = the gear-side drag
            offset = float(np.mean(d_mesh[order] - d[order]))
            tsw[k] = -(crossing - offset)
    point_tsw = np.nan_to_num(np.maximum(tsw, 0.0))[points.speed_index]
    mu = f.mu
    inside = np.isfinite(mu) & (mu >= 0.0) & (mu <= rig.gearbox.mu_engagement_max) & f.valid
    return PaperFigures(
        drag=drag,
        omega_worm=w, tau_load=tau, load_along_motion=d, input_torque=np.asarray(t_in, dtype=float),
        normal_force=f.normal_force, signed_normal_force=signed_n, friction_force=f.friction_force,
        mu=mu, mu_filtered=np.where(inside, mu, math.nan),
        mode=np.where(f.valid, classify_mode(d, point_tsw), Mode.STANDSTILL).astype(np.int8),
        speed_index=points.speed_index, torque_index=points.torque_index,
        speed_setpoints=points.speed_setpoints, torque_setpoints=points.torque_setpoints,
        switching_torque=tsw, mu_max=rig.gearbox.mu_engagement_max,
    )


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    ok = np.isfinite(x) & np.isfinite(y)
    return float(np.polyfit(x[ok], y[ok], 1)[0]) if ok.sum() >= 2 and np.ptp(x[ok]) > 0 else math.nan


def trends(fig: PaperFigures) -> dict[str, float]:
    """The numbers behind the paper's section 3.2 narrative, for the report's summary.

    Returns (units in the keys' comments):
        normal_force_linearity: smallest R^2 of N vs |D| over the speeds (Fig. 6, ~1)
        normal_force_speed_spread: largest spread of N across speeds at one torque
            setpoint, relative to the largest N (Fig. 6: speed hardly matters, ~0)
        friction_vs_load_slope: median over speeds of dF_f/dD on resistive points [N/(N m)]
        friction_vs_speed_slope: dF_f/d|omega| at the largest resistive load [N/(rad/s)]
        assistive_minus_resistive_friction: median F_f(D<0) - F_f(D>0) at equal |D| [N]
        switching_torque_vs_speed_slope: d tau_sw / d|omega| [N m/(rad/s)] (Fig. 8)
        mu_vs_load_slope: median over speeds of d mu/dD on resistive points [1/(N m)] (Fig. 9)
        mu_vs_speed_slope: d mu/d|omega| at the largest resistive load [1/(rad/s)] (Fig. 11)
    """
    out: dict[str, float] = {}
    r2, lin_f, lin_mu, diffs = [], [], [], []
    for k in range(len(fig.speed_setpoints)):
        idx = fig.per_speed(k)
        if idx.size < 3:
            continue
        x, n = np.abs(fig.load_along_motion[idx]), fig.normal_force[idx]
        r2.append(np.corrcoef(x, n)[0, 1] ** 2)
        res = idx[fig.load_along_motion[idx] > 0]
        lin_f.append(_slope(fig.load_along_motion[res], fig.friction_force[res]))
        lin_mu.append(_slope(fig.load_along_motion[res], fig.mu_filtered[res]))
        ass = idx[fig.load_along_motion[idx] < 0]
        if ass.size and res.size:
            # pair each assistive point with the resistive point of the nearest |D|
            near = res[np.argmin(np.abs(np.abs(fig.load_along_motion[ass])[:, None]
                                        - fig.load_along_motion[res][None, :]), axis=1)]
            diffs.extend(fig.friction_force[ass] - fig.friction_force[near])
    spreads = []
    for j in range(len(fig.torque_setpoints)):
        idx = fig.per_torque(j)
        if idx.size >= 2:
            spreads.append(np.ptp(fig.normal_force[idx]))
    out["normal_force_linearity"] = float(np.min(r2)) if r2 else math.nan
    out["normal_force_speed_spread"] = float(np.max(spreads) / np.max(fig.normal_force)) if spreads else math.nan
    out["friction_vs_load_slope"] = float(np.nanmedian(lin_f)) if lin_f else math.nan
    out["mu_vs_load_slope"] = float(np.nanmedian(lin_mu)) if lin_mu else math.nan
    out["assistive_minus_resistive_friction"] = float(np.median(diffs)) if diffs else math.nan
    speed = np.abs(fig.speed_setpoints)
    out["switching_torque_vs_speed_slope"] = _slope(speed, fig.switching_torque)
    top = fig.load_along_motion >= 0.9 * np.max(fig.load_along_motion)
    out["friction_vs_speed_slope"] = _slope(np.abs(fig.omega_worm[top]), fig.friction_force[top])
    out["mu_vs_speed_slope"] = _slope(np.abs(fig.omega_worm[top]), fig.mu_filtered[top])
    return out
