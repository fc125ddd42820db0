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

The same ``effects`` section may also sit in a ``worm_rig_parameters`` file (the rig file, which
:func:`worm_model.physics.parameters.load_rig` skips; the residual analysis writes its extended model
so); :func:`load_effects` reads it from either. Effect names and parameters are the vocabulary's
(worm_model.effects.vocabulary). Every failure raises :class:`EffectsError`, whose message names the
file and the key.
"""
from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import worm_model.effects.vocabulary  # noqa: F401  (declares the built-in effects)
from worm_model.effects.parameters import parameter_value
from worm_model.effects.registry import VOCABULARY
from worm_model.errors import EffectsError, InputError
from worm_model.files.reading import load_yaml

FORMAT_NAME = "worm_rig_effects"
FORMAT_VERSION = 1
#: a rig parameter file (worm_model.physics.parameters) may carry an ``effects`` section too
RIG_FORMAT_NAME = "worm_rig_parameters"


@dataclass(frozen=True)
class EffectsConfig:
    """Which effects are on, with every parameter in its declared unit (defaults filled in).

    Build one with :func:`load_effects`, :meth:`from_mapping` or :meth:`defaults`; :meth:`section` is
    what a file's ``effects:`` holds. The simulator builds its live effects from one
    (worm_rig_driver.sim.effects.stack.build_stack).
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
            if name not in VOCABULARY:
                raise EffectsError(origin, where, f"unknown effect (known: {', '.join(VOCABULARY)})")
            section = {} if section is None else section
            if not isinstance(section, Mapping):
                raise EffectsError(origin, where, "expected a mapping of parameters (or {} for the defaults)")
            enabled = section.get("enabled", True)
            if not isinstance(enabled, bool):
                raise EffectsError(origin, where + ".enabled", f"expected true or false, got {enabled!r}")
            declared = VOCABULARY[name].parameters
            unknown = set(section) - set(declared) - {"enabled"}
            if unknown:
                raise EffectsError(origin, f"{where}.{sorted(unknown)[0]}",
                                   f"unknown parameter (known: {', '.join(declared)})")
            values = {key: float(p.default) for key, p in declared.items()}
            for key, raw in section.items():
                if key != "enabled":
                    values[key] = parameter_value(raw, declared[key], origin, f"{where}.{key}")
            if enabled:
                chosen[name] = values
        return cls(chosen, origin)

    @classmethod
    def defaults(cls, *names: str, **overrides: Mapping[str, Any]) -> "EffectsConfig":
        """The named effects at their defaults, plus ``overrides`` (effect -> {parameter: value})."""
        section: dict[str, Any] = {name: {} for name in names}
        section.update({name: dict(values) for name, values in overrides.items()})
        return cls.from_mapping(section, "<defaults>")

    def section(self) -> dict[str, dict[str, float]]:
        """The ``effects:`` mapping of a file: effect name -> {parameter: value in its declared unit}."""
        return {name: {key: float(value) for key, value in params.items()} for name, params in self.effects.items()}

    def to_dict(self) -> dict[str, Any]:
        """The file's document: format, version and the effects (values in declared units)."""
        return {"format": FORMAT_NAME, "version": FORMAT_VERSION, "effects": self.section()}


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


__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "RIG_FORMAT_NAME", "EffectsConfig", "as_config", "load_effects"]
