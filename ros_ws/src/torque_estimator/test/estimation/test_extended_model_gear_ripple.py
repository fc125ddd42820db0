"""extended_model with the worm angle: the gear runout's current is taken out.

A 0.5 s window at low speed covers a small part of a gear turn, so the once-per-gear-turn ripple
does not average out of it (nor out of a live estimate's 50 ms smoothing). Given the encoder's
worm angle, the estimator removes the table's first gear harmonic at that angle. Checked on the
model's own current (exact to the table's interpolation) and on steady windows of the
simulator with only gear runout on (its ripple is the simulator's plug-in, the estimator's the
residual model's Fourier coefficients of its own table).
"""

from __future__ import annotations

import numpy as np
import pytest

from torque_estimator.calibration.batch import DEFAULT_GAINS
from torque_estimator.calibration.operating_points import measure_operating_points
from torque_estimator.estimation.extended_model import ExtendedModelEstimator
from torque_estimator.estimation.live import LiveEstimator
from worm_model.physics.parameters import load_rig
from worm_model.residuals.extended import ExtendedModel, write_with_effects
from worm_rig_driver.drive.speed_loop import SpeedController
from worm_rig_driver.sim.simulated_rig import SimulatedRig

#: the simulator's default gear runout (effects_all.yaml), made 2x larger so it stands out of the noise
GEAR_RUNOUT = {"gear_runout": {"amplitude": 0.02, "load_fraction": 0.06, "phase": 0.7}}
RANGES = (340.0, -0.3, 0.3)


@pytest.fixture(scope="module")
def estimator(tmp_path_factory) -> ExtendedModelEstimator:
    path = write_with_effects(tmp_path_factory.mktemp("gear_ripple") / "rig.yaml", GEAR_RUNOUT)
    return ExtendedModelEstimator(model=ExtendedModel.load(path), ranges=RANGES)


def test_uses_angle_only_with_periodic_effects(estimator) -> None:
    assert estimator.uses_angle
    assert not ExtendedModelEstimator(model=ExtendedModel(load_rig(None)), ranges=RANGES).uses_angle


def test_removes_the_ripple_of_the_models_own_current(estimator) -> None:
    """Current of the model at known (omega, tau, theta): with the angle the error is the table's, without it
    the ripple's (0.02 + 0.06 |load| N m at the gear, i.e. up to ~5 % of a 0.6 N m range)."""
    rng = np.random.default_rng(0)
    n = 400
    omega = rng.choice([-1.0, 1.0], n) * rng.uniform(20.0, 300.0, n)
    tau = rng.uniform(-0.25, 0.25, n)
    theta = rng.uniform(0.0, 2 * np.pi / estimator.model.rig.gearbox.ratio, n)  # anywhere in a gear turn
    model = estimator.model
    current = model.current(model.signals(omega, 0.0, tau, theta, run=np.arange(n)))
    with_angle = estimator.estimate(omega, current, theta_worm=theta).torque - tau
    without = estimator.estimate(omega, current).torque - tau
    rms = lambda e: float(np.sqrt(np.mean(np.square(e[np.isfinite(e)]))))  # noqa: E731
    print(f"model's own current: rms error with the angle {rms(with_angle):.5f}, without {rms(without):.5f} N m")
    # measured (seed 0): 0.00198 with, 0.0195 without. What is left is near zero load, where the ripple moves
    # the mesh across the flank change and the current is not linear in it (|load| > 0.05 N m: 0.00105).
    assert rms(without) > 0.015
    assert rms(with_angle) < 0.0026


def test_window_of_angles_is_the_windows_mean_ripple(estimator) -> None:
    """A trailing axis of angles corrects by the window's mean ripple: equal to the mean current's estimate
    when the window's angles are all the same, and between the extremes otherwise."""
    model = estimator.model
    omega, tau = np.array([30.0, -60.0]), np.array([0.15, -0.1])
    theta = np.array([[1.0] * 5, [4.0] * 5]) / model.rig.gearbox.ratio
    current = model.current(model.signals(omega, 0.0, tau, theta[:, 0], run=np.arange(2)))
    windowed = estimator.estimate(omega, current, theta_worm=theta).torque
    single = estimator.estimate(omega, current, theta_worm=theta[:, 0]).torque
    np.testing.assert_allclose(windowed, single, atol=1e-12)


def test_simulated_windows_at_low_speed(estimator) -> None:
    """Steady 0.5 s windows of the simulator with gear runout on, at speeds where the window covers
    0.3-2 rad of the gear: the window's angles take the ripple out."""
    rig = load_rig(None)
    s, t = (a.ravel() for a in np.meshgrid([-60.0, -25.0, 25.0, 60.0], [-0.2, -0.05, 0.1, 0.2], indexing="ij"))
    sim = SimulatedRig(rig, n=len(s), seed=5, effects=GEAR_RUNOUT)
    points = measure_operating_points(sim, SpeedController(rig, DEFAULT_GAINS, n=len(s)), s, t)
    assert points.settled.all() and points.theta_worm is not None
    assert points.theta_worm.shape == (len(s), int(points.samples[0]))
    with_angle = estimator.estimate(points.omega_worm, points.current_drive, theta_worm=points.theta_worm)
    without = estimator.estimate(points.omega_worm, points.current_drive)
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    e_with, e_without = rms(with_angle.torque - points.tau_true), rms(without.torque - points.tau_true)
    print(f"simulated windows: rms error with the angles {e_with:.4f}, without {e_without:.4f} N m")
    # seed 5: 0.0047 with, 0.0196 without (the rest: noise, the current ADC's 26 mA step, flank changes)
    assert e_without > 0.015
    assert e_with < 0.006


def test_live_estimator_passes_the_angle(estimator) -> None:
    """LiveEstimator hands each sample's encoder angle to an estimator that uses it."""
    rig = estimator.model.rig
    model = estimator.model
    theta = 1.3 / rig.gearbox.ratio
    current = float(model.current(model.signals(np.array([40.0]), 0.0, np.array([0.2]), np.array([theta])))[0])
    results = {}
    for label, angle in (("with", theta), ("without", None)):
        live = LiveEstimator(rig, estimator, 1e-3, inertia_compensation=False)
        for _ in range(400):
            out = live.update(40.0, current, theta_worm=angle)
        results[label] = out.torque
    assert results["with"] == pytest.approx(0.2, abs=0.003)
    assert abs(results["without"] - 0.2) > 0.01
