"""The momentum observer (torque_estimator.estimation.momentum/): the load from current and speed only, no voltage.

The issue's targets on the NMRV030 simulated rig, from current and velocity only: 90 % of a load step in
<= 5 ms, held-out mean <= 1.0 % of the range. The simulator runs the rig file's model, which the
observer also uses. Tolerances from the runs noted in each test (evaluation.transient's seeds).
"""
from __future__ import annotations

import inspect
import math
from dataclasses import replace

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig

from torque_estimator.calibration.batch import CalibrationGrid
from torque_estimator.estimation.base import EstimateFlags, StreamingEstimator
from torque_estimator.estimation.live import LiveEstimator
from torque_estimator.estimation.momentum import (DEFAULT_BANDWIDTH, MomentumEstimator, MomentumObserver, jump_bound,
                                                  linear_noise_bound, predicted_noise, steady_filter)
from torque_estimator.estimation.momentum.bounds import linearised
from torque_estimator.estimation.observer import NoiseFigures, StaticLoadMap
from torque_estimator.estimation.observer.streams import WithoutEncoder
from torque_estimator.estimation.registry import METHODS, make_estimator
from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
from torque_estimator.evaluation.held_out import held_out_setpoints, measure_held_out, score
from torque_estimator.evaluation.observer_study import held_out_streaming, run_observers
from torque_estimator.evaluation.transient import ensemble_noise, transient_figures

RIG = load_rig()
RANGE = 0.495  # [N m] the paper grid's calibrated range
#: the momentum observer as estimator_node builds it (no calibration)
MOMENTUM = build_estimator(EstimatorSettings("momentum"))
GRID = CalibrationGrid.paper(RIG)


def test_the_registry_row_and_the_builder() -> None:
    """A method of the registry like the others: its options declared there (defaults = the class's), no voltage
    read, built by the one builder, run by LiveEstimator as a stream."""
    row = METHODS["momentum"]
    assert {o.name for o in row.options} == {"bandwidth", "false_alarm", "load_min", "load_max"}
    assert row.reads_model_file and not row.needs_calibration and not row.reads_voltage
    assert METHODS["observer"].reads_voltage and not METHODS["knn"].reads_voltage
    signature = inspect.signature(MomentumEstimator).parameters
    for option in row.options:
        assert signature[option.name].default == option.default and option.low <= option.default <= option.high
        assert option.description
    built = build_estimator(EstimatorSettings("momentum", options={"bandwidth": 2.0, "false_alarm": 0.0}))
    assert isinstance(built.estimator, StreamingEstimator)
    live = built.live(1e-3)
    assert isinstance(live.stream, MomentumObserver) and live.stream.bandwidth == 2.0 and live.stream.detector is None
    with pytest.raises(ValueError, match="does not read input_filter"):
        EstimatorSettings("momentum", options={"input_filter": 0.1})
    with pytest.raises(ValueError, match="bandwidth"):
        MomentumEstimator(None, bandwidth=0.0)


def test_it_never_reads_the_voltage() -> None:
    """The same run (load steps, a reversal) fed the applied voltage, NaN, or garbage for it: the same estimates,
    bit for bit."""
    samples = _samples(800)
    rng = np.random.default_rng(3)
    estimates = {}
    for name in ("applied", "nan", "garbage"):
        live = LiveEstimator(RIG, make_estimator("momentum", None), 1e-3)
        voltages = {"applied": [v for _w, _i, v, _th in samples], "nan": [math.nan] * len(samples),
                    "garbage": rng.normal(0.0, 50.0, len(samples)).tolist()}[name]
        estimates[name] = [live.update(w, i, voltage_drive=v, theta_worm=th)
                           for (w, i, _v, th), v in zip(samples, voltages)]
    assert estimates["applied"] == estimates["nan"] == estimates["garbage"]
    assert math.isfinite(estimates["nan"][-1].torque)


def _samples(count: int) -> list[tuple[float, float, float, float]]:
    """(ω, i, V, θ) of one simulated rig under its PI: 150 rad/s, reversing at 0.5 s; 0.1 N m, -0.15 from 0.3 s."""
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController
    from worm_rig_driver.sim.simulated_rig import SimulatedRig
    sim = SimulatedRig(RIG, n=1, seed=4)
    controller = SpeedController(RIG, DEFAULT_GAINS, n=1)
    out = []
    for k in range(count):
        t = k * sim.sample_period
        sim.command(load_torque=0.1 if t < 0.3 else -0.15)
        m = sim.sample()
        sim.command(voltage_drive=controller.update(sim.sample_period, 150.0 if t < 0.5 else -150.0,
                                                    m.omega_worm).voltage)
        out.append((float(m.omega_worm[0]), float(m.current_drive[0]), float(m.voltage_drive[0]),
                    float(m.theta_worm[0])))
    return out


def test_the_targets_from_current_and_velocity_only() -> None:
    """The issue's targets (no calibration; the transient table's experiments, voltage not fed): 90 % of a 0.2 N m
    step in <= 5 ms (measured 4 ms, overshoot 21.7 %: the step detector's estimate from 3-4 samples), the
    reversal and the ramp within 1 % of the range (measured 0.33 % and 0.20 %); without the encoder angle,
    5 ms (overshoot 11.5 %, reversal 0.41 %). The steady noise (0.2 s windows) 4.9e-4 N m."""
    f = transient_figures(RIG, MOMENTUM, RANGE, seeds=12, seed=0)
    assert f.step90_ms <= 5 and f.step90_ms == 4, f
    assert 10 < f.overshoot_pct < 35 and f.reversal_err_pct < 1.0 and f.ramp_err_pct < 0.5, f
    assert f.steady_std < 1e-3, f
    blind = transient_figures(RIG, replace(MOMENTUM, estimator=WithoutEncoder(MOMENTUM.estimator)), RANGE, seeds=12)
    assert blind.step90_ms <= 5 and blind.reversal_err_pct < 1.0 and blind.overshoot_pct < 35, blind


def test_the_reversal_needs_the_hold_off(monkeypatch) -> None:
    """Without resting the step detector where the model does not hold, the reversal is read as load steps: the
    reversal error of the transient table goes from 0.33 % to 4.43 % of the range (momentum.observer's docstring)."""
    monkeypatch.setattr(MomentumObserver, "_model_holds", lambda self, *args: True)
    f = transient_figures(RIG, MOMENTUM, RANGE, seeds=12, seed=0)
    assert f.reversal_err_pct == pytest.approx(4.43, abs=0.01), f


def test_held_out_mean_within_one_percent() -> None:
    """The 17 held-out points of make evaluate: the quasi-static inverse (held_out.score; the observer's, the same
    model) and the stream itself held at each point, averaged over its last 0.5 s. Measured: 0.25 / 0.93 % and
    0.18 / 0.45 % (mean / max)."""
    ev = score(make_estimator("momentum", None), measure_held_out(RIG, GRID, 17, 1), RANGE)
    assert ev.mae_pct <= 1.0 and ev.max_pct < 2.0, (ev.mae_pct, ev.max_pct)
    speeds, torques = held_out_setpoints(GRID, 17, 1)
    est, truth = held_out_streaming(RIG, speeds, torques, estimator=make_estimator("momentum", None))
    error = 100 * np.abs(est - truth) / RANGE
    assert error.mean() <= 1.0 and error.max() < 1.0, error


def test_a_fast_linear_observer_is_a_noisy_one() -> None:
    """Why steps are detected, not followed: any linear estimator (De Luca's fixed-gain residual, the filter at a
    fixed bandwidth) whose mean reaches 90 % of a step 5 samples after it has a noise of at least 0.9 x the
    Cramér–Rao bound on the step after 5 samples: 0.0221 N m with the encoder, 0.049 without (4.5 % and 9.9 %
    of the range). The filter without detection, at the bandwidth that gets there, is above that floor; the
    detecting observer's noise is 1/20 of it."""
    floor = linear_noise_bound(RIG, 150.0, 0.0, 5)
    assert floor == pytest.approx(0.0221, rel=0.02)
    assert linear_noise_bound(RIG, 150.0, 0.0, 5, with_encoder=False) == pytest.approx(0.049, rel=0.02)
    sigma = 100 * jump_bound(RIG, 150.0, 0.1, 5) / 0.2  # the step's size, 1 sigma in % of it
    assert [round(s) for s in sigma] == [87, 39, 24, 16, 12]
    noise = NoiseFigures.from_rig(RIG)
    for bandwidth in (10.0, 30.0, 100.0, 300.0):  # the linear filter's own 90 % time at each bandwidth
        phi, k, _pf, _pp = steady_filter(RIG, 150.0, 0.0, 1e-3, noise, bandwidth)
        h = linearised(RIG, 150.0, 0.0, 1e-3, noise, bandwidth)[3]
        err, covered = phi[:, -1].copy(), []
        for _ in range(40):
            err = (np.eye(3) - k @ h) @ err
            covered.append(1.0 - err[-1])
            err = phi @ err
        if covered[4] >= 0.9:
            break
    assert covered[4] >= 0.9 and predicted_noise(RIG, 150.0, 0.0, bandwidth) >= floor, bandwidth
    detecting = ensemble_noise(RIG, MOMENTUM, seeds=6)
    assert detecting < floor / 20


def test_bandwidth_is_the_slowest_pole() -> None:
    """discrete.load_variance: the steady filter's slowest pole sits at 2π x bandwidth (tacho alone, the relation's
    case); the current's noise makes the 2-state filter overdamped below ~17 Hz on this rig, hence not the
    Butterworth ω0 = (q/R)^(1/4)."""
    noise = NoiseFigures.from_rig(RIG)
    for bandwidth in (0.5, 2.0, 8.0):
        phi, k, _pf, _pp = steady_filter(RIG, 150.0, 0.0, 1e-3, noise, bandwidth, with_encoder=False)
        h = linearised(RIG, 150.0, 0.0, 1e-3, noise, bandwidth, with_encoder=False)[3]
        slowest = max(abs(np.linalg.eigvals((np.eye(2) - k @ h) @ phi)))
        assert -math.log(slowest) / 1e-3 == pytest.approx(2 * math.pi * bandwidth, rel=0.1), bandwidth


def test_noise_as_predicted() -> None:
    """On a constant load the estimate's spread across seeds is the steady filter's predicted noise (measured
    1.00e-3 against 0.97e-3 N m at the default 0.5 Hz; the filter's ripple states and the encoder's
    quantisation, white in the prediction, account for the rest)."""
    measured = ensemble_noise(RIG, MOMENTUM, seeds=12)
    assert measured / predicted_noise(RIG, 150.0, 0.0, DEFAULT_BANDWIDTH) == pytest.approx(1.0, abs=0.2)


def test_invalid_input_missing_angle_and_standstill() -> None:
    """NaN current or speed: flagged INVALID_INPUT, the estimate held, no exception; a NaN angle is a sample without
    the encoder (not invalid); a standing worm keeps the estimate it had (static friction holds it whatever the
    load: without the standing rule, the model would read the stopped worm as the load that balances a zero
    current)."""
    obs = MomentumObserver(RIG, 1e-3)
    assert obs.update(voltage_drive=0.0, current_drive=math.nan, omega_worm=10.0).flags & EstimateFlags.INVALID_INPUT
    assert math.isnan(obs.update(voltage_drive=0.0, current_drive=0.2, omega_worm=math.nan).torque)
    run = run_observers(RIG, lambda t: np.full(1, 150.0 if t < 0.6 else 0.0), lambda t: np.full(1, 0.1), 1, 1.2,
                        estimator=make_estimator("momentum", None))
    moving, standing = run["tau_est"][500:600, 0], run["tau_est"][700:, 0]
    assert np.all(run["omega_true"][700:, 0] == 0.0)  # the PI has stopped it: the worm stands for 0.5 s
    assert abs(moving.mean() - 0.1) < 0.005 and np.all(np.abs(standing - 0.1) < 0.005)  # measured 0.0027-0.0034
    obs = make_estimator("momentum", None).stream(1e-3)
    rng = np.random.default_rng(0)
    for k in range(300):
        est = obs.update(voltage_drive=0.0, current_drive=0.35 + 0.02 * rng.normal(),
                         omega_worm=150.0 + 0.5 * rng.normal(), theta_worm=0.15 * k)
    held = est.torque
    for bad in ((0.35, math.nan), (math.inf, 150.0)):
        est = obs.update(voltage_drive=0.0, current_drive=bad[0], omega_worm=bad[1], theta_worm=0.15 * 300)
        assert est.flags & EstimateFlags.INVALID_INPUT and abs(est.torque - held) < 1e-3
    est = obs.update(voltage_drive=0.0, current_drive=0.35, omega_worm=150.0, theta_worm=math.nan)
    assert not est.flags & EstimateFlags.INVALID_INPUT and math.isfinite(est.torque)


def test_self_locking_v_and_limits() -> None:
    """At 2 rad/s the box self-locks (AGMA mu ~0.12): the estimate is flagged AMBIGUOUS and its uncertainty reaches
    the other flank's load; a load beyond what the rig can apply is OUT_OF_CALIBRATION."""
    obs = MomentumObserver(RIG, 1e-3)
    smap = StaticLoadMap(RIG)
    t_dist = smap.worm_torque(2.0, 0.1)[0]
    current = (t_dist + RIG.drive_motor.viscous_drag * 2.0) / RIG.drive_motor.torque_constant
    est = obs.update(voltage_drive=0.0, current_drive=current, omega_worm=2.0)
    _driving, coast, _f, _c = smap.invert(2.0, t_dist)
    assert est.flags & EstimateFlags.AMBIGUOUS and est.torque == pytest.approx(0.1, abs=1e-9)
    assert est.uncertainty >= abs(float(coast) - 0.1) - 1e-12
    big = MomentumObserver(RIG, 1e-3)
    big.update(voltage_drive=0.0, current_drive=0.35, omega_worm=150.0)
    big.x[2], big._at_x = 5.0, None
    assert big._estimate(False).flags & EstimateFlags.OUT_OF_CALIBRATION


def test_gaps_and_restarts_through_live_estimator() -> None:
    """LiveEstimator's seq: a gap is predicted over (the state kept), a seq going back starts again."""
    live = LiveEstimator(RIG, make_estimator("momentum", None), 1e-3)
    rng = np.random.default_rng(1)
    for k in range(400):
        live.update(150.0 + 0.5 * rng.normal(), 0.35 + 0.02 * rng.normal(), theta_worm=0.15 * k, seq=k)
    before = live.stream.x.copy()
    live.update(150.0, 0.35, theta_worm=0.15 * 405, seq=405)
    assert live.gaps == 1 and live.lost == 5 and abs(live.stream.x[2] - before[2]) < 0.01
    live.update(150.0, 0.35, theta_worm=0.0, seq=3)
    assert live.restarts == 1 and live.stream.samples == 1
