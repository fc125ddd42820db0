"""The live monitor on streams whose truth is known (the health model itself, quasi-static, with noise): a step of
mu raises WARN within its window, a warming oil raises nothing, operation outside the checked range is not judged."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from worm_model.health.live import LiveHealth, LiveReference
from worm_model.health.model import HealthParameters, TemperatureLaw, input_torque
from worm_model.health.settings import HealthSettings
from worm_model.physics.parameters import load_rig

RIG = load_rig()
SETTINGS = HealthSettings()
PERIOD = 1e-3
LAW = TemperatureLaw(25.0, -0.004, 0.0005, "test")
REFERENCE = LiveReference(HealthParameters.from_rig(RIG), LAW, 5e-5, {"forward": [60.0, 300.0],
                                                                       "backward": [60.0, 300.0]},
                          [-0.25, 0.25], 35.0, "test")


def stream(monitor: LiveHealth, seconds: float, omega, load, *, mu=lambda t: 1.0, temperature=lambda t: 35.0,
           measured: bool = True, seed: int = 0, start: float = 0.0) -> list[tuple[float, str, float]]:
    """Feed ``seconds`` of samples (batches of 5); returns (time, level, mu change) after each block."""
    rng = np.random.default_rng(seed)
    out = []
    n = int(round(seconds / PERIOD))
    theta = 0.0
    for k0 in range(0, n, 5):
        t = start + (k0 + np.arange(5)) * PERIOD
        w = np.array([omega(x) for x in t])
        d = np.array([load(x) for x in t])
        temp = np.array([temperature(x) for x in t])
        p = replace(REFERENCE.parameters, mu_scale=REFERENCE.parameters.mu_scale * mu(t[0]))
        current = input_torque(RIG, p, w, d, LAW.factor(temp)) / RIG.drive_motor.torque_constant \
            + rng.normal(0.0, 0.02, 5)
        theta_w = theta + np.cumsum(w) * PERIOD
        theta = theta_w[-1]
        if monitor.add(w, current, d, theta_w, None, temp if measured else None):
            st = monitor.status
            out.append((st.time, st.level, st.mu_change.value))
    return out


def test_a_step_of_mu_raises_warn_within_the_window_and_nothing_before() -> None:
    monitor = LiveHealth(RIG, REFERENCE, SETTINGS, PERIOD)
    trace = stream(monitor, 12.0, lambda t: 200.0, lambda t: 0.22, mu=lambda t: 1.3 if t >= 8.0 else 1.0)
    before = [(t, lv) for t, lv, _ in trace if t < 8.0]
    assert all(lv == "OK" for _, lv in before)
    settled = [m for t, _, m in trace if 3.0 < t < 8.0]
    assert np.nanmax(np.abs(settled)) < 0.05
    warned = next(t for t, lv, _ in trace if lv != "OK")
    assert 8.0 < warned <= 8.0 + 2.0 and warned - 8.0 < SETTINGS.live.window + SETTINGS.limits.live_hold + 0.2
    assert trace[-1][2] == pytest.approx(0.3, abs=0.03)
    assert "friction" in monitor.status.message and "+" in monitor.status.message


def test_a_cold_start_raises_nothing() -> None:
    """The oil from 15 to 45 degC (sped up: 60 s here) lowers mu by 12 %; the law takes it out."""
    monitor = LiveHealth(RIG, REFERENCE, SETTINGS, PERIOD)
    trace = stream(monitor, 60.0, lambda t: 150.0 if (t // 5) % 2 else 250.0, lambda t: 0.2,
                   temperature=lambda t: 15.0 + 30.0 * t / 60.0)
    assert all(lv == "OK" for _, lv, _ in trace)
    values = np.array([m for _, _, m in trace if math.isfinite(m)])
    assert np.abs(values).max() < 0.05


def test_without_a_sensor_the_thermal_estimate_takes_over() -> None:
    monitor = LiveHealth(RIG, REFERENCE, SETTINGS, PERIOD)
    stream(monitor, 5.0, lambda t: 200.0, lambda t: 0.2, measured=False)
    st = monitor.status
    assert st.temperature_source == "estimated"
    assert st.oil_temperature.value == pytest.approx(SETTINGS.thermal.ambient, abs=0.5)  # 5 s after a cold start
    assert st.oil_temperature.sigma == pytest.approx(math.hypot(SETTINGS.thermal.ambient_sigma,
                                                                SETTINGS.thermal.initial_sigma), rel=0.05)


def test_operation_outside_the_checked_range_is_not_judged() -> None:
    monitor = LiveHealth(RIG, REFERENCE, SETTINGS, PERIOD)
    trace = stream(monitor, 5.0, lambda t: 20.0, lambda t: 0.22, mu=lambda t: 2.0)
    assert all(lv == "OK" for _, lv, _ in trace) and monitor.status.blocks == 0
    assert monitor.status.outside > 50


def test_a_raised_level_stands_until_the_window_shows_the_friction_back() -> None:
    monitor = LiveHealth(RIG, REFERENCE, SETTINGS, PERIOD)
    trace = stream(monitor, 6.0, lambda t: 200.0, lambda t: 0.22, mu=lambda t: 1.3 if t >= 3.0 else 1.0)
    assert trace[-1][1] == "WARN"
    # at a light load the window cannot tell: the alarm holds
    trace = stream(monitor, 3.0, lambda t: 200.0, lambda t: 0.01, mu=lambda t: 1.0, start=6.0, seed=1)
    assert trace[-1][1] == "WARN"
    # back at load with mu as the reference: lowered after the window and the hold
    trace = stream(monitor, 4.0, lambda t: 200.0, lambda t: 0.22, mu=lambda t: 1.0, start=9.0, seed=2)
    assert trace[-1][1] == "OK"
