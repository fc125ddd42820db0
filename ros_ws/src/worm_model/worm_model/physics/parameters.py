"""Rig parameters: frozen dataclasses loaded from one YAML file with a source for every number.

File format ``worm_rig_parameters``
-----------------------------------
version 1 (current): top-level keys ``format``, ``version``, ``name`` and the sections
``gearbox``, ``friction``, ``drive_motor``, ``load_motor``, ``sensors`` plus the leaves
``load_motor_count`` and ``supply_voltage``.  Every numeric leaf is a mapping::

    lead_angle: {value: 5.71, unit: deg, source: "catalogue p. 12"}      # or
    lead_angle: {value: 5.71, unit: deg, assumption: "why this value"}

with exactly one of ``source`` / ``assumption``.  Values are converted to SI with
:mod:`worm_model.physics.units`.  Which fields exist, their dimension and their range check
are declared once, as ``metadata`` on the dataclass fields below; the loader walks
that table (adding a parameter is adding a field).  A field declared optional (the sensor
chain's tacho scaling, ripple order and ADC timing) may be left out of a file: it then takes
the bundled rig's value, so a file written without them reads as it always did.

Conventions: SI units, angles in rad.  ``hand`` is +1 for a right-hand worm and -1
for a left-hand one; it only decides the sign of the gear rotation,
``omega_gear = hand * ratio * omega_worm`` (paper Eqs 26-27).

Every failure raises :class:`ParameterError`, whose message names the file and the
field (``nmrv030_rig.yaml: gearbox.lead_angle: ...``).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from worm_model.errors import InputError, ParameterError
from worm_model.files.reading import load_yaml
from worm_model.physics.friction import FRICTION_MODELS
from worm_model.physics.units import UNITS, normalize_unit, to_si

#: the SI unit of each dimension, for messages
_SI = {"length": "m", "inertia": "kg m^2", "resistance": "ohm", "inductance": "H", "torque_constant": "N m/A",
       "back_emf_constant": "V s/rad", "viscous": "N m s/rad", "torque": "N m", "current": "A", "voltage": "V",
       "angular_velocity": "rad/s", "frequency": "Hz"}

FORMAT_NAME = "worm_rig_parameters"
FORMAT_VERSION = 1
#: relative tolerance of the check n/Z == r_w tan(lambda) / r_g
RATIO_TOLERANCE = 0.05
#: optional top-level sections other modules read from the same file (load_rig skips them):
#: ``free`` (parameters the residual analysis may fit), ``effects`` (effects beyond
#: Eqs 19-30: a ``worm_rig_effects`` section, worm_model.effects) and
#: ``identification`` (what torque_estimator's ``identify`` recorded and found: ranges, corrections)
OPTIONAL_TOP_SECTIONS = frozenset({"free", "effects", "identification"})


# ---------------------------------------------------------------------------
# range checks a field can declare: name -> (predicate on the SI value, message)
CHECKS: dict[str, tuple[Callable[[float], bool], str]] = {
    "positive": (lambda x: x > 0.0, "must be > 0"),
    "nonnegative": (lambda x: x >= 0.0, "must be >= 0"),
    "angle": (lambda x: 0.0 < x < math.pi / 4.0, "must lie in (0, 45 deg)"),
    "count": (lambda x: x >= 1, "must be an integer >= 1"),
    "hand": (lambda x: x in (1, -1), "must be +1 (right-hand) or -1 (left-hand)"),
    "fraction": (lambda x: 0.0 <= x < 1.0, "must lie in [0, 1)"),
}


#: physically plausible SI values per dimension, for an electric drive on a worm gear from a bench rig to an
#: industrial one: a value outside is a unit slip or a typo (K_t = 1e-12 N m/A, a 1 MV supply), refused
#: with the range. A field may narrow it (``plausible=``); dimensionless fields have their own.
PLAUSIBLE: dict[str, tuple[float, float]] = {
    "length": (1e-4, 2.0),  # [m] a pitch radius from 0.1 mm to 2 m
    "inertia": (1e-10, 1e3),  # [kg m^2]
    "resistance": (1e-3, 1e3),  # [ohm] a winding
    "inductance": (1e-7, 10.0),  # [H]
    "torque_constant": (1e-4, 50.0),  # [N m/A]
    "back_emf_constant": (1e-4, 50.0),  # [V s/rad]
    "viscous": (0.0, 10.0),  # [N m s/rad]
    "torque": (0.0, 1e3),  # [N m] a drag torque
    "current": (0.0, 1e4),  # [A]
    "voltage": (0.1, 1e3),  # [V]
    "angular_velocity": (0.0, 1e4),  # [rad/s] a noise level
    "frequency": (1.0, 1e7),  # [Hz] a sample rate
}
#: K_t [N m/A] and K_e [V s/rad] of one DC motor are the same number in SI; a rig file may differ this much
#: (rounding, two data-sheet values), not by the factor a unit slip makes (V/krpm taken for V s/rad: 105)
MOTOR_CONSTANT_RATIO = 1.5
#: the supply may exceed the drive motor's rated voltage this many times, no more (PWM drives a 24 V motor
#: from up to ~48 V)
SUPPLY_OVER_MOTOR = 2.5


def _num(dimension: str, check: str = "positive", plausible: tuple[float, float] | None = None, *,
         optional: bool = False, default: float | None = None) -> Any:
    """Field declaration of a numeric leaf: its dimension, its range check and its plausible SI range. A file
    may leave the leaf out when it is ``optional`` (the bundled rig's value is taken then) or has a ``default``
    (that value [SI], so the files written before the leaf existed still load)."""
    metadata = {"dimension": dimension, "check": check, "plausible": plausible or PLAUSIBLE.get(dimension),
                "optional": optional}
    if default is None:
        return field(metadata=metadata)
    return field(default=default, metadata={**metadata, "default": default})


def _text() -> Any:
    return field(metadata={"kind": "text"})


def _section(cls: type) -> Any:
    return field(metadata={"section": cls})


@dataclass(frozen=True)
class Gearbox:
    """Worm gear set (SI).  ``gear_inertia`` is gear + output shaft, NOT the load motors."""

    worm_starts: int = _num("dimensionless", "count", (1, 20))
    gear_teeth: int = _num("dimensionless", "count", (1, 1000))
    worm_pitch_radius: float = _num("length")  # r_w [m]
    gear_pitch_radius: float = _num("length")  # r_g [m]
    lead_angle: float = _num("angle", "angle", (math.radians(0.5), math.radians(45)))  # lambda [rad]
    normal_pressure_angle: float = _num("angle", "angle", (math.radians(5), math.radians(40)))  # phi_n [rad]
    hand: int = _num("dimensionless", "hand")  # +1 right-hand, -1 left-hand
    worm_inertia: float = _num("inertia")  # J_w [kg m^2]
    gear_inertia: float = _num("inertia")  # J_g [kg m^2]

    @property
    def ratio(self) -> float:
        """Speed ratio i = n / Z_g = |omega_g / omega_w| (Eq. 26)."""
        return self.worm_starts / self.gear_teeth

    @property
    def geometric_ratio(self) -> float:
        """r_w tan(lambda) / r_g: the ratio the pitch geometry implies (should equal ``ratio``)."""
        return self.worm_pitch_radius * math.tan(self.lead_angle) / self.gear_pitch_radius

    @property
    def radius_ratio(self) -> float:
        """r_w / r_g."""
        return self.worm_pitch_radius / self.gear_pitch_radius

    @property
    def mu_engagement_max(self) -> float:
        """Remark 4 (after Yeh & Wu): the driving flank engages correctly only for mu < cos(phi_n) cot(lambda)."""
        return math.cos(self.normal_pressure_angle) / math.tan(self.lead_angle)

    @property
    def self_locking_mu(self) -> float:
        """mu above which the load cannot back-drive the worm: cos(phi_n) tan(lambda) (section 6)."""
        return math.cos(self.normal_pressure_angle) * math.tan(self.lead_angle)


@dataclass(frozen=True)
class Friction:
    """Tooth-thread friction model: ``model`` is a key of ``worm_model.physics.friction.FRICTION_MODELS``.

    ``stribeck_rise`` and ``stribeck_speed`` are optional (model "stribeck" only; 0 and 0.01 m/s when left out).
    """

    model: str = _text()  # "agma", "constant" or "stribeck"
    mu_constant: float = _num("dimensionless", "nonnegative", (0.0, 1.0))  # "constant"; the kinetic mu of "stribeck"
    scale: float = _num("dimensionless", "positive", (0.01, 100.0))  # multiplies the AGMA curve and the Stribeck law
    stribeck_rise: float = _num("dimensionless", "nonnegative", (0.0, 1.0), default=0.0)  # mu_s of "stribeck"
    stribeck_speed: float = _num("velocity", "positive", (1e-6, 10.0), default=0.01)  # V_st [m/s] of "stribeck"


@dataclass(frozen=True)
class Motor:
    """PMDC motor, Eq. 29 (SI), with its shaft's drags: viscous b, Coulomb c and c's low-speed rise.

    ``stribeck_rise`` and ``stribeck_speed`` are optional (0 and 1 rad/s when left out): the Coulomb drag is
    (c + c_s exp(-|omega| / omega_s)) sign(omega) (worm_model.physics.motor.coulomb_friction). For the
    ``load_motor`` section of a drive without load motors they are the output shaft supports' friction.
    """

    resistance: float = _num("resistance")  # R [ohm]
    inductance: float = _num("inductance")  # L [H]
    torque_constant: float = _num("torque_constant")  # K_t [N m/A]
    back_emf_constant: float = _num("back_emf_constant")  # K_e [V s/rad]
    rotor_inertia: float = _num("inertia")  # J_m [kg m^2]
    viscous_drag: float = _num("viscous", "nonnegative")  # b [N m s/rad]
    coulomb_drag: float = _num("torque", "nonnegative")  # c [N m]
    rated_current: float = _num("current")  # continuous [A]
    max_voltage: float = _num("voltage")  # [V]
    # the Coulomb drag's rise at low speed (a support's Stribeck friction, motor.coulomb_friction): c_s [N m] at
    # standstill, decaying over stribeck_speed [rad/s of this motor's shaft]; optional (0: none)
    stribeck_rise: float = _num("torque", "nonnegative", default=0.0)
    stribeck_speed: float = _num("angular_velocity", "positive", (1e-6, 1e4), default=1.0)


#: The firmware's analogue conversion order within one sample period (firmware/adc_mux.c): per motor its
#: armature current, then its tachogenerator. Channel k is held at (k * adc_conversion_cycles +
#: adc_hold_cycles) ADC clocks after the tick (:meth:`Sensors.sample_times`).
ADC_SEQUENCE = ("current_drive", "tacho_drive", "current_load_1", "tacho_load_1", "current_load_2", "tacho_load_2")


@dataclass(frozen=True)
class Sensors:
    """The rig's measurement chain (SI): what the simulator reproduces and what an estimator's noise model reads.

    The current and tacho figures hold for every motor's channel but the tacho's resolution, which is per
    shaft (the load motors' tachos turn with the gear, 1/ratio slower than the worm).
    """

    current_noise_std: float = _num("current", "nonnegative")  # [A]
    current_lsb: float = _num("current")  # ADC resolution of the Hall current channel [A]
    tacho_noise_std: float = _num("angular_velocity", "nonnegative")  # [rad/s]
    tacho_ripple: float = _num("dimensionless", "fraction")  # relative ripple amplitude
    encoder_pulses_per_rev: int = _num("dimensionless", "count", (1, 1e7))  # per channel
    encoder_decoding: int = _num("dimensionless", "count", (1, 4))  # 1, 2 or 4 (quadrature)
    sample_rate_hz: float = _num("frequency")  # [Hz]
    tacho_drive_lsb: float = _num("angular_velocity", optional=True)  # ADC resolution, drive tacho [rad/s]
    tacho_load_lsb: float = _num("angular_velocity", optional=True)  # ADC resolution, each load tacho [rad/s]
    tacho_ripple_order: int = _num("dimensionless", "count", optional=True)  # ripple periods per shaft turn
    adc_clock_hz: float = _num("frequency", optional=True)  # the ADC's conversion clock [Hz]
    adc_conversion_cycles: int = _num("dimensionless", "count", optional=True)  # ADC clocks per conversion
    adc_hold_cycles: float = _num("dimensionless", "nonnegative", optional=True)  # clocks to the sample-and-hold

    @property
    def counts_per_rev(self) -> int:
        """Encoder counts per shaft turn after decoding."""
        return self.encoder_pulses_per_rev * self.encoder_decoding

    def sample_times(self, sequence: tuple[str, ...] = ADC_SEQUENCE) -> dict[str, float]:
        """Signal -> instant [s] after the tick at which its channel is held, for channels converted one after
        the other in ``sequence`` order (default: the firmware's, :data:`ADC_SEQUENCE`)."""
        cycle = 1.0 / self.adc_clock_hz
        return {signal: (k * self.adc_conversion_cycles + self.adc_hold_cycles) * cycle
                for k, signal in enumerate(sequence)}

    def sequence_time(self, channels: int = len(ADC_SEQUENCE)) -> float:
        """[s] from the tick to the end of the last of ``channels`` conversions."""
        return channels * self.adc_conversion_cycles / self.adc_clock_hz


@dataclass(frozen=True)
class Rig:
    """The whole test rig: one drive motor on the worm, ``load_motor_count`` load motors on the gear."""

    name: str = _text()
    gearbox: Gearbox = _section(Gearbox)
    friction: Friction = _section(Friction)
    drive_motor: Motor = _section(Motor)
    load_motor: Motor = _section(Motor)
    load_motor_count: int = _num("dimensionless", "count", (1, 16))
    supply_voltage: float = _num("voltage")  # [V]
    sensors: Sensors = _section(Sensors)
    source: str = field(default="", metadata={"kind": "origin"})  # file it came from

    @property
    def total_worm_inertia(self) -> float:
        """J_w + J_m,drive [kg m^2]: everything rigidly on the worm shaft (Eq. 30)."""
        return self.gearbox.worm_inertia + self.drive_motor.rotor_inertia

    @property
    def total_gear_inertia(self) -> float:
        """J_g + count * J_m,load [kg m^2]: everything rigidly on the gear shaft."""
        return self.gearbox.gear_inertia + self.load_motor_count * self.load_motor.rotor_inertia

    @property
    def max_load_torque(self) -> float:
        """Continuous disturbance torque the load motors can make: count * K_t,load * rated current [N m]."""
        return self.load_motor_count * self.load_motor.torque_constant * self.load_motor.rated_current


# ---------------------------------------------------------------------------
# loading

_LEAF_KEYS = {"value", "unit", "source", "assumption", "note"}


def default_rig_path() -> Path:
    """Path of the bundled rig file ``worm_model/data/nmrv030_rig.yaml``."""
    return Path(__file__).resolve().parent.parent / "data" / "nmrv030_rig.yaml"


#: A rig file named by its package, as ROS names package files: ``package://worm_model/data/tro2021_worm_rig.yaml``
PACKAGE_SCHEME = "package://"


def resolve_rig_path(path: str | os.PathLike[str]) -> Path:
    """The file ``path`` names: ``package://<pkg>/<file>`` is ``<file>`` in the folder of the installed Python
    package ``<pkg>`` (the bundled rigs, wherever the package is installed, so a graph file can name them);
    any other path as it is. An unknown package is left as the path it spells (loading then names it)."""
    text = os.fspath(path)
    if not text.startswith(PACKAGE_SCHEME):
        return Path(text)
    package, _, rest = text[len(PACKAGE_SCHEME):].partition("/")
    spec = importlib.util.find_spec(package) if package.isidentifier() else None
    if spec is None or not spec.submodule_search_locations:
        return Path(text)
    return Path(next(iter(spec.submodule_search_locations))) / rest


def _is_int_field(f: dataclasses.Field[Any]) -> bool:
    return f.type in ("int", int)


def finite_number(raw: Any, origin: str, where: str, error: type[ParameterError] = ParameterError) -> float:
    """A YAML scalar as a finite float (PyYAML reads '1e-5' as a string: accepted).

    Shared with the other YAML files that sit beside the rig file (the simulator's
    effects file raises its own subclass, passed as ``error``).

    Raises:
        ParameterError (or ``error``): a bool, a non-scalar, a non-numeric string, inf or nan.
    """
    if isinstance(raw, bool) or not isinstance(raw, (int, float, str)):
        raise error(origin, where, f"value {raw!r} is not numeric")
    try:
        number = float(raw)
    except ValueError:
        raise error(origin, where, f"value {raw!r} is not numeric") from None
    if not math.isfinite(number):
        raise error(origin, where, f"value {raw!r} is not finite")
    return number


def _read_leaf(node: Any, f: dataclasses.Field[Any], origin: str, where: str) -> float | int:
    """One ``{value, unit, source|assumption}`` leaf -> SI number, checked."""
    if not isinstance(node, Mapping):
        raise ParameterError(origin, where, "expected a mapping {value, unit, source | assumption}")
    for key in ("value", "unit"):
        if key not in node:
            raise ParameterError(origin, where, f"missing '{key}'")
    unknown = set(node) - _LEAF_KEYS
    if unknown:
        raise ParameterError(origin, where, f"unknown keys {sorted(unknown)}")
    provenance = [k for k in ("source", "assumption") if str(node.get(k) or "").strip()]
    if len(provenance) != 1:
        raise ParameterError(
            origin, where, "needs exactly one non-empty 'source' or 'assumption' (where the number comes from)"
        )
    number = finite_number(node["value"], origin, where)
    try:
        value, dimension = to_si(number, node["unit"])
    except KeyError:
        raise ParameterError(
            origin, where, f"unknown unit {node['unit']!r} (known: {', '.join(UNITS)})"
        ) from None
    expected = f.metadata["dimension"]
    if dimension != expected:
        raise ParameterError(
            origin, where, f"unit {normalize_unit(node['unit'])!r} is a {dimension}, expected a {expected}"
        )
    return _checked(f, value, origin, where, f"{node['value']!r} {node['unit']}")


def _checked(f: dataclasses.Field[Any], value: float, origin: str, where: str, shown: str) -> float | int:
    """Integer conversion for int fields and the field's declared range check."""
    result: float | int = value
    if _is_int_field(f):
        if not float(value).is_integer():
            raise ParameterError(origin, where, f"value {shown} must be an integer")
        result = int(value)
    predicate, message = CHECKS[f.metadata["check"]]
    if not predicate(result):
        raise ParameterError(origin, where, f"value {shown}: {message}")
    plausible = f.metadata.get("plausible")
    if plausible is not None and not plausible[0] <= result <= plausible[1]:
        low, high = plausible
        si = {"angle": "rad", "dimensionless": ""}.get(f.metadata["dimension"], _SI.get(f.metadata["dimension"], ""))
        span = (f"{math.degrees(low):g} .. {math.degrees(high):g} deg" if f.metadata["dimension"] == "angle"
                else f"{low:g} .. {high:g}{' ' + si if si else ''}")
        raise ParameterError(origin, where, f"value {shown} = {result:g}{' ' + si if si else ''} (SI) is not a "
                                            f"plausible {where.rsplit('.', 1)[-1]}: expected {span} (a unit slip?)")
    return result


@functools.lru_cache(maxsize=1)
def _bundled_rig() -> Rig:
    return load_rig(None)


def _bundled_value(dotted: str) -> Any:
    """The bundled rig's value of an optional field (``sensors.adc_clock_hz``) a file leaves out."""
    value: Any = _bundled_rig()
    for name in dotted.split("."):
        value = getattr(value, name)
    return value


def _build(cls: type, node: Any, origin: str, prefix: str, leaves: bool) -> Any:
    """Walk the field table of ``cls``; ``leaves`` False reads plain SI numbers (rig_from_dict)."""
    if not isinstance(node, Mapping):
        raise ParameterError(origin, prefix.rstrip(".") or "<top>", "expected a mapping")
    kwargs: dict[str, Any] = {}
    known = set()
    for f in dataclasses.fields(cls):
        where = prefix + f.name
        known.add(f.name)
        if f.metadata.get("kind") == "origin":
            continue
        if f.name not in node:
            if "default" in f.metadata:
                kwargs[f.name] = f.metadata["default"]
                continue
            if f.metadata.get("optional") and origin != str(default_rig_path()):
                kwargs[f.name] = _bundled_value(prefix + f.name)
                continue
            raise ParameterError(origin, where, "missing")
        raw = node[f.name]
        if "section" in f.metadata:
            kwargs[f.name] = _build(f.metadata["section"], raw, origin, where + ".", leaves)
        elif f.metadata.get("kind") == "text":
            if not isinstance(raw, str) or not raw.strip():
                raise ParameterError(origin, where, f"expected a non-empty string, got {raw!r}")
            kwargs[f.name] = raw.strip()
        elif leaves:
            kwargs[f.name] = _read_leaf(raw, f, origin, where)
        else:
            kwargs[f.name] = _checked(f, finite_number(raw, origin, where), origin, where, repr(raw))
    extra = set(node) - known - {"format", "version"} - (OPTIONAL_TOP_SECTIONS if not prefix else set())
    if extra:
        raise ParameterError(origin, prefix + sorted(extra)[0], "unknown field")
    return cls(**kwargs)


def check_rig(rig: Rig, origin: str) -> None:
    """Cross-field checks: friction model known; n/Z consistent with r_w tan(lambda)/r_g within 5 %; each
    motor's K_t and K_e the same number in SI within MOTOR_CONSTANT_RATIO; a supply the drive motor is
    rated for (at most SUPPLY_OVER_MOTOR x its max_voltage).

    Raises:
        ParameterError: naming the fields and both values.
    """
    for section in ("drive_motor", "load_motor"):
        motor: Motor = getattr(rig, section)
        ratio = motor.torque_constant / motor.back_emf_constant
        if not 1 / MOTOR_CONSTANT_RATIO <= ratio <= MOTOR_CONSTANT_RATIO:
            raise ParameterError(
                origin, f"{section}.torque_constant vs {section}.back_emf_constant",
                f"K_t = {motor.torque_constant:g} N m/A but K_e = {motor.back_emf_constant:g} V s/rad: in SI they "
                f"are the same constant of a DC motor, these differ {max(ratio, 1 / ratio):.3g}-fold (one of them "
                "in another unit?)")
    if rig.supply_voltage > SUPPLY_OVER_MOTOR * rig.drive_motor.max_voltage:
        raise ParameterError(
            origin, "supply_voltage",
            f"{rig.supply_voltage:g} V is {rig.supply_voltage / rig.drive_motor.max_voltage:.3g}"
            f" x the drive motor's max_voltage {rig.drive_motor.max_voltage:g} V: not a supply that motor runs on "
            "(a unit slip?)")
    if rig.friction.model not in FRICTION_MODELS:
        raise ParameterError(
            origin, "friction.model", f"unknown model {rig.friction.model!r} (known: {', '.join(FRICTION_MODELS)})"
        )
    gb = rig.gearbox
    if abs(gb.geometric_ratio - gb.ratio) > RATIO_TOLERANCE * gb.ratio:
        raise ParameterError(
            origin,
            "gearbox.worm_starts/gearbox.gear_teeth vs gearbox.worm_pitch_radius, "
            "gearbox.gear_pitch_radius, gearbox.lead_angle",
            f"ratio n/Z = {gb.ratio:.5f} but r_w*tan(lambda)/r_g = {gb.geometric_ratio:.5f} "
            f"(more than {RATIO_TOLERANCE:.0%} apart): the geometry is inconsistent",
        )


def load_rig(path: str | os.PathLike[str] | None = None) -> Rig:
    """Load and check a ``worm_rig_parameters`` v1 file; ``None`` loads :func:`default_rig_path`, and
    ``package://<pkg>/<file>`` a file of an installed package (:func:`resolve_rig_path`).

    Returns:
        a :class:`Rig` in SI units whose ``source`` is the resolved file path.

    Raises:
        ParameterError: unreadable file, wrong format/version, missing or unknown field,
            leaf without source/assumption, non-numeric value, unknown or mismatched unit,
            a key given twice,
            out-of-range value, inconsistent gear geometry.  The message names file and field.
    """
    file = resolve_rig_path(path) if path is not None else default_rig_path()
    origin = str(file)
    try:
        document = load_yaml(file, "rig parameter file")
    except InputError as err:
        raise ParameterError(err.where, "", err.what) from None
    if not isinstance(document, Mapping):
        raise ParameterError(origin, "", "not a YAML mapping")
    if document.get("format") != FORMAT_NAME:
        raise ParameterError(origin, "format", f"expected {FORMAT_NAME!r}, got {document.get('format')!r}")
    if document.get("version") != FORMAT_VERSION:
        raise ParameterError(origin, "version", f"unsupported version {document.get('version')!r}")
    rig = dataclasses.replace(_build(Rig, document, origin, "", leaves=True), source=str(file.resolve()))
    check_rig(rig, origin)
    return rig


def rig_to_dict(rig: Rig) -> dict[str, Any]:
    """Plain JSON-able dict of the rig, SI values, same nesting as the dataclasses."""
    return dataclasses.asdict(rig)


def rig_from_dict(data: Mapping[str, Any], origin: str = "<dict>") -> Rig:
    """Inverse of :func:`rig_to_dict` (e.g. the rig embedded in a calibration file), checked.

    Raises:
        ParameterError: missing/unknown/non-numeric field or inconsistent geometry.
    """
    rig = dataclasses.replace(_build(Rig, data, origin, "", leaves=False), source=str(data.get("source", "")))
    check_rig(rig, origin)
    return rig
