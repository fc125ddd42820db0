"""The health check on a real worm drive: the T-RO 2021 drive's steady-state data, one half against the other.

The data (worm_model/data/tro2021, 46 EPOS exports: 23 speeds per direction, one hanging load of
18.84 mN m on the gear) and their reader (worm_model.rig_data.epos) and rig file
(worm_model/data/tro2021_worm_rig.yaml) come with the real-data work; until they are in this tree
:func:`real_drive_line` says so and :func:`real_drive_check` raises :class:`RealDataMissing`
(the tests skip). They are looked up at run time, not imported, so that this module stands
without them.

Each export is one steady point (epos.steady_point: its mean speed and motor torque, the torque's
standard error from 10 blocks); its load is the hanging mass's torque, + opposing + rotation. The
points are split into two halves (alternate speeds in each direction); each half is fitted as a
check (worm_model.health.fit, the rig file's values as the priors' centres), and the second is
compared with the first on mu's scale (both at the lab's temperature, unrecorded: the same for
both) and the drive-side drag: a drive that did not change between two runs must show no change,
within the intervals one load allows. One load tells the mesh's friction from the drags only through
lifting against lowering, and the gear side's drag not at all from the load (both add to the mesh
load): mu's scale is barely identified (the line says so), the drive-side drag is.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from worm_model.health.assess import Z95
from worm_model.health.fit import fit_points
from worm_model.health.model import HealthParameters
from worm_model.health.points import Points
from worm_model.health.settings import HealthSettings
from worm_model.physics.parameters import load_rig

from torque_estimator.errors import RealDataMissing

#: the hanging load: 0.096 kg on a 20 mm pulley at the lab's 9.812 m/s^2 (SOURCE.md of the data) [N m]
LOAD = 9.812 * 0.096 * 0.02


@dataclass
class RealCheck:
    """The two halves' fits and the change between them."""

    points: tuple[int, int]
    mu_change: float  # relative, second half against the first
    mu_sigma: float
    drag_change: float  # [N m] drive-side drag at the halves' mean speed
    drag_sigma: float
    torque: float  # [N m] the drive's mean |torque| over the points (the scale of the drag's interval)
    mu_identified: bool  # both halves' fits decided mu's scale (a single load hardly does)

    def line(self) -> str:
        return (f"health: real=tro2021 points={self.points[0]}+{self.points[1]} mu_change={self.mu_change:+.1%} "
                f"+- {Z95 * self.mu_sigma:.1%} mu_identified={'yes' if self.mu_identified else 'no'} "
                f"drive_drag_change_mNm={1e3 * self.drag_change:+.3f} +- {1e3 * Z95 * self.drag_sigma:.3f} "
                f"change={'yes' if self.changed else 'none'}")

    @property
    def changed(self) -> bool:
        return abs(self.mu_change) > Z95 * self.mu_sigma or abs(self.drag_change) > Z95 * self.drag_sigma


def _data() -> tuple[object, Path, Path]:
    import worm_model  # noqa: PLC0415 (only to find its data)

    root = Path(worm_model.__file__).resolve().parent / "data"
    folder = root / "tro2021" / "driveNo3" / "steady_state" / "0.096kg"
    rig_file = root / "tro2021_worm_rig.yaml"
    try:
        epos = importlib.import_module("worm_model.rig_data.epos")
    except ModuleNotFoundError:
        raise RealDataMissing("the EPOS reader (worm_model.rig_data.epos) is not in this tree") from None
    if not folder.is_dir() or not rig_file.is_file():
        raise RealDataMissing(f"{folder} or {rig_file} is not in this tree")
    return epos, folder, rig_file


def real_drive_check(settings: HealthSettings = HealthSettings()) -> RealCheck:
    """The check of the real drive, half against half (module docstring). Raises RealDataMissing."""
    epos, folder, rig_file = _data()
    rig = load_rig(rig_file)
    nominal = rig.drive_motor.torque_constant * rig.drive_motor.rated_current  # the EPOS's 100 % torque
    steady = [epos.steady_point(export) for export in epos.read_epos_folder(folder, skip_bad_rows=True)]
    omega = np.array([_field(p, "speed") for p in steady])  # [rad/s] of the motor = the worm
    torque = nominal * np.array([_field(p, "torque") for p in steady])  # [fraction of nominal] -> [N m]
    sem = nominal * np.array([_field(p, "torque_sem") for p in steady])
    order = np.argsort(omega)
    halves = ([], [])
    for direction in (omega[order] > 0, omega[order] < 0):
        for j, k in enumerate(order[direction]):
            halves[j % 2].append(k)
    fits = []
    for half in halves:
        k = np.array(half)
        n = len(k)
        points = Points(omega=omega[k], tau_load=np.full(n, LOAD), torque=torque[k], torque_sigma=sem[k],
                        gear_sin=np.zeros(n), gear_cos=np.zeros(n), te=np.full(n, math.nan),
                        te_sigma=np.full(n, math.nan), temperature=np.full(n, math.nan), duration=np.ones(n),
                        t=np.arange(n, dtype=float))
        fits.append(fit_points(points, rig, HealthParameters.from_rig(rig), settings.priors))
    a, b = fits
    s_a, s_b = a.parameters.mu_scale, b.parameters.mu_scale
    speed = float(np.mean(np.abs(omega)))
    drags = []
    for f in fits:
        g = np.zeros(8)
        g[3], g[4] = 1.0, speed
        drags.append((f.parameters.drive_coulomb + f.parameters.drive_viscous * speed,
                      math.sqrt(max(g @ f.covariance @ g, 0.0) * max(1.0, f.chi2_red))))
    mu_sigma = math.hypot(a.interval("mu_scale") / s_a, b.interval("mu_scale") / s_b) * s_b / s_a
    return RealCheck((a.points, b.points), s_b / s_a - 1.0, mu_sigma, drags[1][0] - drags[0][0],
                     math.hypot(drags[0][1], drags[1][1]), float(np.mean(np.abs(torque))),
                     a.identified["mu_scale"] and b.identified["mu_scale"])


def _field(point, name: str) -> float:
    if not hasattr(point, name):
        raise RealDataMissing(f"the EPOS steady point has no {name!r}: the reader is not the one this was written for")
    return float(getattr(point, name))


def real_drive_line(settings: HealthSettings = HealthSettings()) -> str:
    """``make evaluate``'s line for the real drive (skipped, saying why, while its data are not in this tree)."""
    try:
        return real_drive_check(settings).line()
    except RealDataMissing as err:
        return f"health: real=skipped ({err})"


__all__ = ["LOAD", "RealCheck", "real_drive_check", "real_drive_line"]
