"""The rig files of the residual case matrix: the rigs it simulates and the file it gives the analysis.

:data:`RIGS` names the rig files the matrix uses (the bundled NMRV030 and the NMRV040 variant, each under
a friction model); :func:`plant_rig` is the simulated rig of one.  :func:`write_rig_file` writes the rig
file a user writes: the rig's own file with its declared numbers off by realistic amounts
(:data:`PERTURBATIONS`: mu +-30 %, K_t +-5 %, drags x2 / x0.5, inertias +-20 %, the oil reference
temperature +-15 K; mu 25 % and K_t 3 % high as copied from a catalogue; drags declared 0), every changed
number carrying a ``source:`` (a catalogue value) instead of its ``assumption:``.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from pathlib import Path

import yaml

from worm_model.physics.parameters import Rig, default_rig_path, load_rig
from worm_model.residuals.free import get_value, mu_parameter, set_values

#: rig files the matrix uses: key -> (file in worm_model/data, friction model written into it, None: the file's)
RIGS: dict[str, tuple[str, str | None]] = {
    "nmrv030": ("nmrv030_rig.yaml", None),  # the bundled rig: AGMA friction
    "nmrv030_constant": ("nmrv030_rig.yaml", "constant"),  # the same rig, mu a constant (the file's 0.05)
    "nmrv040": ("nmrv040_rig.yaml", None),  # the variant rig: constant mu 0.06
    "nmrv040_agma": ("nmrv040_rig.yaml", "agma"),  # the variant rig under the AGMA curve
    "nmrv030_stribeck": ("nmrv030_rig.yaml", "stribeck"),  # the bundled rig, mu a Stribeck law (FRICTION_LEAVES)
}

#: friction leaves a RIGS key writes into its file beside the model: leaf -> (value [SI], assumption)
FRICTION_LEAVES: dict[str, dict[str, tuple[float, str]]] = {
    "nmrv030_stribeck": {
        "stribeck_rise": (0.03, "a Stribeck rise of 60 % of the file's kinetic 0.05, as a lubricated bronze mesh "
                                "shows at low sliding speed (the residual case matrix's choice)"),
        "stribeck_speed": (0.3, "V_st 0.3 m/s: the rise is felt over the lower third of the rig's 0.2-3.4 m/s "
                                "sliding speeds, so the profiles' speeds see it (the residual case matrix's choice)"),
    },
}

#: declared-value errors: factor on the rig file's value (the simulated rig keeps the file's values);
#: "mu" is the friction model's mu parameter (free.MU_PARAMETERS); "reference_temperature" is an offset [K]
#: of the oil temperature at which the tool assumes the declared mu; a factor 0 declares the value 0
PERTURBATIONS: dict[str, dict[str, float]] = {
    "nominal": {},
    "high": {"mu": 1.3, "torque_constant": 1.05, "drags": 2.0, "inertia": 1.2, "reference_temperature": 15.0},
    "low": {"mu": 0.7, "torque_constant": 0.95, "drags": 0.5, "inertia": 0.8, "reference_temperature": -15.0},
    # mu and K_t copied from a catalogue: mu 25 % and K_t 3 % high, both with a source
    "catalogue": {"mu": 1.25, "torque_constant": 1.03},
    # no drag known, so none declared: every drag 0 (with a source: "none measured")
    "zero_drags": {"drags": 0.0},
}

_DRAGS = ("drive_motor.coulomb_drag", "drive_motor.viscous_drag", "load_motor.coulomb_drag", "load_motor.viscous_drag")
_INERTIAS = ("drive_motor.rotor_inertia", "gearbox.worm_inertia", "gearbox.gear_inertia")


def perturbed_parameters(rig: Rig, perturbation: Mapping[str, float]) -> dict[str, float]:
    """Dotted rig parameter -> factor on its value, for the groups of a perturbation (:data:`PERTURBATIONS`)."""
    out: dict[str, float] = {}
    for key, factor in perturbation.items():
        if key in ("mu", "friction.scale"):  # "friction.scale": the AGMA name of mu, as older callers wrote it
            out[mu_parameter(rig.friction.model)] = factor
        elif key == "torque_constant":  # K_e equals K_t in SI: a user who has one wrong has both
            out.update({"drive_motor.torque_constant": factor, "drive_motor.back_emf_constant": factor})
        elif key == "drags":
            out.update(dict.fromkeys(_DRAGS, factor))
        elif key == "inertia":
            out.update(dict.fromkeys(_INERTIAS, factor))
        elif key != "reference_temperature":
            raise KeyError(f"unknown perturbation group {key!r}")
    return out


def declared_rig(rig: Rig, perturbation: Mapping[str, float]) -> Rig:
    """``rig`` with its declared numbers off by ``perturbation`` (the groups of :data:`PERTURBATIONS`)."""
    factors = perturbed_parameters(rig, perturbation)
    return set_values(rig, list(factors), [get_value(rig, n) * f for n, f in factors.items()])


def rig_path(key: str) -> Path:
    """The file of a :data:`RIGS` key."""
    return default_rig_path().parent / RIGS[key][0]


def plant_rig(key: str, plant: Mapping[str, float] = {}) -> Rig:  # noqa: B006 (read only)
    """The simulated rig of a :data:`RIGS` key: its file's values under the key's friction model, then
    ``plant`` (perturbation groups, factors on the file's values) where the plant differs from its file."""
    rig = load_rig(rig_path(key))
    model = RIGS[key][1]
    if model is not None:
        leaves = {leaf: value for leaf, (value, _) in FRICTION_LEAVES.get(key, {}).items()}
        rig = dataclasses.replace(rig, friction=dataclasses.replace(rig.friction, model=model, **leaves))
    return declared_rig(rig, plant)


def write_rig_file(path: str | Path, key: str, perturbation: Mapping[str, float],
                   source: str = "catalogue value") -> Path:
    """The rig file a user writes: the key's file (its friction model set) with the numbers of ``perturbation``
    changed, each then carrying ``source:`` (``source``) instead of its ``assumption:``; loadable by load_rig."""
    base = rig_path(key)
    document = json.loads(json.dumps(yaml.safe_load(base.read_text(encoding="utf-8"))))  # no shared YAML anchors
    model = RIGS[key][1]
    if model is not None:
        document["friction"]["model"] = model
        for leaf, (value, why) in FRICTION_LEAVES.get(key, {}).items():
            document["friction"][leaf] = {"value": value, "unit": "m/s" if leaf == "stribeck_speed" else "1",
                                          "assumption": why}
    rig = plant_rig(key)
    for name, factor in perturbed_parameters(rig, perturbation).items():
        section, leaf = name.split(".")
        node = document[section][leaf]
        node["value"] = float(f"{float(node['value']) * factor:.6g}")
        node.pop("assumption", None)
        node["source"] = (f"{source} (the residual case matrix declares x{factor:g} the simulated rig's value)"
                          if factor else f"{source}: none measured, declared 0")
    Path(path).write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return Path(path)
