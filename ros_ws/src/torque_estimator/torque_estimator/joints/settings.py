"""Per-joint estimator settings from estimator_node's parameters, on a robot's JointState.

One estimator per joint, each built by estimation.settings (build_estimator) as every other caller
builds its own. A robot's joints may differ (another gearbox, another identification): the file
parameters ``rig_files``, ``model_files``, ``calibration_files`` and ``voltage_topics`` are lists
parallel to ``joint_names``, the i-th entry for the i-th joint ("" for none); an empty list gives
every joint the single ``rig_file``, ``model_file``, ``calibration_file`` (and no voltage). The
method and its options are one for all joints.

A method that reads the drive voltage every sample (estimation.base.needs_voltage: the observer)
needs a ``voltage_topics`` entry for every joint; the others run from current and speed alone.
:data:`JOINT_STATE_METHOD` is the method estimator_node runs on JointState input unless told.

Errors are ValueError, one line naming the parameter (run_node: exit 2). No ROS.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from worm_model.cli.node_options import STRING_ARRAY, Option

from torque_estimator.estimation.base import needs_voltage
from torque_estimator.estimation.registry import METHODS
from torque_estimator.estimation.settings import EstimatorSettings

#: The method estimator_node runs on a JointState unless ``method`` says otherwise: one that needs no
#: calibration and no voltage.
JOINT_STATE_METHOD = "extended_model"

#: The per-joint list parameters (module docstring) -> the single parameter each falls back on.
PER_JOINT_FILES: dict[str, str] = {"rig_files": "rig_file", "model_files": "model_file",
                                   "calibration_files": "calibration_file"}

#: estimator_node's joint_state input's own parameters, besides the JointState input's
#: (worm_model.rig_data.joint_states.JOINT_STATE_OPTIONS).
JOINT_STATE_ESTIMATOR_OPTIONS: tuple[Option, ...] = (
    Option("voltage_topics", STRING_ARRAY, "Per joint (parallel to joint_names), a std_msgs/Float64 topic of the "
           "drive voltage [V] ('' for none): needed by a method that reads it (the observer)."),
    *(Option(name, STRING_ARRAY, f"Per joint (parallel to joint_names), its {single} ('' for none); empty: "
             f"{single} for every joint.") for name, single in PER_JOINT_FILES.items()),
    Option("publish_every", 5, "Publish the estimates of the JointStates stamped at every n-th sample period of the "
           "stamps' clock (5: 200 Hz from 1 kHz); every message is estimated.", low=1, high=100000),
)


@dataclass(frozen=True)
class JointSetup:
    """One joint: its name in the JointState, its estimator's settings, its voltage topic ("" for none)."""

    name: str
    settings: EstimatorSettings
    voltage_topic: str = ""


def per_joint(name: str, values: Sequence[str] | None, joints: Sequence[str], fallback: str = "") -> list[str]:
    """The list parameter ``name`` for each joint: its entries (one per joint), or ``fallback`` for all when it
    is empty or unset.

    Raises:
        ValueError: a list whose length is not the number of joints.
    """
    values = list(values or [])
    if not values:
        return [fallback] * len(joints)
    if len(values) != len(joints):
        raise ValueError(f"parameter {name}: {len(values)} entries for {len(joints)} joints {list(joints)} "
                         "(one per joint, in joint_names' order, or none)")
    return [str(v) for v in values]


def joint_setups(parameters: Mapping[str, Any], joint_names: Sequence[str],
                 voltage_topics: Sequence[str] | None = None,
                 files: Mapping[str, Sequence[str] | None] | None = None) -> list[JointSetup]:
    """Each joint's setup from estimator_node's parameters (``parameters``: the settings' own and the method's,
    as EstimatorSettings.from_parameters reads them; ``files``: the PER_JOINT_FILES lists by name).

    Raises:
        ValueError: no joints, a repeated one, a list of the wrong length, or a voltage-reading method
            without a voltage topic for every joint (one line naming the parameter).
    """
    joints = [str(j) for j in joint_names]
    if not joints or any(not j for j in joints):
        raise ValueError("parameter joint_names: name the joints to estimate (one or more, as in the JointState)")
    if len(set(joints)) != len(joints):
        raise ValueError(f"parameter joint_names: {joints} names a joint twice")
    base = EstimatorSettings.from_parameters(parameters)
    lists = {name: per_joint(name, (files or {}).get(name), joints, str(parameters.get(single) or ""))
             for name, single in PER_JOINT_FILES.items()}
    volts = per_joint("voltage_topics", voltage_topics, joints)
    if needs_voltage(METHODS[base.method].factory) and not all(volts):
        missing = [j for j, v in zip(joints, volts) if not v]
        raise ValueError(f"parameter method={base.method!r} reads the drive voltage every sample, and a JointState "
                         f"carries none: set voltage_topics for every joint (none for {missing}), or choose a method "
                         "that needs none "
                         f"({', '.join(m for m, row in METHODS.items() if not needs_voltage(row.factory))})")
    return [JointSetup(joint, replace(base, rig_file=lists["rig_files"][k], model_file=lists["model_files"][k],
                                      calibration_file=lists["calibration_files"][k]), volts[k])
            for k, joint in enumerate(joints)]


__all__ = ["JOINT_STATE_METHOD", "PER_JOINT_FILES", "JointSetup", "joint_setups", "per_joint"]
