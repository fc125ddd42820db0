"""The health monitor's settings: priors of the fit, alarm limits, the thermal model, the live window.

One frozen dataclass per section, every field a number with its unit and meaning in the
dataclass's comments; :func:`load_settings` reads a YAML file ``worm_gearbox_health_settings`` v1
whose sections and keys are these (any may be left out: the default holds)::

    format: worm_gearbox_health_settings
    version: 1
    limits: {check_warn: 0.06, trend_warn: 0.03}
    thermal: {ambient: 22.0, thermal_resistance: 8.0}

Every default is an assumption, argued beside it; a maintenance engineer tunes the limits, not the
model. Bad files raise :class:`SettingsError` naming the file and the key.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace
from typing import Any

from worm_model.effects import VOCABULARY
from worm_model.errors import InputError, SettingsError
from worm_model.files.reading import load_yaml
from worm_model.health.points import PointRules

FORMAT_NAME = "worm_gearbox_health_settings"
FORMAT_VERSION = 1
#: the oil's declared defaults (worm_model.effects.vocabulary): the thermal model's and mu's temperature law's
_OIL = VOCABULARY["oil_temperature"]


@dataclass(frozen=True)
class Priors:
    """Standard widths of the fit's priors around the reference values (SI): what a check may move.

    Wide enough that a parameter the run excites is decided by the data; a parameter it does not
    excite stays at its reference with this width (and is reported as not identified).
    """

    mu_scale: float = 0.5  # [1]
    mu_speed_exponent: float = 0.3  # [1]
    mu_load_slope: float = 2.0  # [1/(N m)]
    drive_coulomb: float = 0.01  # [N m]
    drive_viscous: float = 1e-4  # [N m s/rad]
    gear_coulomb: float = 0.05  # [N m]
    gear_viscous: float = 2e-3  # [N m s/rad]
    torque_offset: float = 5e-3  # [N m]
    runout: float = 0.03  # [N m] on the gear shaft: a once-per-gear-turn ripple (wheel runout), sin and cos parts
    runout_load: float = 0.1  # [1] its part proportional to the mesh load, N m per N m
    #: what a gearbox's shape may drift from its baseline between two checks (fit.SHAPE; assess.watched_fit)
    drift_mu_speed_exponent: float = 0.02  # [1]
    drift_mu_load_slope: float = 0.1  # [1/(N m)]
    drift_gear_viscous: float = 3e-4  # [N m s/rad]
    #: [N m] added in quadrature to each point's standard error: the model's own error at a point
    #: (assumption: ~0.5 mA of drive current)
    model_floor: float = 3e-5


@dataclass(frozen=True)
class Limits:
    """When a change is an alarm: it must be both large (the limit) and sure (z = change / sigma >= z_min).

    Relative changes of the friction quantities against the baseline; the drags' at ``drag_speed``.
    Only rises alarm: wear raises friction; a fall is reported, never alarmed.
    """

    check_warn: float = 0.06  # [1] mu scale, one check
    check_error: float = 0.20  # [1]
    trend_warn: float = 0.03  # [1] mu scale, mean of the last trend_window checks
    trend_error: float = 0.15  # [1]
    trend_window: int = 4  # checks
    baseline_checks: int = 5  # the first checks of a gearbox's trend that make its baseline
    drag_warn: float = 0.5  # [1] drive or gear drag torque at drag_speed
    drag_error: float = 1.0  # [1]
    drag_floor: float = 2e-3  # [N m] a drag change smaller than this never alarms
    drag_speed: float = 200.0  # [rad/s] worm speed at which the drags are compared
    backlash_warn: float = 0.5  # [1] relative growth of the backlash
    backlash_error: float = 1.0  # [1]
    backlash_floor: float = 1.5e-3  # [rad] (~5 arcmin) a growth smaller than this never alarms
    z_min: float = 3.5  # [1] how sure: change / its standard uncertainty
    live_warn: float = 0.15  # [1] mu scale, live window
    live_error: float = 0.40  # [1]
    live_hold: float = 0.3  # [s] a live level must hold this long of rig time before it is raised or lowered


@dataclass(frozen=True)
class TemperaturePrior:
    """mu's temperature law before the baseline checks teach it (worm_model.health.model.TemperatureLaw)."""

    reference: float = 25.0  # [degC] the health parameters' reference temperature
    mu_per_kelvin: float = _OIL.default("mu_per_kelvin")  # [1/K] the oil effect's assumption: thinner, hotter oil
    # lowers mu (sign known, size not)
    sigma: float = 0.003  # [1/K] as wide as the value: the baseline checks decide it
    min_span: float = 10.0  # [K] baseline checks must span this much to learn k from them
    sensor_sigma: float = 0.5  # [K] standard uncertainty of a measured oil temperature


@dataclass(frozen=True)
class Thermal:
    """First-order thermal model of the gearbox (worm_model.health.thermal) for a drive without an oil sensor."""

    ambient: float = _OIL.default("ambient")  # [degC] assumption: a hall kept at 25 degC (the oil effect's ambient)
    ambient_sigma: float = 2.5  # [K] how far the hall's temperature may be from it
    # [K/W] and [s]: the oil effect's (worm_model.effects.vocabulary, THERMAL_RESISTANCE: why 5 K/W; to identify
    # with a sensor once)
    thermal_resistance: float = _OIL.default("thermal_resistance")
    time_constant: float = _OIL.default("time_constant")
    power_sigma: float = 0.25  # [1] relative uncertainty of the heat estimate and of the resistance, together
    initial_sigma: float = 3.0  # [K] how far the oil may be from the hall at a cold start (a cold night), decaying
    drive_drag_heat: float = 0.6  # [1] share of the worm-shaft drag that heats the oil (input seal, churning;
    # the rest is the motor's own: assumption from the rig file's split of the viscous drag, 2e-5 of 3e-5)
    gear_drag_heat: float = 0.0  # [1] share of the gear-shaft drag that heats the oil (the rig's is the load motors')


@dataclass(frozen=True)
class Live:
    """The live monitor's sliding window (worm_model.health.live)."""

    window: float = 1.5  # [s] of rig time
    block_time: float = 0.05  # [s]
    min_blocks: int = 6  # blocks in the window before a level is given
    settle: float = 0.3  # [s] left out after a change of speed or load (the speed loop's current settling)
    margin: float = 0.1  # [1] how far beyond the checked speeds and loads (relative to their span) a block may lie
    publish_period: float = 0.2  # [s]


@dataclass(frozen=True)
class HealthSettings:
    """Every section (module docstring)."""

    points: PointRules = field(default_factory=PointRules)
    priors: Priors = field(default_factory=Priors)
    limits: Limits = field(default_factory=Limits)
    temperature: TemperaturePrior = field(default_factory=TemperaturePrior)
    thermal: Thermal = field(default_factory=Thermal)
    live: Live = field(default_factory=Live)
    source: str = "defaults"


SECTIONS = ("points", "priors", "limits", "temperature", "thermal", "live")


def _section(cls: type, node: Any, origin: str, name: str) -> Any:
    if not isinstance(node, dict):
        raise SettingsError(f"{origin}: {name}", "expected a mapping of settings")
    known = {f.name: f for f in fields(cls)}
    values = {}
    for key, raw in node.items():
        if key not in known:
            raise SettingsError(f"{origin}: {name}.{key}", f"unknown setting (known: {', '.join(known)})")
        default = getattr(cls(), key)
        if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
            raise SettingsError(f"{origin}: {name}.{key}", f"expected a finite number, got {raw!r}")
        if isinstance(default, int) and not float(raw).is_integer():
            raise SettingsError(f"{origin}: {name}.{key}", f"expected a whole number, got {raw!r}")
        if raw < 0 and key not in ("mu_per_kelvin", "reference", "ambient"):
            raise SettingsError(f"{origin}: {name}.{key}", f"must be >= 0, got {raw!r}")
        values[key] = type(default)(raw)
    return replace(cls(), **values)


def load_settings(path: str | os.PathLike[str] | None) -> HealthSettings:
    """Settings from a ``worm_gearbox_health_settings`` v1 file; None: the defaults.

    Raises:
        SettingsError: unreadable file, wrong format or version, unknown section or key, a value
            that is not a finite number (or is negative where it cannot be).
    """
    if path is None:
        return HealthSettings()
    origin = str(path)
    try:
        document = load_yaml(path, "health settings file")
    except InputError as err:
        raise SettingsError(err.where, err.what) from None
    if not isinstance(document, dict):
        raise SettingsError(origin, "not a YAML mapping")
    if document.get("format") != FORMAT_NAME:
        raise SettingsError(f"{origin}: format", f"expected {FORMAT_NAME!r}, got {document.get('format')!r}")
    if document.get("version") != FORMAT_VERSION:
        raise SettingsError(f"{origin}: version", f"unsupported version {document.get('version')!r}")
    sections = {}
    for key, node in document.items():
        if key in ("format", "version"):
            continue
        if key not in SECTIONS:
            raise SettingsError(f"{origin}: {key}", f"unknown section (known: {', '.join(SECTIONS)})")
        cls = type(getattr(HealthSettings(), key))
        sections[key] = _section(cls, node, origin, key)
    return replace(HealthSettings(), **sections, source=origin)


__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "HealthSettings", "Limits", "Live", "Priors", "SECTIONS",
           "TemperaturePrior", "Thermal", "load_settings"]
