"""The trend figure is drawn from assessed checks, by hours run where every check has them."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from matplotlib.image import imread

from worm_model.health.assess import assess_trend, baseline_of
from worm_model.health.fit import Temperature
from worm_model.health.model import NAMES, HealthParameters
from worm_model.health.plots import trend_figure
from worm_model.health.record import CheckRecord
from worm_model.health.settings import HealthSettings
from worm_model.physics.parameters import load_rig

RIG = load_rig()


def test_the_trend_figure_is_written(tmp_path) -> None:
    rng = np.random.default_rng(0)
    base = HealthParameters.from_rig(RIG)
    records = []
    for i in range(12):
        t = rng.uniform(25, 55)
        scale = (1 - 0.004 * (t - 25)) * (1.1 if i >= 9 else 1.0) * (1 + rng.normal(0, 0.01))
        sigma = {n: 0.02 * abs(getattr(base, n)) + 1e-6 for n in NAMES}
        records.append(CheckRecord("d", 100.0 * i, "test", Temperature(t, 0.5, "measured"),
                                   replace(base, mu_scale=scale), sigma, np.diag([sigma[n] ** 2 for n in NAMES]),
                                   {n: True for n in NAMES}, 0.0, math.nan, math.nan, 30, 20.0, 1e-4, 1.0))
    settings = HealthSettings()
    assessments = assess_trend(records, settings, RIG)
    path = trend_figure(tmp_path / "trend.png", records, assessments, settings, RIG,
                        baseline_of(records[:5], settings, RIG))
    image = imread(path)
    assert image.shape[0] > 600 and image.shape[1] > 800
    assert assessments[-1].level == "WARN"
