"""The ``worm_rig_effects`` file: its format, which effects are on with their parameters (checked), reading it.

File format ``worm_rig_effects``
--------------------------------
version 1 (current)::

    format: worm_rig_effects
    version: 1
    effects:
      tooth_pass: {load_fraction: 0.05}          # plain number: the parameter's own unit
      backlash: {angle: {value: 15, unit: arcmin}}
      oil_temperature: {}                        # every parameter at its default
      sensor_gain: {enabled: false}              # listed but off

The same ``effects`` section may also sit in a ``worm_rig_parameters`` file
(worm_model's rig file, which skips it); :func:`load_effects` reads it from either.
Every failure raises :class:`EffectsError`, whose message names the file and the key.
"""
from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from worm_model.errors import InputError
from worm_model.files.reading import load_yaml
from worm_model.physics.parameters import Rig, finite_number

from worm_rig_driver.errors import EffectsError
from worm_rig_driver.sim.effects.hooks import CHECKS, PLAUSIBLE, UNITS, Parameter
from worm_rig_driver.sim.effects.registry import EFFECTS
from worm_rig_driver.sim.effects.stack import EffectStack

FORMAT_NAME = "worm_rig_effects"
FORMAT_VERSION = 1
#: a rig parameter file (worm_model.physics.parameters) may carry an ``effects`` section too
RIG_FORMAT_NAME = "worm_rig_parameters"


def _parameter_value(raw: Any, declared: Parameter, origin: str, where: str) -> float:
    """A plain number (in the declared unit) or {value, unit[, note|source|assumption]}, checked."""
    if isinstance(raw, Mapping):
        unknown = set(raw) - {"value", "unit", "note", "source", "assumption"}
        if unknown or "value" not in raw:
            raise EffectsError(origin, where, "expected a number or a mapping {value, unit}"
                               + (f"; unknown keys {sorted(unknown)}" if unknown else ""))
        number = finite_number(raw["value"], origin, where, EffectsError)
        unit = str(raw.get("unit", declared.unit))
        if unit not in UNITS:
            raise EffectsError(origin, where, f"unknown unit {unit!r} (known: {', '.join(UNITS)})")
        factor, base = UNITS[unit]
        if base != declared.unit:
            raise EffectsError(origin, where, f"unit {unit!r} is not a {declared.unit!r}")
        number *= factor
    else:
        number = finite_number(raw, origin, where, EffectsError)
    predicate, message = CHECKS[declared.check]
    if not predicate(number):
        raise EffectsError(origin, where, f"value {number:g} {declared.unit}: {message}")
    limit = PLAUSIBLE[declared.unit]
    if abs(number) > limit:
        raise EffectsError(origin, where, f"value {number:g} {declared.unit} is far beyond any bench rig "
                                          f"(|value| <= {limit:g} {declared.unit})")
    return number


@dataclass(frozen=True)
class EffectsConfig:
    """Which effects are on, with every parameter in its declared unit (defaults filled in).

    Build one with :func:`load_effects`, :meth:`from_mapping` or :meth:`defaults`;
    :meth:`build` makes the live effects for a simulator of n rigs.
    """

    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    source: str = ""

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.effects)

    @classmethod
    def from_mapping(cls, effects: Mapping[str, Any] | None, origin: str = "<dict>") -> "EffectsConfig":
        """The ``effects`` section: effect name -> {parameter: value, ..., enabled: bool} (or null).

        Raises:
            EffectsError: unknown effect or parameter, bad value, unit or range.
        """
        if effects is None:
            return cls({}, origin)
        if not isinstance(effects, Mapping):
            raise EffectsError(origin, "effects", "expected a mapping effect name -> parameters")
        chosen: dict[str, dict[str, float]] = {}
        for name, section in effects.items():
            where = f"effects.{name}"
            if name not in EFFECTS:
                raise EffectsError(origin, where, f"unknown effect (known: {', '.join(EFFECTS)})")
            section = {} if section is None else section
            if not isinstance(section, Mapping):
                raise EffectsError(origin, where, "expected a mapping of parameters (or {} for the defaults)")
            enabled = section.get("enabled", True)
            if not isinstance(enabled, bool):
                raise EffectsError(origin, where + ".enabled", f"expected true or false, got {enabled!r}")
            declared = EFFECTS[name].parameters
            unknown = set(section) - set(declared) - {"enabled"}
            if unknown:
                raise EffectsError(origin, f"{where}.{sorted(unknown)[0]}",
                                   f"unknown parameter (known: {', '.join(declared)})")
            values = {key: float(p.default) for key, p in declared.items()}
            for key, raw in section.items():
                if key != "enabled":
                    values[key] = _parameter_value(raw, declared[key], origin, f"{where}.{key}")
            if enabled:
                chosen[name] = values
        return cls(chosen, origin)

    @classmethod
    def defaults(cls, *names: str, **overrides: Mapping[str, Any]) -> "EffectsConfig":
        """The named effects at their defaults, plus ``overrides`` (effect -> {parameter: value})."""
        section: dict[str, Any] = {name: {} for name in names}
        section.update({name: dict(values) for name, values in overrides.items()})
        return cls.from_mapping(section, "<defaults>")

    def build(self, n: int, rig: Rig) -> EffectStack:
        """Live effects (with their own state) for a simulator of n rigs."""
        return EffectStack([EFFECTS[name](params, n, rig) for name, params in self.effects.items()])

    def to_dict(self) -> dict[str, Any]:
        """The file's document: format, version and the effects (values in declared units)."""
        return {"format": FORMAT_NAME, "version": FORMAT_VERSION,
                "effects": {name: dict(params) for name, params in self.effects.items()}}


def load_effects(path: str | os.PathLike[str]) -> EffectsConfig:
    """Read the effects of a ``worm_rig_effects`` v1 file, or the ``effects`` section of a rig file.

    A ``worm_rig_parameters`` file (worm_model) may carry an optional top-level
    ``effects`` section in the same form; only that section is read here.

    Raises:
        EffectsError: unreadable file, wrong format or version, unknown effect or
            parameter, bad value, unit or range; the message names the file and the key.
    """
    origin = str(path)
    try:
        document = load_yaml(path, "effects file")
    except InputError as err:
        raise EffectsError(err.where, "", err.what) from None
    if not isinstance(document, Mapping):
        raise EffectsError(origin, "", "not a YAML mapping")
    if document.get("format") == RIG_FORMAT_NAME:
        return EffectsConfig.from_mapping(document.get("effects"), origin)
    if document.get("format") != FORMAT_NAME:
        raise EffectsError(origin, "format", f"expected {FORMAT_NAME!r} (or a {RIG_FORMAT_NAME!r} file with an "
                           f"'effects' section), got {document.get('format')!r}")
    if document.get("version") != FORMAT_VERSION:
        raise EffectsError(origin, "version", f"unsupported version {document.get('version')!r}")
    extra = set(document) - {"format", "version", "effects"}
    if extra:
        raise EffectsError(origin, sorted(extra)[0], "unknown key (expected format, version, effects)")
    return EffectsConfig.from_mapping(document.get("effects"), origin)


def as_config(effects: "EffectsConfig | Mapping[str, Any] | str | os.PathLike[str] | None") -> EffectsConfig:
    """Accept a config, an ``effects`` mapping, a file path, or None (no effects)."""
    if effects is None:
        return EffectsConfig()
    if isinstance(effects, EffectsConfig):
        return effects
    if isinstance(effects, Mapping):
        return EffectsConfig.from_mapping(effects)
    return load_effects(effects)
