"""Free parameters of the declared model: which rig parameters the residual analysis may fit.

A rig parameter file (worm_model.physics.parameters, format ``worm_rig_parameters``) may carry an
optional top-level list naming them by their dotted field path::

    free: [friction.scale, drive_motor.coulomb_drag]

``load_rig`` ignores the list; :func:`read_free` reads and checks it.  Only parameters
the drive-current model depends on can be free (:data:`FREE_PARAMETERS`).

Refitted always (:data:`STANDARD_REFIT`), on top of that list
---------------------------------------------------------------------
A rig file's numbers are nominal, whatever their provenance: a ``source:`` says where a
number was read (a catalogue, a datasheet), not that this gearbox has it.  Nor is "every
leaf marked assumption" the set to refit: in the bundled file nearly every leaf is one,
including geometry the current cannot identify (lead angle and pressure angle trade off
against mu, radii against K_t).  The default is instead a small standard set: the declared
quantities that vary from gearbox to gearbox (or motor to motor) and are identifiable from the
drive current with sensor noise; the geometry stays as declared:

* ``friction.mu``: the friction model's mu parameter (:data:`MU_PARAMETERS`: the AGMA curve's
  ``friction.scale``, the constant model's ``friction.mu_constant``).  mu is catalogue-level
  knowledge (+-30 % is common); it is also the quantity every mu effect modulates, so a wrong
  reference state of a mu effect (the oil temperature at which the declared mu holds, the
  zero-load or high-speed mu) shows as a correction of it instead of as extra effects;
* ``drive_motor.torque_constant``: datasheet tolerance +-5..10 %;
* ``drive_motor.coulomb_drag``, ``drive_motor.viscous_drag``, ``load_motor.coulomb_drag``:
  drags are guesses until no-load runs are fitted (x2 either way);
* ``drive_motor.rotor_inertia``: +-20 % (the worm-shaft inertia is dominated by it).

Left out: ``load_motor.viscous_drag`` (2 x 1.1e-5 N m s/rad at the gear speed moves the
drive current by ~2e-4 A at full speed, 1 % of the sensor noise: a free value wanders over
+-20x its size), the gear-side inertia (its share of the current is ~0.2 % of the worm
side's, see effects.InertiaError), and the geometry.

Some effects of the vocabulary are *the same function* of the data as a refitted
parameter (an alias): the drive-current sensor's gain and K_t, bearing Coulomb drag and
the motors' Coulomb drags, viscous drag with exponent 1 and the viscous drag, the worm-side
inertia error and the rotor inertia.  No fit can tell them apart; only size can.  Each
refitted parameter therefore has a tolerance band (:data:`TOLERANCES`), the spread of a
declared value a user should expect: inside it, a deviation is a parameter correction;
beyond it (and only if clamping the parameter to the band's edge costs a significant
held-out error, aliases.resolve_aliases) the deviation is named as the aliased effect.  The
band is relative to the declared value, except around a declared 0 (a drag "none known"),
where a relative band is empty: there it is absolute, [0, x2.5 a typical drag of that motor]
(:meth:`Tolerance.band`).

Physical range: a drag, a friction coefficient and an inertia are never negative
(:data:`LOWER_BOUNDS`: the fit holds them at 0 rather than cross it, fitting.fit).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path


from worm_model.errors import InputError, ParameterError
from worm_model.files.reading import load_yaml
from worm_model.physics.parameters import Motor, Rig, default_rig_path

#: the name of the friction model's mu parameter, whichever model (:func:`resolve_parameters`)
MU = "friction.mu"

#: dotted path -> (SI unit, what it does in the current model)
FREE_PARAMETERS: dict[str, tuple[str, str]] = {
    MU: ("1", "the friction model's mu parameter: friction.scale (agma, stribeck), friction.mu_constant (constant)"),
    "friction.scale": ("1", "multiplies the mu(V_s) curve (agma, stribeck)"),
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


#: friction model (worm_model.physics.friction.FRICTION_MODELS) -> the rig parameter its mu is proportional to:
#: the mu correction of that model (the others of the ``friction`` section are not read by it)
MU_PARAMETERS: dict[str, str] = {
    "agma": "friction.scale",
    "constant": "friction.mu_constant",
    "stribeck": "friction.scale",  # the whole curve, kinetic mu and its low-speed rise alike
}


#: friction model -> the ``friction`` numbers of MU_PARAMETERS' kind it reads (a refit of another would never move)
READ_BY_MODEL: dict[str, frozenset[str]] = {
    "agma": frozenset({"friction.scale"}),
    "constant": frozenset({"friction.mu_constant"}),
    "stribeck": frozenset({"friction.scale", "friction.mu_constant"}),
}


def mu_parameter(friction_model: str) -> str:
    """The dotted rig parameter that scales mu under ``friction_model`` (:data:`MU_PARAMETERS`).

    Raises:
        KeyError: a friction model without a mu parameter here.
    """
    return MU_PARAMETERS[friction_model]


def resolve_parameters(rig: Rig, names: Iterable[str], origin: str = "<free>") -> list[str]:
    """The dotted ``names`` as rig fields of ``rig``: :data:`MU` becomes the friction model's mu parameter;
    duplicates removed, order kept.

    Raises:
        ParameterError: a ``friction`` parameter the rig's friction model does not read (it would be
            refitted without changing anything: a correction that can never move).
    """
    live = mu_parameter(rig.friction.model)
    out: list[str] = []
    for name in names:
        if name == MU:
            name = live
        elif name in MU_PARAMETERS.values() and name not in READ_BY_MODEL[rig.friction.model]:
            raise ParameterError(origin, name, f"not read by the friction model {rig.friction.model!r}: its mu is "
                                               f"{live} (or write {MU}, the mu of whichever model)")
        if name not in out:
            out.append(name)
    return out


#: refitted by default on top of the rig file's ``free:`` list (module docstring)
STANDARD_REFIT: tuple[str, ...] = (
    MU,
    "drive_motor.torque_constant",
    "drive_motor.coulomb_drag",
    "drive_motor.viscous_drag",
    "drive_motor.rotor_inertia",
    "load_motor.coulomb_drag",
)


#: a typical drag of a motor, as a share of its rated torque K_t x rated current: the no-load current of a
#: brushed DC motor (its Coulomb and viscous drag at no-load speed) is 3-10 % of its rated current
TYPICAL_DRAG_SHARE = 0.05


def typical_coulomb_drag(motor: Motor) -> float:
    """A typical Coulomb drag of ``motor`` [N m]: :data:`TYPICAL_DRAG_SHARE` of its rated torque."""
    return TYPICAL_DRAG_SHARE * motor.torque_constant * motor.rated_current


def typical_viscous_drag(motor: Motor) -> float:
    """A typical viscous drag of ``motor`` [N m s/rad]: the typical Coulomb drag at its no-load speed V_max / K_e."""
    return typical_coulomb_drag(motor) * motor.back_emf_constant / motor.max_voltage


@dataclass(frozen=True)
class Tolerance:
    """How far an identified value may sit from the declared one and still be a parameter correction.

    ``low``/``high``: identified / declared ratios bounding the band (None: unbounded).
    ``effect``: the vocabulary effect that is an alias of this parameter (None: none);
    ``upward_only``: the alias exists only above the band (a drag effect adds drag).
    ``typical``: a typical value of the parameter on a rig [SI] (None: none); around a declared 0
    the band is absolute, [0, ``high`` x typical] (a relative band around 0 is empty).
    """

    low: float | None
    high: float | None
    effect: str | None = None
    upward_only: bool = False
    why: str = ""
    #: physical range of identified / declared: a fit outside it is not accepted (selection.physical); a
    #: declared 0 has none (its parameter's lower bound, LOWER_BOUNDS, is what keeps it physical)
    hard: tuple[float, float] | None = None
    typical: Callable[[Rig], float] | None = None

    def band(self, declared: float, rig: Rig) -> tuple[float | None, float | None]:
        """The band's edges [SI] around ``declared`` (None: unbounded on that side)."""
        if declared == 0.0:
            if self.typical is None or self.high is None:
                return None, None
            return 0.0, self.high * self.typical(rig)
        return (None if self.low is None else self.low * declared,
                None if self.high is None else self.high * declared)

    def outside(self, declared: float, identified: float, rig: Rig) -> bool:
        """``identified`` lies beyond the band around ``declared``."""
        low, high = self.band(declared, rig)
        return (low is not None and identified < low) or (high is not None and identified > high)

    def describe(self, declared: float, rig: Rig, unit: str) -> str:
        """The band as a user reads it: ``x0.4..x2.5``, or around a declared 0 ``0..0.0172 N m``."""
        if declared == 0.0:
            low, high = self.band(declared, rig)
            return "" if high is None else f"{low:g}..{high:.3g} {unit} (absolute: declared 0)"
        if self.low is None and self.high is None:
            return ""
        return f"x{self.low:g}..x{self.high:g}"

    def hard_range(self, declared: float) -> tuple[float, float] | None:
        """The physical range [SI] of the identified value (None: none besides LOWER_BOUNDS)."""
        if self.hard is None or declared == 0.0:
            return None
        return tuple(sorted((self.hard[0] * declared, self.hard[1] * declared)))


#: tolerance bands of the refitted parameters (module docstring); twice to 2.5x the issue's
#: "realistic" declared errors (K_t +-5 %, drags x2, inertia +-20 %), so that a declared value off
#: by that much plus the fit's own spread stays a correction
_MU_TOLERANCE = Tolerance(None, None, None, why="mu: no effect is a constant scale of mu", hard=(0.2, 5.0))
TOLERANCES: dict[str, Tolerance] = {
    "friction.scale": _MU_TOLERANCE,
    "friction.mu_constant": _MU_TOLERANCE,
    "drive_motor.torque_constant": Tolerance(0.9, 1.1, "sensor_gain",
                                             why="K_t datasheet tolerance +-5..10 %; a current-sensor gain "
                                                 "error is the same function of the data", hard=(0.5, 2.0)),
    "drive_motor.coulomb_drag": Tolerance(0.4, 2.5, "bearing_coulomb", True,
                                          why="drags are guesses within x2; bearing drag on the worm adds to it",
                                          typical=lambda rig: typical_coulomb_drag(rig.drive_motor)),
    "load_motor.coulomb_drag": Tolerance(0.4, 2.5, "bearing_coulomb", True,
                                         why="drags are guesses within x2; bearing drag on the gear adds to it",
                                         typical=lambda rig: typical_coulomb_drag(rig.load_motor)),
    "drive_motor.viscous_drag": Tolerance(0.4, 2.5, "viscous_drag", True,
                                          why="drags are guesses within x2; viscous drag (exponent 1) adds to it",
                                          typical=lambda rig: typical_viscous_drag(rig.drive_motor)),
    "drive_motor.rotor_inertia": Tolerance(0.7, 1.4, "inertia_error",
                                           why="rotor inertia +-20 %; an inertia error is the same function",
                                           hard=(0.2, 5.0)),
}

#: refitted parameters that are never negative (drags, friction coefficients, inertias): lower bound [SI]
LOWER_BOUNDS: dict[str, float] = {name: 0.0 for name in (
    "friction.scale", "friction.mu_constant", "drive_motor.coulomb_drag", "drive_motor.viscous_drag",
    "load_motor.coulomb_drag", "load_motor.viscous_drag", "drive_motor.rotor_inertia", "gearbox.worm_inertia",
    "gearbox.gear_inertia")}

#: effect -> the refitted parameters it is entirely an alias of (not screened while they are all free)
PURE_ALIASES: dict[str, tuple[str, ...]] = {
    "bearing_coulomb": ("drive_motor.coulomb_drag", "load_motor.coulomb_drag"),
    "inertia_error": ("drive_motor.rotor_inertia",),
    # its load-sensor part is a load-proportional change nearly collinear with K_t and mu scale
    "sensor_gain": ("drive_motor.torque_constant",),
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
            raise ParameterError(origin, f"free[{k}]", f"{name!r} cannot be free "
                                                       f"(allowed: {', '.join(FREE_PARAMETERS)})")
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
