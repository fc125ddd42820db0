"""Blocks and steady points: the same blocks from a recorded run and from samples one at a time; the
statistics they keep are the samples' (mean, slope, white-noise variance); points are the held segments."""
from __future__ import annotations

import numpy as np
import pytest
from fixtures.health_runs import PERIOD, check_segments, steady_run

from worm_model.health.blocks import BlockAccumulator, blocks_from_data
from worm_model.health.model import HealthParameters
from worm_model.health.points import PointRules, steady_points
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.schema import MeasuredData

RIG = load_rig()


def test_a_recorded_run_and_samples_one_at_a_time_give_the_same_blocks() -> None:
    data = steady_run(RIG, HealthParameters.from_rig(RIG), [(100.0, 0.1), (-200.0, -0.2)], hold=0.5,
                      gap=0.004, temperature=31.0)
    recorded = blocks_from_data(data, RIG.gearbox.ratio)
    acc = BlockAccumulator(2, PERIOD, RIG.gearbox.ratio)
    for k in range(len(data)):  # the same run twice side by side, as a batch of two rigs
        pair = lambda x: np.array([x[k], x[k]])  # noqa: E731, B023 - used only within this iteration
        acc.add(data.t[k], pair(data.omega_worm), pair(data.current_drive), pair(data.tau_load),
                pair(data.theta_worm), pair(data.theta_gear), pair(data.temperature))
    streamed = acc.blocks().rig(1)
    assert len(recorded) == len(streamed) == 20
    for name in ("omega", "alpha", "current", "current_var", "current_noise", "tau_load", "gear_sin", "gear_cos", "te",
                 "temperature"):
        np.testing.assert_allclose(getattr(streamed, name), getattr(recorded, name), rtol=1e-12, atol=1e-15,
                                   err_msg=name)


def test_block_statistics_are_the_samples() -> None:
    n = 5000
    t = np.arange(n) * PERIOD
    rng = np.random.default_rng(1)
    omega = 50.0 + 20.0 * t  # a 20 rad/s^2 ramp
    current = 0.3 + rng.normal(0.0, 0.02, n)
    data = MeasuredData(t=t, current_drive=current, omega_worm=omega, theta_worm=np.cumsum(omega) * PERIOD,
                        tau_load=np.full(n, 0.1))
    blocks = blocks_from_data(data, RIG.gearbox.ratio)
    np.testing.assert_allclose(blocks.alpha, 20.0, rtol=1e-9)
    np.testing.assert_allclose(blocks.omega, omega.reshape(-1, 50).mean(1), rtol=1e-12)
    assert np.mean(blocks.current_noise) == pytest.approx(0.02 ** 2, rel=0.05)  # the white noise's variance
    assert np.all(np.isnan(blocks.te)) and np.all(np.isnan(blocks.temperature))
    assert blocks.one_way.all()


def test_steady_points_are_the_held_segments_without_their_settling() -> None:
    segments = check_segments(RIG)
    data = steady_run(RIG, HealthParameters.from_rig(RIG), segments, seed=2)
    rules = PointRules()
    points = steady_points(blocks_from_data(data, RIG.gearbox.ratio), RIG, rules)
    assert len(points) == len(segments)
    np.testing.assert_allclose(points.omega, [w for w, _ in segments])
    np.testing.assert_allclose(points.tau_load, [d for _, d in segments])
    assert np.all(points.duration == pytest.approx(0.8 - rules.settle * 0.05))
    # the standard error: the white noise over sqrt(samples), times loop_noise
    expected = rules.loop_noise * RIG.drive_motor.torque_constant * 0.02 / np.sqrt(700)
    # (the estimate of a sigma from 700 samples has a relative sd of 2.7 %)
    np.testing.assert_allclose(points.torque_sigma, expected, rtol=0.12)


def test_transients_and_slow_speeds_make_no_point() -> None:
    n = 3000
    t = np.arange(n) * PERIOD
    omega = np.where(t < 1.0, 200.0 * t, np.where(t < 2.0, 2.0, 200.0))  # a ramp, a crawl, then held
    data = MeasuredData(t=t, current_drive=np.full(n, 0.2), omega_worm=omega, theta_worm=np.cumsum(omega) * PERIOD,
                        tau_load=np.zeros(n))
    points = steady_points(blocks_from_data(data, RIG.gearbox.ratio), RIG)
    assert len(points) == 1 and points.omega[0] == pytest.approx(200.0)
