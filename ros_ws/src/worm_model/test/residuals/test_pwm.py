"""The ``pwm`` effect of the residual vocabulary: the PWM ripple the ADC samples at a fixed phase.

Model-only checks (no simulator: worm_model does not depend on it; the checks against the
simulator's pwm plug-in and timing are in tests/test_residuals_sim.py): the sampled ripple is the
triangle's value at the phase, the translation to and from the simulator's entry, and the
analysis finding the effect in data the declared model makes with it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import worm_model.residuals.analysis as an
from worm_model.physics.parameters import load_rig
from worm_model.residuals.effects import (EFFECTS, PWM_FREQUENCY, Pwm, firmware_sampling_phase,
                                          sampled_ripple)
from worm_model.residuals.extended import ExtendedModel
from worm_model.residuals.model import evaluate, prepare_signals
from worm_model.rig_data.schema import MeasuredData

RIG = load_rig()
PWM = EFFECTS["pwm"]


def triangle(duty: float, phase: float, points: int = 20000) -> float:
    """The armature current's ripple at ``phase`` [periods], per unit of V_s / (L f), integrated numerically.

    Over one period of sign-magnitude PWM at duty d with L f >> R the current rises with slope
    (1 - d) V_s / L while the bridge is on (the back-emf and R i take the mean voltage d V_s) and
    falls with slope -d V_s / L while it is off; its mean over the period is the plant's current.
    """
    x = (np.arange(points) + 0.5) / points  # phase of each sub-interval's midpoint
    slope = np.where(x < duty, 1.0 - duty, -duty)  # d i / d phase in V_s / (L f)
    current = np.cumsum(slope) / points
    current -= current.mean()
    return float(np.interp(phase, x, current))


@pytest.mark.parametrize("phase", [0.0, 0.1, 0.24, 0.5, 0.83])
def test_sampled_ripple_is_the_triangle_at_its_phase(phase: float) -> None:
    duties = np.array([0.0, 0.05, 0.2, 0.24, 0.3, 0.5, 0.74, 0.9, 1.0])
    expected = [triangle(d, phase) for d in duties]
    np.testing.assert_allclose(sampled_ripple(duties, phase), expected, atol=2e-4)
    # largest at d = 1/2 (peak to peak d (1 - d) = 1/4), none at 0 % and 100 % duty, clipped beyond
    assert np.ptp([sampled_ripple(np.array([0.5]), p)[0] for p in np.linspace(0, 1, 101)]) == pytest.approx(0.25)
    np.testing.assert_allclose(sampled_ripple(np.array([-0.3, 1.4]), phase), 0.0, atol=1e-15)


def test_simulator_entry_translates_the_filter_to_the_amplitude_and_back() -> None:
    full = RIG.supply_voltage / (RIG.drive_motor.inductance * PWM_FREQUENCY)  # 24 V / (1.5 mH x 20 kHz) = 0.8 A
    values, grid = PWM.from_simulator_entry({}, RIG)  # the simulator's defaults: 20 kHz, a 2 kHz filter
    assert values["amplitude"] == pytest.approx(full / math.sqrt(1 + 10.0**2))
    assert grid["phase"] == pytest.approx(0.24)  # 12 us after the tick / 50 us PWM period
    values, grid = PWM.from_simulator_entry({"filter_cutoff": 7000.0}, RIG)
    assert PWM.simulator_entry(values, grid) == pytest.approx({"frequency": PWM_FREQUENCY, "filter_cutoff": 7000.0})
    # what the simulator cannot make: a negative amplitude (no ripple), one beyond the unfiltered ripple (no filter)
    assert PWM.simulator_entry({"amplitude": -0.1}, grid)["filter_cutoff"] == Pwm.min_filter_cutoff
    assert PWM.simulator_entry({"amplitude": 2 * full}, grid)["filter_cutoff"] == Pwm.max_filter_cutoff
    # a PWM that is not a whole multiple of the 1 kHz sample rate: the phase walks, the bias averages out
    assert firmware_sampling_phase(19_500.0) is None
    assert PWM.from_simulator_entry({"frequency": 19_500.0}, RIG)[0]["amplitude"] == 0.0


def test_the_bias_follows_the_model_voltage_and_its_sign() -> None:
    """Channel 'current' = sign(V) A sampled_ripple(|V| / V_s, p), V = R i_true + K_e omega."""
    model = ExtendedModel(RIG, [(PWM, {"amplitude": 0.3}, {"phase": 0.24, "frequency": PWM_FREQUENCY,
                                                          "full_ripple": 0.8})])
    omega = np.array([-300.0, -100.0, 0.0, 50.0, 100.0, 300.0, 500.0])  # 500 rad/s: 27.5 V, the bridge saturated
    sig = model.signals(omega, 0.0, 0.1 * np.sign(omega), omega * 0.0)
    i_true = evaluate(RIG, sig).current_true
    v = RIG.drive_motor.resistance * i_true + RIG.drive_motor.back_emf_constant * omega
    expected = np.sign(v) * 0.3 * sampled_ripple(np.abs(v) / RIG.supply_voltage, 0.24)
    np.testing.assert_allclose(model.current(sig) - model.without_effects().current(sig), expected, atol=1e-12)
    assert expected[-1] == 0.0 and expected[0] == -expected[-2]  # saturated; odd in the direction


def synthetic_pwm(amplitude: float, phase: float, seconds: float = 24.0, seed: int = 0) -> MeasuredData:
    """The declared model plus the pwm bias and 0.02 A of noise, 1 kHz, 6 runs over the duty range."""
    rng = np.random.default_rng(seed)
    runs = []
    per_run = seconds / 6
    for r, (w0, sign) in enumerate(((40.0, 1), (110.0, -1), (180.0, 1), (250.0, -1), (320.0, 1), (380.0, -1))):
        t = np.arange(0.0, per_run, 1e-3)
        omega = sign * (w0 + 0.3 * w0 * np.sin(2 * np.pi * 0.5 * t + r))
        theta = np.cumsum(omega) * 1e-3
        tau = 0.05 + 0.15 * np.sin(2 * np.pi * 0.3 * t + 2 * r)
        runs.append((t + r * (per_run + 1.0), omega, theta, tau))
    t, omega, theta, tau = (np.concatenate(x) for x in zip(*runs))
    data = MeasuredData(t=t, current_drive=np.zeros(len(t)), omega_worm=omega, theta_worm=theta, tau_load=tau)
    sig = prepare_signals(RIG, data)  # the model's alpha, as the analysis computes it
    grid = {"phase": phase, "frequency": PWM_FREQUENCY, "full_ripple": PWM.full_ripple(RIG)}
    data.current_drive = ExtendedModel(RIG, [(PWM, {"amplitude": amplitude}, grid)]).current(sig) \
        + rng.normal(0.0, 0.02, len(t))
    return data


def test_analysis_finds_the_pwm_bias_and_its_phase_in_model_data() -> None:
    data = synthetic_pwm(amplitude=0.36, phase=0.62)
    settings = an.Settings()
    sig = prepare_signals(RIG, data, settings.alpha_time_constant)
    split = an.make_split(sig, settings, rig=RIG)
    result = an.analyse(an.Problem(RIG, ["friction.scale"], sig, data.current_drive, split, settings))
    assert result.found == ["pwm"]
    fitted = result.final.effects[0]
    print(f"pwm: phase {fitted.grid['phase']:.2f} (true 0.62), amplitude {fitted.values['amplitude']:.4f} "
          f"+- {fitted.ci['amplitude']:.4f} A (true 0.36), held-out RMS {result.rms_before:.4f} -> "
          f"{result.final.rms_held_out:.4f} A")
    assert fitted.grid["phase"] == pytest.approx(0.62, abs=0.021)  # the grid's step is 0.02
    assert fitted.values["amplitude"] == pytest.approx(0.36, rel=0.1)
    assert result.final.rms_held_out < 1.05 * 0.02
