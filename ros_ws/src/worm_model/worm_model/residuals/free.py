"""Free parameters of the declared model: which rig parameters the residual analysis may fit.

A rig parameter file (worm_model.physics.parameters, format ``worm_rig_parameters``) may carry an
optional top-level list naming them by their dotted field path::

    free: [friction.scale, drive_motor.coulomb_drag]

``load_rig`` ignores the list; :func:`read_free` reads and checks it.  Only parameters
the drive-current model depends on can be free (:data:`FREE_PARAMETERS`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from pathlib import Path


from worm_model.cli.validate import InputError, load_yaml
from worm_model.physics.parameters import ParameterError, Rig, default_rig_path

#: dotted path -> (SI unit, what it does in the current model)
FREE_PARAMETERS: dict[str, tuple[str, str]] = {
    "friction.scale": ("1", "multiplies the AGMA mu(V_s) curve"),
    "friction.mu_constant": ("1", "mu of the 'constant' friction model"),
    "drive_motor.torque_constant": ("N m/A", "K_t: current per torque"),
    "drive_motor.coulomb_drag": ("N m", "drive motor's Coulomb drag"),
    "drive_motor.viscous_drag": ("N m s/rad", "drive motor's viscous drag"),
    "drive_motor.rotor_inertia": ("kg m^2", "rotor inertia (worm side)"),
    "gearbox.worm_inertia": ("kg m^2", "worm shaft inertia"),
    "gearbox.gear_inertia": ("kg m^2", "gear shaft inertia"),
    "load_motor.coulomb_drag": ("N m", "load motors' Coulomb drag (gear side)"),
    "load_motor.viscous_drag": ("N m s/rad", "load motors' viscous drag (gear side)"),
}


def get_value(rig: Rig, path: str) -> float:
    """SI value of a dotted rig field."""
    section, name = path.split(".")
    return float(getattr(getattr(rig, section), name))


def set_value(rig: Rig, path: str, value: float) -> Rig:
    """A copy of the rig with one dotted field replaced (no range check: fits may probe)."""
    section, name = path.split(".")
    return dataclasses.replace(rig, **{section: dataclasses.replace(getattr(rig, section), **{name: float(value)})})


def set_values(rig: Rig, paths: Iterable[str], values: Iterable[float]) -> Rig:
    for path, value in zip(paths, values):
        rig = set_value(rig, path, value)
    return rig


def check_free(names: Iterable[str], origin: str = "<free>") -> list[str]:
    """The names, checked against :data:`FREE_PARAMETERS` (duplicates removed, order kept).

    Raises:
        ParameterError: an unknown name, naming it and listing the allowed ones.
    """
    out: list[str] = []
    for k, name in enumerate(names):
        if not isinstance(name, str) or name.strip() not in FREE_PARAMETERS:
            raise ParameterError(origin, f"free[{k}]", f"{name!r} cannot be free (allowed: {', '.join(FREE_PARAMETERS)})")
        if name.strip() not in out:
            out.append(name.strip())
    return out


def read_free(path: str | Path | None) -> list[str]:
    """The ``free:`` list of a parameter file ([] if absent); None reads the bundled rig file.

    Raises:
        ParameterError: unreadable file, ``free`` not a list, or an unknown name.
    """
    file = Path(path) if path is not None else default_rig_path()
    try:
        document = load_yaml(file, "rig parameter file")
    except InputError as err:
        raise ParameterError(err.where, "", err.what) from None
    raw = document.get("free", []) if isinstance(document, dict) else []
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise ParameterError(str(file), "free", f"expected a list of dotted parameter names, got {raw!r}")
    return check_free(raw, str(file))
