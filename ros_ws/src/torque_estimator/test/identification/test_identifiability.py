"""What a record can tell (torque_estimator.identification.identifiability): the tolerance bands, the 95 % bands of
a least-squares fit, and which parameter is held first and why, on small synthetic Jacobians.

The Jacobians are made up, in the units the roads use (A per SI unit of the parameter; the NMRV030 rig file's
declared values set the bands): columns for a worm-shaft Coulomb drag (sign of the speed), a viscous drag (the
speed), K_t (the current itself), and what a test needs besides.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import norm

from worm_model.physics.parameters import load_rig
from worm_model.residuals.free import typical_coulomb_drag

from torque_estimator.identification.identifiability import (CONFIDENCE, OWN_BANDS, PARTNER_CORRELATION, Assessment,
                                                             RecordFacts, assess, tolerance_half_width)

RIG = load_rig()
N = 200
OMEGA = np.linspace(-340.0, 340.0, N)  # [rad/s] the points' worm speeds
NOISE = np.random.default_rng(0).normal(0.0, 0.01, N)  # [A] the fit's residual
COULOMB = np.sign(OMEGA) / RIG.drive_motor.torque_constant  # [A per N m] a worm-shaft Coulomb drag
VISCOUS = OMEGA / RIG.drive_motor.torque_constant  # [A per N m s/rad] its viscous drag
FACTS = RecordFacts(loads=2, speeds=8, accelerates=False, current_from_torque=False)
Z = norm.ppf(0.975)


def _columns(*columns: np.ndarray) -> np.ndarray:
    return np.column_stack(columns)


def test_tolerance_bands_around_the_declared_values() -> None:
    """Half the band: free.TOLERANCES' ratios (K_t x0.9..1.1, drags x0.4..2.5) around the declared value, the
    module's own for mu and the inertias, absolute around a declared 0 drag ([0, 2.5 x typical]); unbounded for a
    parameter without a band or an OWN_BANDS one declared 0."""
    kt, drag = RIG.drive_motor.torque_constant, RIG.drive_motor.coulomb_drag
    assert tolerance_half_width("drive_motor.torque_constant", kt, RIG) == pytest.approx(0.1 * kt)
    assert tolerance_half_width("drive_motor.coulomb_drag", drag, RIG) == pytest.approx(1.05 * drag)
    assert tolerance_half_width("friction.mu_constant", 0.05, RIG) == pytest.approx(1.05 * 0.05)
    assert OWN_BANDS["gearbox.gear_inertia"] == (0.2, 5.0)
    assert tolerance_half_width("gearbox.gear_inertia", 4.1e-5, RIG) == pytest.approx(2.4 * 4.1e-5)
    assert tolerance_half_width("drive_motor.coulomb_drag", 0.0, RIG) == pytest.approx(
        1.25 * typical_coulomb_drag(RIG.drive_motor))
    assert tolerance_half_width("load_motor.viscous_drag", 1.1e-5, RIG) == math.inf  # no band known
    assert tolerance_half_width("friction.mu_constant", 0.0, RIG) == math.inf
    assert tolerance_half_width("friction.mu_constant", -0.05, RIG) == pytest.approx(1.05 * 0.05)


def test_the_bands_are_the_least_squares_ones() -> None:
    """Half-width = z_0.975 sqrt(s^2 (J^T J)^-1_kk), s^2 the residual's variance on n - p degrees of freedom (times
    ``inflation``); correlations from the same covariance; each band around the declared value or ``values``."""
    names = ["drive_motor.coulomb_drag", "drive_motor.viscous_drag", "drive_motor.torque_constant"]
    current = 0.3 + 0.4 * np.abs(OMEGA) / 340.0
    jacobian = _columns(COULOMB, VISCOUS + 0.3 * COULOMB, current)
    a = assess(names, jacobian, NOISE, RIG)
    s2 = float(np.sum(NOISE ** 2)) / (N - 3)
    cov = np.linalg.inv(jacobian.T @ jacobian) * s2
    sd = np.sqrt(np.diag(cov))
    assert CONFIDENCE == 0.95
    for k, name in enumerate(names):
        assert a.half_width[name] == pytest.approx(Z * sd[k], rel=1e-9)
    np.testing.assert_allclose(a.correlation, cov / np.outer(sd, sd), atol=1e-9)
    assert a.band["drive_motor.torque_constant"] == pytest.approx(0.1 * RIG.drive_motor.torque_constant)
    inflated = assess(names, jacobian, NOISE, RIG, inflation=4.0)
    assert inflated.half_width[names[0]] == pytest.approx(2.0 * a.half_width[names[0]], rel=1e-9)
    other = assess(names, jacobian, NOISE, RIG, values={"drive_motor.coulomb_drag": 0.01})
    assert other.band["drive_motor.coulomb_drag"] == pytest.approx(1.05 * 0.01)
    assert other.band["drive_motor.viscous_drag"] == a.band["drive_motor.viscous_drag"]


def test_every_parameter_pinned_holds_nothing() -> None:
    """Bands well inside the tolerances (a Coulomb and a viscous drag on 200 points of both directions): nothing
    to hold."""
    a = assess(["drive_motor.coulomb_drag", "drive_motor.viscous_drag"], _columns(COULOMB, VISCOUS), NOISE, RIG)
    assert all(a.half_width[n] < 0.1 * a.band[n] for n in a.names)
    assert a.worst() is None


def test_a_band_wider_than_its_tolerance_is_held_and_named() -> None:
    """K_t seen only through a current of a few mA (its column 1000 x smaller than a real current's): its 95 %
    band exceeds +-10 % of the declared K_t, so it is held first, by its band, and its line says so; held (its
    column dropped and the rest reassessed, as the roads refit), nothing is left to hold."""
    names = ["drive_motor.coulomb_drag", "drive_motor.viscous_drag", "drive_motor.torque_constant"]
    faint = 1e-3 * (0.3 + 0.4 * np.abs(OMEGA) / 340.0)
    a = assess(names, _columns(COULOMB, VISCOUS, faint), NOISE, RIG)
    kt = "drive_motor.torque_constant"
    assert a.half_width[kt] > a.band[kt] and a.worst() == kt
    held = a.held(kt, FACTS)
    assert held.parameter == kt and held.reason == "band"
    assert held.line().startswith(f"not identifiable from this run: {kt} ")
    assert f"95 % band +-{a.half_width[kt]:.3g} wider than its tolerance +-{a.band[kt]:.3g}" in held.line()
    assert a.worst(["drive_motor.coulomb_drag", "drive_motor.viscous_drag"]) is None  # among the others: none
    refit = assess(names[:2], _columns(COULOMB, VISCOUS), NOISE, RIG)
    assert refit.worst() is None


def test_the_worst_ratio_goes_first() -> None:
    """Two bands over their tolerances: the one over by the larger factor is held first."""
    names = ["drive_motor.coulomb_drag", "drive_motor.viscous_drag"]
    a = assess(names, _columns(1e-4 * COULOMB, 1e-5 * VISCOUS), NOISE, RIG)
    ratio = {n: a.half_width[n] / a.band[n] for n in names}
    assert all(r > 1.0 for r in ratio.values())
    assert a.worst() == max(ratio, key=ratio.get)
    assert a.worst([min(ratio, key=ratio.get)]) == min(ratio, key=ratio.get)


def test_a_parameter_at_its_physical_bound_is_held_first() -> None:
    """A parameter the fit left on its bound is held before any band is judged (here K_t, whose band passes,
    before a viscous drag 10 x over its tolerance), with a line saying it was traded to its bound (against its
    partner when it has one: K_t's even column has none); a name not fitted is no bound."""
    names = ["drive_motor.coulomb_drag", "drive_motor.viscous_drag", "drive_motor.torque_constant"]
    current = 0.3 + 0.4 * np.abs(OMEGA) / 340.0
    kt = "drive_motor.torque_constant"
    a = assess(names, _columns(COULOMB, 1e-5 * VISCOUS, current), NOISE, RIG, at_bound=[kt, "load_motor.coulomb_drag"])
    assert a.at_bound == [kt]
    assert a.half_width[kt] < a.band[kt]  # its band passes
    assert a.half_width["drive_motor.viscous_drag"] > 10 * a.band["drive_motor.viscous_drag"]
    assert a.worst() == kt and a.worst(names[:2]) == "drive_motor.viscous_drag"
    held = a.held(kt, FACTS)
    assert held.reason == "bound" and "traded it to its physical bound" in held.line()
    assert a.partner(kt) is None and "against" not in held.line()

    pair = assess(names[:2], _columns(COULOMB, VISCOUS), NOISE, RIG, at_bound=["drive_motor.viscous_drag"])
    assert abs(pair.correlation[0, 1]) > PARTNER_CORRELATION  # sign and speed alike over these speeds
    line = pair.held("drive_motor.viscous_drag", FACTS).line()
    assert "traded it to its physical bound against drive_motor.coulomb_drag" in line


def test_two_parameters_the_data_move_alike_are_partners() -> None:
    """The worm's and the gear's Coulomb drags seen only through the same sign-of-speed column (to 0.1 % noise):
    correlation -1 (one traded against the other), each the other's partner, both bands several times their
    tolerances (8.6..20 x over seven draws of the 0.1 %), and the line names the pair and what would separate them.
    A third parameter uncorrelated with them has no partner."""
    names = ["drive_motor.coulomb_drag", "load_motor.coulomb_drag", "drive_motor.viscous_drag"]
    twin = 2.0 * COULOMB + np.random.default_rng(1).normal(0.0, 1e-3 * 2.0 / RIG.drive_motor.torque_constant, N)
    a = assess(names, _columns(COULOMB, twin, VISCOUS), NOISE, RIG)
    assert a.correlation[0, 1] < -0.999
    assert a.partner(names[0]) == names[1] and a.partner(names[1]) == names[0]
    assert a.partner(names[2]) is None and abs(a.correlation[0, 2]) < PARTNER_CORRELATION
    assert a.half_width[names[0]] > 5 * a.band[names[0]] and a.half_width[names[1]] > 5 * a.band[names[1]]
    worst = a.worst()
    assert worst in names[:2]
    line = a.held(worst, replace(FACTS, loads=1)).line()
    partner = names[1] if worst == names[0] else names[0]
    assert f"{worst} with {partner} (95 % band" in line and "1 load, held speeds" in line
    assert line.endswith("to separate them, record a second load")


def test_a_parameter_the_data_do_not_move_is_unbounded() -> None:
    """A zero column (nothing in the record moves with it): an infinite band, held first, its partner none."""
    names = ["drive_motor.coulomb_drag", "drive_motor.viscous_drag"]
    a = assess(names, _columns(COULOMB, np.zeros(N)), NOISE, RIG)
    assert a.half_width["drive_motor.viscous_drag"] == math.inf and a.worst() == "drive_motor.viscous_drag"
    assert math.isfinite(a.half_width["drive_motor.coulomb_drag"])
    assert a.partner("drive_motor.viscous_drag") is None


def test_an_effects_parameter_has_no_band() -> None:
    """A parameter outside the rig's sections (an effect's) has no declared value and no band: never held for it,
    however wide its band."""
    names = ["drive_motor.coulomb_drag", "viscous_drag.worm_torque"]
    a = assess(names, _columns(COULOMB, 1e-6 * VISCOUS), NOISE, RIG)
    assert a.band["viscous_drag.worm_torque"] == math.inf and a.worst() is None
    direct = Assessment.of(names, {n: 1.0 for n in names}, np.eye(2), RIG)
    assert direct.worst() == "drive_motor.coulomb_drag" and direct.band["viscous_drag.worm_torque"] == math.inf


@pytest.mark.parametrize("facts, hint", [
    (RecordFacts(1, 8, True, False), "record a second load"),
    (RecordFacts(2, 8, False, False), "record speed steps (the acceleration shows the inertias)"),
    (RecordFacts(2, 8, True, False, directions=1), "record both directions of rotation"),
    (RecordFacts(2, 3, True, False), "record more speeds"),
    (RecordFacts(3, 8, True, False), "record longer, or more loads and speeds"),
])
def test_the_hint_is_what_the_record_lacks_first(facts: RecordFacts, hint: str) -> None:
    """What a second record should add, in the order: a load, accelerations, a direction, speeds."""
    assert facts.hint() == hint


def test_the_record_described() -> None:
    assert RecordFacts(1, 8, False, False).describe() == "1 load, held speeds"
    assert RecordFacts(3, 8, True, False).describe() == "3 loads"
