"""The file ``identify`` writes: the rig file extended with what the record identified, loadable by every tool.

A ``worm_rig_parameters`` v1 file (worm_model.physics.parameters) that is the declared rig file with

* every identified leaf's value replaced and its ``source:`` saying so (``identified by identify from
  <record> (95 % CI +-x unit); declared <value> <unit>, <its source or assumption>``), a leaf the
  declared file left out (a support's low-speed rise) added, and the friction law the record chose
  (``friction.model``);
* the ``sensors:`` noise the record showed (identification.noise: the current's and the speed's white
  noise and grid step, the encoder's counts per turn), each with its ``source:``;
* ``free:`` (the identified parameters a refit can fit again), ``effects:`` (the effects found, in the vocabulary's
  names and units, as worm_model.residuals.extended writes them) and ``identification:`` (the road, the
  ranges the record covered, what was fitted and what was held and why).

Held parameters keep their declared leaves. Nothing is written at a physical bound (the
identifiability check held such a parameter). The text is loaded as every reader loads it
(``load_rig``, ``ExtendedModel.load``, the estimators' ``identification:`` ranges) before it is
written: a file identify cannot read back is never written.

No ROS.
"""
from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from worm_model.physics.parameters import default_rig_path, load_rig
from worm_model.physics.units import UNITS, normalize_unit
from worm_model.residuals.extended import ExtendedModel, effects_section
from worm_model.residuals.free import FREE_PARAMETERS, get_value

from torque_estimator.estimation.extended_model import identification_ranges

if TYPE_CHECKING:
    from torque_estimator.identification.fit import Identification

#: the SI unit written for a leaf the declared file does not have
NEW_LEAF_UNITS = {"stribeck_rise": ("N m", "1"), "stribeck_speed": ("rad/s", "m/s")}


def _si_to_unit(value: float, unit: str) -> float:
    factor, _dimension = UNITS[normalize_unit(unit)]
    return value / factor


def _shortened(text: str, limit: int = 120) -> str:
    return text if len(text) <= limit else text[: limit - 3].rstrip() + "..."


def _leaf(document: dict, path: str, value_si: float, text: str) -> None:
    """Set leaf ``path`` of ``document`` to ``value_si`` in the leaf's own unit (a new leaf: SI), ``source: text``
    plus what was declared."""
    section, name = path.split(".")
    node = document[section].get(name)
    if node is None:
        unit = NEW_LEAF_UNITS[name][1 if section == "friction" else 0]
        node = {"value": 0.0, "unit": unit, "assumption": "not in the declared file (0: none)"}
    unit = node["unit"]
    kind = "source" if "source" in node else "assumption"
    shown = f"{node['value']}" + ("" if unit == "1" else f" {unit}")
    before = f"declared {shown}, {kind}: {_shortened(str(node.get(kind, '')))}"
    node = {k: v for k, v in node.items() if k not in ("source", "assumption")}
    node["value"] = float(f"{_si_to_unit(value_si, unit):.6g}")
    node["source"] = f"{text}; {before}"
    document[section][name] = node


def _ci_text(provenance: str, unit: str, half: float) -> str:
    return f"{provenance} (95 % CI +-{_si_to_unit(half, unit):.2g} {unit})" if math.isfinite(half) else provenance


def document(rig_file: str | Path | None, ident: "Identification", source: str) -> dict[str, Any]:
    """The written file's document (module docstring)."""
    base = Path(rig_file) if rig_file else default_rig_path()
    doc = json.loads(json.dumps(yaml.safe_load(base.read_text(encoding="utf-8"))))  # no shared YAML anchors
    provenance = f"identified by identify from {source}"
    rig = ident.model.rig
    if rig.friction.model != ident.declared.friction.model:
        doc["friction"]["model"] = rig.friction.model
        if rig.friction.model != "stribeck":  # the declared law's leaves no other law reads
            for name in ("stribeck_rise", "stribeck_speed"):
                doc["friction"].pop(name, None)
    for path in ident.fitted:
        section, name = path.split(".")
        unit = (doc[section].get(name) or {}).get("unit") or NEW_LEAF_UNITS[name][1 if section == "friction" else 0]
        _leaf(doc, path, get_value(rig, path), _ci_text(provenance, unit, ident.corrections[path][2]))
    if ident.noise is not None:
        _sensors(doc, ident, f"measured on the record by identify from {source}")
    # the free list is what the next refit (identify or residuals --rig this file) may fit: the parameters the
    # time-series refit knows; the steady road's own (a support's low-speed rise) stay identified values only
    doc["free"] = [name for name in ident.fitted if name in FREE_PARAMETERS]
    doc["effects"] = effects_section(ident.model)  # an unphysical fit of an effect is left out (its docstring)
    doc["identification"] = ident.section(source)
    return doc


def _sensors(doc: dict, ident: "Identification", text: str) -> None:
    """The measured noise into ``sensors:`` (module docstring); a channel the record could not judge keeps its
    declared leaves."""
    noise = ident.noise
    sensors = doc["sensors"]
    current, speed = noise.current, noise.speed

    def put(name: str, value: float, unit: str, why: str) -> None:
        if not (math.isfinite(value) and value >= 0.0):
            return
        node = sensors.get(name) or {"value": 0.0, "unit": unit, "assumption": "not in the declared file"}
        kind = "source" if "source" in node else "assumption"
        before = f"declared {node['value']} {node['unit']}, {kind}: {_shortened(str(node.get(kind, '')), 80)}"
        sensors[name] = {"value": float(f"{_si_to_unit(value, node['unit']):.4g}"), "unit": node["unit"],
                         "source": f"{text}: {why}; {before}"}

    if math.isfinite(current.white):
        put("current_noise_std", current.white, "A", "the white part of the current's second difference")
        step = current.step if current.step is not None else max(current.white / 10.0, 1e-9)
        put("current_lsb", step, "A", "the grid its values fall on" if current.step is not None
            else "not quantised on the record (a step well below its noise)")
    if math.isfinite(speed.white):
        put("tacho_noise_std", speed.white, "rad/s", "the white part of the speed's second difference")
        step = speed.step if speed.step is not None else max(speed.white / 10.0, 1e-9)
        put("tacho_drive_lsb", step, "rad/s", "the grid its values fall on" if speed.step is not None
            else "not quantised on the record (a step well below its noise)")
    if noise.encoder_counts is not None:
        decoding = int((sensors.get("encoder_decoding") or {}).get("value", 1))
        counts = noise.encoder_counts
        if decoding < 1 or counts % decoding:
            decoding = 1
            put("encoder_decoding", 1.0, "1", "the counts per turn the angle showed, taken as decoded")
        put("encoder_pulses_per_rev", counts / decoding, "1",
            f"{counts} counts per turn on the angle's grid, {decoding}-fold decoding")


def text(rig_file: str | Path | None, ident: "Identification", source: str) -> str:
    """The file's text, header comment first."""
    header = (f"# Rig file extended by `identify` from {source} ({ident.road}).\n"
              "# Identified leaves say so in their source:, held ones keep what was declared (identification.held\n"
              "# says why); sensors: are the record's measured noise; effects: a worm_rig_effects section\n"
              "# (worm_effects --list names its parameters).\n")
    return header + yaml.safe_dump(document(rig_file, ident, source), sort_keys=False, allow_unicode=True, width=120)


def check_readable(path: Path) -> None:
    """Load ``path`` as every reader does (module docstring).

    Raises:
        ParameterError: what the reader refused.
    """
    load_rig(path)
    ExtendedModel.load(path)
    identification_ranges(path)


def write_identified(path: str | Path, rig_file: str | Path | None, ident: "Identification", source: str) -> None:
    """Write the extended rig file (module docstring), checked readable first.

    Raises:
        ParameterError: the file would not read back (nothing written then).
    """
    body = text(rig_file, ident, source)
    with tempfile.TemporaryDirectory() as folder:
        trial = Path(folder) / Path(path).name
        trial.write_text(body, encoding="utf-8")
        check_readable(trial)
    Path(path).write_text(body, encoding="utf-8")


__all__ = ["check_readable", "document", "text", "write_identified"]
