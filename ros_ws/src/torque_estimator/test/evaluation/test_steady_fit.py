"""The steady-point fit and residual selection (evaluation.steady_fit) on points our own model makes:
it recovers the parameters it was given, names the term that was planted, and names nothing when there is none."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import worm_model
from worm_model.physics.parameters import load_rig

from torque_estimator.evaluation.steady_fit import SteadyPoints, build, fit, halves, model_torque, select

RIG = load_rig(Path(worm_model.__file__).resolve().parent / "data" / "tro2021_worm_rig.yaml")
LOAD = 0.01884
RPM = np.array([1, 2, 4, 6, 8, 10, 13, 17, 20, 25, 30, 40, 50, 60, 70, 80, 90, 100, 120, 140, 160, 180, 200.0])
OMEGA = np.concatenate([RPM, -RPM]) * np.pi / 30
TRUE = {"friction.mu_constant": 0.10, "drive_motor.coulomb_drag": 6e-4, "drive_motor.viscous_drag": 1.5e-5,
        "load_motor.coulomb_drag": 3.5e-3, "gear_support_stribeck.torque": 0.012, "gear_support_stribeck.speed": 0.25}
NOISE = 2e-5  # [N m] on each point, about the real points' standard error


def points(structure: tuple[str, ...], values: dict[str, float], seed: int = 0) -> SteadyPoints:
    model = build(RIG, structure, {"friction.stribeck_rise": 0.0, **values})  # constant mu unless planted
    torque = model_torque(model, OMEGA, np.full(len(OMEGA), LOAD))
    torque = torque + np.random.default_rng(seed).normal(0.0, NOISE, len(OMEGA))
    return SteadyPoints(OMEGA, torque, np.full(len(OMEGA), NOISE), np.full(len(OMEGA), LOAD))


def test_halves_alternate_speeds_in_each_direction() -> None:
    half = halves(OMEGA)
    assert half[:23].tolist() == [0, 1] * 11 + [0] and half[23:].tolist() == half[:23].tolist()


def test_fit_recovers_the_parameters_it_was_given() -> None:
    sp = points(("gear_support_stribeck",), TRUE)
    fitted = fit(RIG, sp, ("gear_support_stribeck",))
    assert fitted.rms < 1.2 * NOISE
    for path, value in TRUE.items():
        assert fitted.values[path] == pytest.approx(value, rel=0.15), path


def test_selection_names_the_planted_term_and_only_it() -> None:
    selection = select(RIG, points(("gear_support_stribeck",), TRUE), ("tooth_stribeck", "gear_support_stribeck",
                                                                          "mode_dependent_mu"))
    assert selection.accepted == ["gear_support_stribeck"]
    assert not selection.unexplained


def test_selection_names_nothing_when_the_base_is_the_truth() -> None:
    base = {k: v for k, v in TRUE.items() if not k.startswith("gear_support")}
    selection = select(RIG, points((), base, seed=1), ("tooth_stribeck", "gear_support_stribeck",
                                                       "mode_dependent_mu"))
    assert selection.accepted == [] and selection.held_out[0] < 1.1 * selection.floor
