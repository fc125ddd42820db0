"""The thermal estimate is the first-order model's exact response, its uncertainty the terms it states; the
settings file is read whole or refused naming the key."""
from __future__ import annotations

import math

import pytest

from worm_model.health.settings import Thermal, load_settings
from worm_model.errors import SettingsError
from worm_model.health.thermal import ThermalEstimate


def test_the_estimate_is_the_first_order_response() -> None:
    s = Thermal(ambient=20.0, thermal_resistance=10.0, time_constant=600.0)
    est = ThermalEstimate.start(s)
    for _ in range(1200):  # 20 min in 1 s steps at 2 W
        est.step(1.0, 2.0)
    expected = 20.0 + 10.0 * 2.0 * (1.0 - math.exp(-1200.0 / 600.0))
    assert est.temperature == pytest.approx(expected, rel=1e-12)
    one = ThermalEstimate.start(s)
    one.settle(2.0, 1200.0)  # one exact step gives the same
    assert one.temperature == pytest.approx(expected, rel=1e-12)
    # from a known start it relaxes to the steady state R P
    warm = ThermalEstimate.start(s, temperature=60.0, sigma=0.5)
    warm.settle(0.0, 6000.0)
    assert warm.temperature == pytest.approx(20.0 + 40.0 * math.exp(-10.0), abs=1e-9)


def test_its_uncertainty_is_the_terms_it_states() -> None:
    s = Thermal(ambient=25.0, ambient_sigma=2.0, initial_sigma=3.0, power_sigma=0.25, thermal_resistance=10.0,
                time_constant=900.0)
    cold = ThermalEstimate.start(s)
    assert cold.sigma == pytest.approx(math.hypot(2.0, 3.0))  # the hall's and the night's
    cold.settle(3.0, 900.0)
    rise = 30.0 * (1.0 - math.exp(-1.0))
    assert cold.sigma == pytest.approx(math.sqrt(2.0 ** 2 + (3.0 * math.exp(-1.0)) ** 2 + (0.25 * rise) ** 2))
    known = ThermalEstimate.start(s, temperature=40.0, sigma=0.5)
    known.settle(0.0, 900.0)
    e = math.exp(-1.0)
    assert known.sigma == pytest.approx(math.hypot(0.5 * e, 2.0 * (1.0 - e)))


def test_settings_files(tmp_path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("format: worm_gearbox_health_settings\nversion: 1\nlimits: {check_warn: 0.08, trend_window: 6}\n"
                    "thermal: {ambient: 18.5}\n")
    settings = load_settings(path)
    assert settings.limits.check_warn == 0.08 and settings.limits.trend_window == 6
    assert settings.thermal.ambient == 18.5 and settings.limits.check_error == 0.20  # the rest: defaults
    assert load_settings(None).source == "defaults"
    for text, where in [("format: x\nversion: 1\n", "format"), ("format: worm_gearbox_health_settings\nversion: 2\n",
                        "version"),
                        ("format: worm_gearbox_health_settings\nversion: 1\nlimits: {check_wran: 0.1}\n",
                         "limits.check_wran"),
                        ("format: worm_gearbox_health_settings\nversion: 1\nlimits: {trend_window: 2.5}\n",
                         "limits.trend_window"),
                        ("format: worm_gearbox_health_settings\nversion: 1\nthermal: {time_constant: -5}\n",
                         "thermal.time_constant"),
                        ("format: worm_gearbox_health_settings\nversion: 1\nalarms: {}\n", "alarms")]:
        path.write_text(text)
        with pytest.raises(SettingsError) as err:
            load_settings(path)
        assert str(path) in str(err.value) and where in str(err.value), str(err.value)
