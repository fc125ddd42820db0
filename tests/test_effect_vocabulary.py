"""A new effect is added in one place: a toy declared here, at test time, with its two faces, is simulated, named by
the residual analysis and carried by the effects file, with no module of the simulator, of ``residuals`` or of the
file format edited (docs/design.md, "Adding an effect").

The toy is a gear-shaft torque ripple three times per gear turn (a three-jaw coupling), (A + f L) sin(3 theta_g + ph)
with L the mesh load: an order no built-in effect has (the case matrix keeps it as an effect outside the vocabulary).
Its simulator face steps it forward; its residual face is a regressor of the analysis's ripple family. Both read the
amplitude, load fraction and phase from the one declaration.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from worm_model.effects import VOCABULARY, Declaration, Parameter, load_effects, register, unregister
from worm_model.physics.parameters import load_rig
from worm_model.residuals.effects import EFFECTS as REGRESSORS
from worm_model.residuals.effects.ripples import _Ripple
from worm_model.residuals.extended import ExtendedModel, write_with_effects
from worm_model.residuals.settings import Settings
from worm_rig_driver.sim.effects import EFFECTS as HOOKS
from worm_rig_driver.sim.effects import EffectBase, main as worm_effects
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.evaluation.residual_cases.case import Case
from torque_estimator.evaluation.residual_cases.runner import run_case

TOY = "toy_gear_order3_ripple"
RIG = load_rig()
#: the ripple the cases simulate: 50 mN m on the gear shaft, as the case matrix's order-3 ripple on this rig
SIZE = {"amplitude": 0.05, "load_fraction": 0.0, "phase": 0.4}


class ToyHooks(EffectBase):
    """The simulator's face: gear torque (A + f mesh_load) sin(3 theta_gear + phase), + opposing + rotation."""

    name = TOY

    def gear_torque(self, s):
        return (self.p["amplitude"] + self.p["load_fraction"] * s.mesh_load) * np.sin(
            3.0 * s.theta_gear + self.p["phase"])


class ToyRegressor(_Ripple):
    """The analysis's face: the ripple family's regressor at order 3 of the gear angle."""

    name = TOY
    description = "torque ripple three times per gear turn"
    angle = "theta_gear"
    channel = "gear_torque"

    def orders(self, rig):
        return [3.0]


@pytest.fixture
def toy():
    register(Declaration(TOY, "gear torque ripple three times per gear turn (a three-jaw coupling)", {
        "amplitude": Parameter(0.0, "N m", "load-independent ripple amplitude on the gear shaft", "nonnegative"),
        "load_fraction": Parameter(0.0, "1", "ripple amplitude per unit of mesh load", "nonnegative"),
        "phase": Parameter(0.0, "rad", "phase of the ripple at theta_gear = 0"),
    }), simulator=ToyHooks, residuals=ToyRegressor())
    yield
    unregister(TOY)
    assert TOY not in VOCABULARY and TOY not in HOOKS and TOY not in REGRESSORS


def test_the_toy_is_in_the_effects_file(toy, tmp_path, capsys) -> None:
    path = tmp_path / "effects.yaml"
    path.write_text(yaml.safe_dump({"format": "worm_rig_effects", "version": 1,
                                    "effects": {TOY: {"amplitude": {"value": 30, "unit": "mN m"}}}}), encoding="utf-8")
    config = load_effects(path)
    assert config.effects == {TOY: {"amplitude": pytest.approx(0.03), "load_fraction": 0.0, "phase": 0.0}}
    assert load_effects(_written(tmp_path / "again.yaml", config.to_dict())).effects == config.effects
    assert worm_effects(["--list", "--template", "-", "--check", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"{TOY}: gear torque ripple three times per gear turn" in out  # --list, with the hook it changes
    assert "[changes: gear_torque]" in out.split(f"{TOY}:")[1].splitlines()[0]
    assert f"  {TOY}:  #" in out and "amplitude: {value: 0.0, unit: \"N m\"}" in out  # --template
    assert f"{TOY}: amplitude=0.03 N m, load_fraction=0, phase=0 rad" in out  # --check
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"format": "worm_rig_effects", "version": 1, "effects": {TOY: {"amplitude": -1}}}),
                   encoding="utf-8")
    with pytest.raises(ValueError, match=f"effects.{TOY}.amplitude: value -1 N m: must be >= 0"):
        load_effects(bad)


def _written(path, document):
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    return path


def test_the_simulator_steps_the_toy(toy) -> None:
    sims = [SimulatedRig(RIG, n=1, seed=3, effects=effects, scalar=False) for effects in ({TOY: SIZE}, None)]
    assert sims[0].effects.names == (TOY,)
    for sim in sims:
        sim.command(voltage_drive=np.array([12.0]), load_torque=np.array([0.1]))
    readings = [[sim.sample() for _ in range(800)] for sim in sims]
    toy_current, base_current = (np.array([r.current_drive[0] for r in rs[400:]]) for rs in readings)
    # a gear-side ripple of 50 mN m reaches the drive current (the same noise draws: the difference is the toy)
    assert np.ptp(toy_current - base_current) > 0.01


def test_the_residual_analysis_names_the_toy_and_the_extended_model_carries_it(toy, tmp_path) -> None:
    assert TOY in Settings().candidates and REGRESSORS[TOY].family == "periodic"
    result = run_case(Case(f"{TOY}/nominal", effects={TOY: SIZE}))
    assert result.found == (TOY,), result.found
    assert result.within_floor, (result.rms_after, result.floor)
    # the analysis's model file: the toy in the effects section, read back through the file format
    path = write_with_effects(tmp_path / "extended.yaml", {TOY: SIZE})
    model = ExtendedModel.load(path)
    assert model.names == [TOY]
    values, grid = model.effects[0][1], model.effects[0][2]
    assert math.hypot(values["amplitude_sin"], values["amplitude_cos"]) == pytest.approx(SIZE["amplitude"])
    assert grid["order"] == 3.0
