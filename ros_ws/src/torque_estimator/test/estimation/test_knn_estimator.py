"""k-NN estimator against synthetic calibration maps with a known truth.

The maps are a PMDC drive through a worm gear, both directions, on the
paper's 17 speeds × 16 load torques grid. In the frame of motion (σ = sign ω,
D = σ·τ_d):  K_t·|i| = T_0 + b·|ω| + load(D) / (G·η(|ω|)), η rising with
speed. MONOTONE has load(D) = D; V_SHAPED (self-locking, physics.md §8) has a
V around D_sw: assistive loads beyond D_sw also draw current.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pytest

from torque_estimator.estimation.database import CalibrationDatabase
from torque_estimator.estimation.base import EstimateFlags, TorqueEstimator
from torque_estimator.estimation.registry import ESTIMATORS, make_estimator
from torque_estimator.estimation.knn import KnnEstimator

SPEEDS = np.linspace(20.0, 340.0, 17)  # [rad/s]
K_T, T_0, B, G = 0.05, 0.02, 1e-4, 30.0  # [N·m/A], [N·m], [N·m·s/rad], ratio
D_SW = -1.0  # [N·m] switching torque of the V-shaped map
ASSIST_SLOPE = 0.7  # current per N·m on the assistive arm, relative to the resistive one

OUT = EstimateFlags.OUT_OF_CALIBRATION
AMBIGUOUS = EstimateFlags.AMBIGUOUS


@dataclass(frozen=True)
class Map:
    """A synthetic steady-state map: load(D) in the frame of motion, its torque grid."""

    load: Callable[[np.ndarray], np.ndarray]
    torques: np.ndarray  # [N·m], frame of motion

    def current(self, omega: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """i [A] for worm speed ω [rad/s] and load τ_d [N·m] (absolute frame)."""
        sigma = np.where(omega < 0, -1.0, 1.0)
        eta = 0.45 + 0.3 * np.abs(omega) / 340.0
        return sigma * (T_0 + B * np.abs(omega) + self.load(sigma * tau) / (G * eta)) / K_T

    @property
    def step(self) -> float:
        return float(self.torques[1] - self.torques[0])

    def database(self, directions: tuple[int, ...] = (1, -1), tau_std: float = 0.01) -> CalibrationDatabase:
        sigma, speed_i, torque_i = (a.ravel() for a in np.meshgrid(
            directions, np.arange(len(SPEEDS)), np.arange(len(self.torques)), indexing="ij"))
        omega, tau = sigma * SPEEDS[speed_i], sigma * self.torques[torque_i]
        n = len(omega)
        return CalibrationDatabase(
            omega_worm=omega, current_drive=self.current(omega, tau), tau_load=tau,
            omega_std=np.full(n, 0.5), current_std=np.full(n, 0.01), tau_std=np.full(n, tau_std),
            samples=np.full(n, 100), speed_setpoints=SPEEDS, torque_setpoints=self.torques,
            setpoint_index=np.column_stack((speed_i, torque_i)),
            rig={}, created="2024-01-01T00:00:00+00:00", steady_state={})

    def queries(self, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ω, i, true τ_d) uniformly inside the calibrated region, both directions."""
        rng = np.random.default_rng(seed)
        sigma = rng.choice([-1.0, 1.0], n)
        omega = sigma * rng.uniform(SPEEDS[0], SPEEDS[-1], n)
        tau = sigma * rng.uniform(self.torques[0], self.torques[-1], n)
        return omega, self.current(omega, tau), tau


MONOTONE = Map(load=lambda d: d, torques=np.linspace(-1.0, 4.0, 16))
V_SHAPED = Map(load=lambda d: np.where(d >= D_SW, d - D_SW, ASSIST_SLOPE * (D_SW - d)),
               torques=np.linspace(-3.0, 3.0, 16))


@pytest.fixture(scope="module")
def monotone() -> KnnEstimator:
    return KnnEstimator(MONOTONE.database())


@pytest.fixture(scope="module")
def v_shaped() -> KnnEstimator:
    return KnnEstimator(V_SHAPED.database())


def neighbours(est: KnnEstimator, db: CalibrationDatabase, omega: float, current: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """(indices into db, scaled distances) of the same-direction points, nearest first."""
    scale = np.array(est.feature_scale)
    candidates = np.flatnonzero(np.sign(db.omega_worm) == np.sign(omega))
    stored = np.column_stack((db.omega_worm, db.current_drive))[candidates] / scale
    dist = np.hypot(*(stored - np.array([omega, current]) / scale).T)
    order = np.argsort(dist)
    return candidates[order], dist[order]


def brute_force(est: KnnEstimator, db: CalibrationDatabase, omega: float, current: float
                ) -> tuple[float, float]:
    """Eqs 33–34 and the documented uncertainty, by hand, for one unambiguous query."""
    index, dist = neighbours(est, db, omega, current)
    w = 1.0 / dist[:est.k]
    w /= w.sum()
    tau, var = db.tau_load[index[:est.k]], db.tau_std[index[:est.k]] ** 2
    mean = float(w @ tau)
    return mean, float(np.sqrt(w @ ((tau - mean) ** 2 + var)))


def test_matches_hand_computed_knn_and_uncertainty(monotone: KnnEstimator) -> None:
    db = MONOTONE.database()
    for omega, current in [(150.0, 2.0), (-233.0, -5.1), (31.0, 0.4)]:
        est = monotone.estimate(omega, current)
        assert int(est.flags) == 0
        assert (float(est.torque), float(est.uncertainty)) == pytest.approx(
            brute_force(monotone, db, omega, current), rel=1e-9)


def test_held_out_queries_between_grid_points(monotone: KnnEstimator) -> None:
    omega, current, tau = MONOTONE.queries(2000)
    est = monotone.estimate(omega, current)
    error = est.torque - tau
    # stated accuracy: max 0.4 torque step, rms 0.15 step (observed 0.28, 0.08)
    assert np.max(np.abs(error)) < 0.4 * MONOTONE.step
    assert np.sqrt(np.mean(error ** 2)) < 0.15 * MONOTONE.step
    assert np.all(est.flags == 0)


def test_held_out_speed_row_via_subset() -> None:
    db = MONOTONE.database()
    held_out = db.setpoint_index[:, 0] == 8  # the middle speed, both directions
    est = KnnEstimator(db.subset(~held_out)).estimate(db.subset(held_out).omega_worm,
                                                      db.subset(held_out).current_drive)
    assert np.max(np.abs(est.torque - db.tau_load[held_out])) < 0.5 * MONOTONE.step
    assert np.all(est.flags == 0)


def test_stored_point_is_returned_exactly_with_its_spread(monotone: KnnEstimator) -> None:
    db = MONOTONE.database()
    est = monotone.estimate(db.omega_worm, db.current_drive)
    np.testing.assert_allclose(est.torque, db.tau_load, atol=1e-9)
    np.testing.assert_allclose(est.uncertainty, db.tau_std, rtol=1e-6)


def test_uniform_weighting_averages_the_neighbours() -> None:
    db = MONOTONE.database()
    est = make_estimator("knn", db, weighting="uniform").estimate(db.omega_worm[40], db.current_drive[40])
    assert abs(float(est.torque) - db.tau_load[40]) > 0.01 * MONOTONE.step
    assert float(est.uncertainty) > 5 * db.tau_std[40]


def test_feature_scaling_matters(monotone: KnnEstimator) -> None:
    # unscaled, ω [rad/s] swamps i [A]: all neighbours come from the nearest
    # speed row, whatever their current, and the estimate degrades
    omega, current, tau = MONOTONE.queries(2000)
    unscaled = KnnEstimator(MONOTONE.database(), feature_scale=(1.0, 1.0))

    def rms(e: KnnEstimator) -> float:
        return float(np.sqrt(np.mean((e.estimate(omega, current).torque - tau) ** 2)))

    assert rms(unscaled) > 3 * rms(monotone)
    assert np.max(np.abs(unscaled.estimate(omega, current).torque - tau)) > MONOTONE.step
    assert monotone.feature_scale[0] > 50 * monotone.feature_scale[1]


def test_out_of_calibration_far_outside_not_inside(monotone: KnnEstimator) -> None:
    omega, current, _ = MONOTONE.queries(500)
    assert not np.any(monotone.estimate(omega, current).flags & OUT)

    far_omega = np.array([700.0, -700.0, 150.0, 150.0, -150.0])
    far_tau = np.array([1.0, -1.0, 12.0, -8.0, -12.0])
    est = monotone.estimate(far_omega, MONOTONE.current(far_omega, far_tau))
    assert np.all(est.flags & OUT)
    assert np.all(np.isfinite(est.torque))  # still the nearest neighbours' value
    assert np.all(np.sign(est.torque) == np.sign(far_tau))


def test_direction_without_calibration_is_nan_and_out() -> None:
    est = KnnEstimator(MONOTONE.database(directions=(1,))).estimate([150.0, -150.0], [2.0, -2.0])
    assert np.isfinite(est.torque[0]) and est.flags[0] == 0
    assert np.isnan(est.torque[1]) and est.flags[1] == OUT


def test_v_shaped_map_is_ambiguous_and_not_averaged(v_shaped: KnnEstimator) -> None:
    db = V_SHAPED.database()
    d_assist = np.linspace(-2.9, -2.0, 10)  # frame of motion, far below D_SW
    d_resist = D_SW + ASSIST_SLOPE * (D_SW - d_assist)  # draws the same current
    for omega in [150.0, -233.0, 47.0]:
        sigma = np.sign(omega)
        currents = V_SHAPED.current(np.full(10, omega), sigma * d_assist)
        est = v_shaped.estimate(omega, currents)
        assert np.all(est.flags & AMBIGUOUS)
        assert np.all(est.uncertainty >= (d_resist - d_assist) / 2)
        # one branch, not their mean: close to one of the two true torques ...
        error = np.minimum(abs(est.torque - sigma * d_assist), abs(est.torque - sigma * d_resist))
        assert np.all(error < 0.5 * V_SHAPED.step)
        # ... and the branch of the nearest stored point
        nearest = [neighbours(v_shaped, db, omega, i)[0][0] for i in currents]
        assert np.array_equal(sigma * est.torque > D_SW, sigma * db.tau_load[nearest] > D_SW)


def test_monotone_map_is_never_ambiguous(monotone: KnnEstimator) -> None:
    omega, current, _ = MONOTONE.queries(4000, seed=3)
    assert not np.any(monotone.estimate(omega, current).flags & AMBIGUOUS)


def test_invalid_input_gives_nan_and_flag(monotone: KnnEstimator) -> None:
    est = monotone.estimate([np.nan, 150.0, np.inf, 150.0], [1.0, -np.inf, 1.0, 2.0])
    assert np.all(np.isnan(est.torque[:3])) and np.all(np.isnan(est.uncertainty[:3]))
    assert list(est.flags) == [EstimateFlags.INVALID_INPUT] * 3 + [0]
    scalar = monotone.estimate(np.nan, 1.0)
    assert np.isnan(scalar.torque) and scalar.flags == EstimateFlags.INVALID_INPUT


def test_output_shapes(monotone: KnnEstimator) -> None:
    assert monotone.estimate(150.0, 2.0).torque.shape == ()
    assert monotone.estimate([150.0, 160.0, 170.0], 2.0).flags.shape == (3,)
    assert monotone.estimate(np.full((2, 3), 150.0), np.full((2, 3), 2.0)).uncertainty.shape == (2, 3)


@pytest.mark.parametrize("options", [{}, {"k": 1}, {"k": 6, "weighting": "uniform"}])
@pytest.mark.parametrize("the_map", [MONOTONE, V_SHAPED], ids=["monotone", "v_shaped"])
def test_scalar_path_equals_batch_path(the_map: Map, options: dict[str, object]) -> None:
    est = KnnEstimator(the_map.database(directions=(1,)), **options)  # type: ignore[arg-type]
    omega, current, _ = the_map.queries(300, seed=5)
    omega = np.concatenate((omega, [np.nan, 900.0, 0.0, 0.0]))
    current = np.concatenate((current, [1.0, 1.0, 2.0, -2.0]))
    batch = est.estimate(omega, current)
    assert np.any(batch.flags & OUT) and np.any(batch.flags & EstimateFlags.INVALID_INPUT)
    assert np.any(batch.flags & AMBIGUOUS) == (the_map is V_SHAPED)
    one = [est.estimate(w, i) for w, i in zip(omega, current)]
    np.testing.assert_allclose([float(e.torque) for e in one], batch.torque, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose([float(e.uncertainty) for e in one], batch.uncertainty, rtol=1e-9, atol=1e-12)
    assert [int(e.flags) for e in one] == batch.flags.tolist()


def test_speed(monotone: KnnEstimator) -> None:
    best = min(_seconds(lambda: monotone.estimate(150.0, 2.0), 200) for _ in range(5))
    assert best < 100e-6
    omega, current, _ = MONOTONE.queries(100_000)
    assert _seconds(lambda: monotone.estimate(omega, current), 1) < 1.5


def _seconds(call: Callable[[], object], repeat: int) -> float:
    start = time.perf_counter()
    for _ in range(repeat):
        call()
    return (time.perf_counter() - start) / repeat


def test_registry_and_options() -> None:
    db = MONOTONE.database()
    est = make_estimator("knn", db, k=3)
    assert isinstance(est, KnnEstimator) and isinstance(est, TorqueEstimator)
    assert est.name == "knn" and est.k == 3 and "knn" in ESTIMATORS
    with pytest.raises(ValueError, match="knn"):
        make_estimator("kalman", db)
    for bad in [{"k": 0}, {"weighting": "gaussian"}, {"feature_scale": (1.0, 0.0)},
                {"ambiguity_ratio": -1.0}, {"outside_margin": float("nan")}]:
        with pytest.raises(ValueError, match=next(iter(bad))):
            KnnEstimator(db, **bad)  # type: ignore[arg-type]
