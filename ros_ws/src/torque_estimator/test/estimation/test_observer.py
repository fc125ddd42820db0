"""The model-based load observer (torque_estimator.estimation.observer/) on the simulated rig.

Tolerances come from runs over several seeds (bench/observer_bench.py prints them); each
test says what it measured. The simulator runs the rig file's parameters and, unless said,
the paper's model exactly, which the observer also uses: its steady accuracy is therefore
near perfect and the robustness test (the observer's model perturbed) is the one that says
how it fares with a model error.
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from torque_estimator.calibration.batch import CalibrationGrid
from torque_estimator.estimation.base import EstimateFlags
from torque_estimator.estimation.registry import ESTIMATORS, METHODS, PRIOR_OPTIONS, make_estimator
from torque_estimator.evaluation.held_out import held_out_setpoints
from torque_estimator.estimation.observer import (LoadObserver, ObserverEstimator, StaticLoadMap, jump_bound,
                                       predicted_noise, steady_state_bound)
from torque_estimator.evaluation.observer_study import (held_out_streaming, perturbed_rig, profile_error, run_observers,
                                             step_response)
from worm_model.physics.parameters import load_rig

RIG = load_rig(None)
RANGE = 0.495  # [N m] the paper grid's calibrated range (CalibrationGrid.paper: ±0.9 x max load torque)


@pytest.fixture(scope="module")
def nominal_step():
    return step_response(RIG, seeds=8)


def test_registry() -> None:
    assert "observer" in ESTIMATORS and METHODS["observer"].reads_model_file
    assert METHODS["observer"].options == PRIOR_OPTIONS
    est = make_estimator("observer", None)
    assert callable(est.stream) and isinstance(est.stream(0.001), LoadObserver)


def test_static_map_round_trip() -> None:
    """The quasi-static estimate inverts the model's current at alpha = 0 on both flanks and both directions."""
    est = ObserverEstimator(None)
    smap = StaticLoadMap(RIG)
    motor = RIG.drive_motor
    for omega in (-300.0, -40.0, 40.0, 150.0):
        for tau in (-0.2, -0.05, -0.004, 0.0, 0.1, 0.24):
            t_dist, _slope, _flank = smap.worm_torque(omega, tau)
            current = (t_dist + motor.viscous_drag * omega) / motor.torque_constant
            result = est.estimate(omega, current)
            assert float(result.torque) == pytest.approx(tau, abs=1e-9)
            assert int(result.flags) == 0


def test_self_locking_v_is_ambiguous() -> None:
    """At 2 rad/s the AGMA mu (~0.12) self-locks the box: two loads draw the same current."""
    est = ObserverEstimator(None)
    smap = StaticLoadMap(RIG)
    t_dist, _s, _f = smap.worm_torque(2.0, 0.1)
    current = (t_dist + RIG.drive_motor.viscous_drag * 2.0) / RIG.drive_motor.torque_constant
    result = est.estimate(2.0, current)
    assert int(result.flags) & EstimateFlags.AMBIGUOUS
    assert float(result.torque) == pytest.approx(0.1, abs=1e-9)  # the driving flank is reported
    driving, coast, _flags, _chosen = smap.invert(2.0, t_dist)
    assert float(coast) < 0 and float(result.other) == pytest.approx(float(coast), abs=1e-12)  # the other arm
    # a prior that admits only the coast arm's load takes that one, and nothing is ambiguous
    only_coast = ObserverEstimator(None, load_min=float(coast) - 0.01, load_max=float(coast) + 0.01).estimate(
        2.0, current)
    assert float(only_coast.torque) == pytest.approx(float(coast), abs=1e-9)
    assert not int(only_coast.flags) & EstimateFlags.AMBIGUOUS and np.isnan(float(only_coast.other))


def test_step_response(nominal_step) -> None:
    """A true step 0 -> 0.2 N m at 150 rad/s (the load loop made instantaneous, so the estimator's own
    delay is measured). Measured over 12 seeds: ensemble-mean 90 % at 3 ms, per seed 2-4 ms with an
    occasional 11-12 ms (a first jump estimate under 90 %, finished by the filter), overshoot of the
    ensemble mean 16-38 % for 1-3 ms right after the detection (the jump is estimated from 3-4 samples).
    The spread is the physics: jump_bound gives 1 sigma = 18 % of the step at 3 samples."""
    r = nominal_step
    assert r.step90_ms <= 5
    assert np.median(r.per_seed90_ms) <= 5
    assert r.overshoot_pct < 60
    assert abs(r.steady_bias) < 0.005
    assert r.steady_std < 0.002  # measured 0.00047 N m


def test_jump_bound_is_the_floor() -> None:
    """Why no observer on these sensors reacts in 1-2 ms: the Cramer-Rao bound on a 0.2 N m step's size."""
    sigma = jump_bound(RIG, 150.0, 0.1, 6) / 0.2
    assert sigma[1] > 0.25 and sigma[2] > 0.12  # 2 samples: ~32 %, 3 samples: ~18 %
    assert sigma[5] < 0.08


def test_steady_noise_against_bound(nominal_step) -> None:
    """Measured steady noise on a constant load vs the filter's predicted noise and the Cramer-Rao-type bound.
    The predicted noise and bound use the 4-state model (armature equation exact); the observer also
    estimates the armature-equation error, which costs ~3x in steady noise (measured 4.7e-4 N m against
    predicted 2.3e-4 and bound 5.0e-4, the bound paying for a random-walk load)."""
    predicted = predicted_noise(RIG, 150.0, 0.0)
    bound = steady_state_bound(RIG, 150.0, 0.0)
    assert predicted < bound
    assert nominal_step.steady_std < 5 * predicted


def test_held_out_points_streaming() -> None:
    """The 17 held-out points of evaluation.py (seed 1), streamed and averaged over 0.5 s once steady.
    Measured: mean 0.003 %, max 0.013 % of the range (the simulator runs the observer's model)."""
    grid = CalibrationGrid.paper(RIG)
    speeds, torques = held_out_setpoints(grid, 17, 1)
    est, truth = held_out_streaming(RIG, speeds, torques)
    error = 100 * np.abs(est - truth) / RANGE
    assert error.mean() <= 1.0 and error.max() <= 2.0


def test_flags_and_invalid_input() -> None:
    obs = LoadObserver(RIG)
    first = obs.update(voltage_drive=math.nan, current_drive=0.1, omega_worm=10.0, theta_worm=0.0)
    assert first.flags & EstimateFlags.INVALID_INPUT  # before any valid sample
    run = run_observers(RIG, lambda t: np.full(1, 150.0), lambda t: np.full(1, 0.1), 1, 0.5)
    assert abs(run["tau_est"][-1, 0] - 0.1) < 0.01
    # feed NaNs into a converged observer: held, flagged, no exception
    obs = LoadObserver(RIG)
    rng = np.random.default_rng(0)
    for k in range(300):
        obs.update(voltage_drive=8.5, current_drive=0.1 + 0.02 * rng.normal(), omega_worm=150.0, theta_worm=0.15 * k)
    held = obs.x[3]
    for bad in (math.nan, math.inf):
        est = obs.update(voltage_drive=bad, current_drive=0.1, omega_worm=150.0, theta_worm=0.15 * 300)
        assert est.flags & EstimateFlags.INVALID_INPUT and est.torque == held
    est = obs.update(voltage_drive=8.5, current_drive=0.1, omega_worm=math.nan, theta_worm=0.15 * 301)
    assert est.flags & EstimateFlags.INVALID_INPUT
    # a load the rig cannot apply is out of calibration
    big = LoadObserver(RIG)
    big.update(voltage_drive=8.5, current_drive=0.1, omega_worm=150.0, theta_worm=0.0)
    big.x[3] = 5.0
    assert big._estimate(False, 0).flags & EstimateFlags.OUT_OF_CALIBRATION



@pytest.mark.parametrize("volts,load", [(8.85, 0.0), (8.85, 0.1), (8.85, -0.1), (8.85, 0.2), (-8.85, 0.0), (3.0, -0.1),
                                        (6.0, -0.2)])
def test_started_on_a_running_drive_it_settles_without_a_load_step(volts: float, load: float) -> None:
    """An observer started while the drive already runs (estimator_node started after the rig) sees no load
    step, so nothing but its own convergence can end the TRANSIENT of its start. Measured on these
    operating points: flagged for its first 0.57-1.3 s (longest in the self-locking V), then not once in
    the next 1.7 s. The variance it settles to is the
    filter's own (1e-6 to 8e-6 (N m)² here), 4-17 x the steady-state Riccati solution of observer.bounds'
    reduced model: with that as the reference, every estimate would stay TRANSIENT."""
    from worm_rig_driver.sim.simulated_rig import SimulatedRig

    sim = SimulatedRig(RIG, n=1, seed=0)
    sim.command(voltage_drive=volts, load_torque=load)
    for _ in range(2000):  # 2 s: the drive at its speed
        sim.sample()
    obs = LoadObserver(RIG)
    flags = []
    for _ in range(3000):
        m = sim.sample()
        est = obs.update(voltage_drive=volts, current_drive=float(m.current_drive[0]),
                         omega_worm=float(m.omega_worm[0]), theta_worm=float(m.theta_worm[0]))
        flags.append(est.flags & EstimateFlags.TRANSIENT)
    transient = np.flatnonzero(flags)
    # one run from the start (converging), then settled for good
    assert transient[0] == 0 and len(transient) == transient[-1] + 1 and 400 < transient[-1] < 1500, transient
    assert abs(est.torque - load) < 0.01, est.torque

def test_speed_ramp_and_reversal() -> None:
    """Error while the speed ramps 50 -> 300 rad/s in 1 s at 0.1 N m (measured, 2 seeds: mean 0.3 %, max
    4.6 % of the range, a short excursion as the ramp starts), and through a +150 -> -150 rad/s reversal
    at 0.1 N m on a simulator integrated finely
    enough for a reversal (20 substeps; its default 2 substeps are coarse at ~30000 rad/s², see the
    report): unflagged samples stay within 4 % of the range (measured 2.1 %; flagged ones are the
    self-locking V at the zero crossing and the TRANSIENT after a detection)."""
    ramp_mean, ramp_max = profile_error(RIG, lambda t: 50 + 250 * min(max(t - 0.5, 0.0), 1.0), 0.1, 1.6,
                                        start=0.5, seeds=2)
    assert 100 * ramp_mean / RANGE < 1.0 and 100 * ramp_max / RANGE < 8.0
    run = run_observers(RIG, lambda t: np.full(2, 150.0 if t < 0.6 else -150.0), lambda t: np.full(2, 0.1), 2,
                        0.8, substeps=20)
    after = slice(600, None)
    error = np.abs(run["tau_est"][after] - run["tau_true"][after])
    unflagged = run["flags"][after] == 0
    assert 100 * error[unflagged].max() / RANGE < 4.0


@pytest.mark.parametrize("perturbation", [dict(mu=1.3), dict(mu=0.7), dict(kt=1.05), dict(kt=0.95),
                                          dict(inertia=1.2), dict(inertia=0.8)],
                         ids=lambda p: ",".join(f"{k}x{v}" for k, v in p.items()))
def test_robustness(perturbation) -> None:
    """The observer's model perturbed (the simulator keeps the rig file's values). Measured (8 seeds):
    ensemble-mean 90 % at 3 ms in all but J x0.8 (12 ms: a lighter model reads less torque from the
    deceleration, the first jump estimate falls short); overshoot up to ~190 % for K_t x0.95 (a short
    spike), ~40 % for J x1.2; steady bias ~0.02 N m (4 % of the range) for mu ±30 % and K_t ±5 %."""
    r = step_response(RIG, seeds=6, observer_rig=perturbed_rig(RIG, **perturbation))
    assert r.step90_ms <= 20
    assert abs(r.steady_bias) < 0.03
    assert r.steady_std < 0.002


# The closed loop with the observer's feedforward (controller_bench's figures, averaged over seeds, and the
# 1.3 x ideal dip target it does not reach) is pinned in tests/test_readme_figures.py.


# ----------------------------------------------------------------------------------------------
# the observer's numbers pinned
#: Inputs and outputs of LoadObserver.update recorded on a demanding run (write_reference below).
REFERENCE = Path(__file__).with_name("data") / "observer_reference.npz"


def _reference_cases() -> dict:
    """name -> (observer's rig, LoadObserver options, encoder angle fed?)."""
    constant_mu = replace(RIG, friction=replace(RIG.friction, model="constant", mu_constant=0.06))
    return {"white": (RIG, {}, True), "interval": (RIG, {"encoder": "interval"}, True),
            "no_encoder": (RIG, {}, False),
            "constant_mu_light": (perturbed_rig(constant_mu, inertia=0.8), {}, True)}


def _reference_outputs(inputs: np.ndarray, rig, options: dict, encoder: bool) -> dict[str, np.ndarray]:
    obs = LoadObserver(rig, 1e-3, **options)
    out = [obs.update(voltage_drive=v, current_drive=i, omega_worm=w, theta_worm=th if encoder else None)
           for v, i, w, th in inputs.tolist()]
    return {"torque": np.array([e.torque for e in out]), "uncertainty": np.array([e.uncertainty for e in out]),
            "flags": np.array([e.flags for e in out], dtype=np.int8), "jump": np.array([e.jump for e in out])}


def _reference_inputs() -> np.ndarray:
    """(samples, 4) V, i, tacho, encoder angle of one simulated rig under the speed controller, 1.6 s:
    load steps, a +150 -> -150 rad/s reversal, 3 rad/s in the self-locking V, standstill, a ramp to
    300 rad/s, and four non-finite samples."""
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, SpeedController
    from worm_rig_driver.sim.simulated_rig import SimulatedRig

    def speed(t):
        return (150.0 if t < 0.4 else -150.0 if t < 0.7 else 3.0 if t < 0.95 else 0.0 if t < 1.1
                else -2.0 + 300 * (t - 1.1) if t < 1.4 else 300.0)

    def load(t):
        return 0.1 if t < 0.15 else 0.3 if t < 0.25 else -0.1 if t < 0.55 else 0.2 if t < 0.8 else \
            -0.05 if t < 1.2 else 0.25

    sim = SimulatedRig(RIG, n=1, seed=0, substeps=20)
    controller = SpeedController(RIG, DEFAULT_GAINS, n=1)
    dt, rows = sim.sample_period, []
    for k in range(1600):
        sim.command(load_torque=np.full(1, load(k * dt)))
        m = sim.sample()
        rows.append([float(m.voltage_drive[0]), float(m.current_drive[0]), float(m.omega_worm[0]),
                     float(m.theta_worm[0])])
        sim.command(voltage_drive=controller.update(dt, np.full(1, speed((k + 1) * dt)), m.omega_worm).voltage)
    inputs = np.array(rows)
    inputs[300, 0], inputs[301, 2], inputs[700, 3], inputs[1000, 1] = math.nan, math.inf, math.nan, -math.inf
    return inputs


def write_reference(path: Path = REFERENCE) -> None:
    """Record the reference (only when the observer's numbers are meant to change: say why in the commit)."""
    inputs = _reference_inputs()
    arrays = {"inputs": inputs}
    for name, case in _reference_cases().items():
        arrays.update({f"{name}/{k}": v for k, v in _reference_outputs(inputs, *case).items()})
    path.parent.mkdir(exist_ok=True)
    np.savez_compressed(path, **arrays)


#: [N m] agreement required per case (relative above 1 N m). The interval encoder model is sensitive to
#: round-off through the 1000 rad/s^2 ramp (its moment-matched pseudo-measurement depends on the prior):
#: today's implementation against itself with ONE input sample nudged by one ulp differs by 1.2e-7 N m
#: there (white: 2.8e-13 N m).
PINNED_TOLERANCE = {"white": 1e-9, "interval": 1e-6, "no_encoder": 1e-9, "constant_mu_light": 1e-9}


def test_numbers_pinned() -> None:
    """LoadObserver.update reproduces the recorded run (torque and uncertainty within PINNED_TOLERANCE, 1e-9
    N m but for the interval model, flags and detections identical) with the white and interval encoder
    models, without encoder, and with a constant-friction, lighter model: a change to the observer's
    arithmetic that is more than round-off fails here. First recorded with the all-numpy implementation of
    2026-11 (~200 us per update), which the float one (~50 us) matched within 5e-14 N m (white), 4.5e-9 N m
    (interval); re-recorded when each J_eff bin came to be discretised at its own value instead of the first
    J_eff met in it (so that a replay starting later than the live node reproduces it; up to 2.6e-4 N m), and
    when a stop's hold came to end only once the motion has lasted (branches.Hold.keeps).

    Values above 1 N m are compared relatively: in the self-locking V near the pole of the coast
    flank (K_- -> 0) the AMBIGUOUS uncertainty reaches the other branch, hundreds of N m away, and 1/K_-
    amplifies round-off (measured: 6e-8 N m on u = 518 N m when only the order of operations changed)."""
    ref = np.load(REFERENCE)
    inputs = ref["inputs"]
    for name, case in _reference_cases().items():
        out = _reference_outputs(inputs, *case)
        for key in ("torque", "uncertainty"):
            expected = ref[f"{name}/{key}"]
            assert np.array_equal(np.isfinite(out[key]), np.isfinite(expected)), (name, key)
            finite = np.isfinite(expected)
            error = np.abs(out[key][finite] - expected[finite]) / np.maximum(1.0, np.abs(expected[finite]))
            assert np.max(error) <= PINNED_TOLERANCE[name], (name, key, np.max(error))
        assert np.array_equal(out["flags"], ref[f"{name}/flags"]), name
        assert np.array_equal(out["jump"], ref[f"{name}/jump"]), name
        assert ref[f"{name}/jump"].sum() >= 10  # the run exercises the GLR


if __name__ == "__main__":
    # tools/run.sh python ros_ws/src/torque_estimator/test/estimation/test_observer.py: re-record the reference
    write_reference()


def test_a_discontinuity_restarts_the_filter() -> None:
    """The rig restarted under the observer's feet (angle and speed back to 0): the innovation is far
    beyond RESTART_NIS (~3e9 against at most 324 on the pinned run) and the filter starts again from
    that sample, finite and at the new state; before, it went to ~1e5 N m and then NaN for good."""
    from torque_estimator.estimation.observer import RESTART_NIS
    inputs = _reference_inputs()
    obs = LoadObserver(RIG, 1e-3)
    for v, i, w, th in inputs[:350].tolist():
        obs.update(voltage_drive=v, current_drive=i, omega_worm=w, theta_worm=th)
    assert obs.restarts == 0
    estimates = [obs.update(voltage_drive=0.0, current_drive=0.0, omega_worm=0.0, theta_worm=0.0)
                 for _ in range(200)]
    assert obs.restarts == 1 and RESTART_NIS < 1e5
    assert all(math.isfinite(e.torque) and abs(e.torque) < 0.01 for e in estimates)
