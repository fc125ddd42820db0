"""How sure one check can be: the best any comparison with the earlier checks could do (a Cramér–Rao bound).

A check's mu change is Delta = s_T / (f_T(T) s_ref) - 1 (assess.mu_change): its watched mu scale s_T
at the oil temperature T, brought to the reference temperature by the law f_T(T) = 1 + k (T - T_ref)
and compared with the gearbox's level s_ref. Only the earlier checks teach s_ref and k. Suppose
everything else is known: every earlier check healthy, no drift between them, k's true value to
linearise at. The earlier checks' watched scales s_i (standard uncertainties sigma_i, each its fit's),
their temperatures T_i (sigma_T,i) and the prior on k then carry the Fisher information on (s_ref, k)

    I = sum_i w_i J_i J_i^T + diag(0, 1 / sigma_k,prior^2)
    J_i = (f_i, s_ref (T_i - T_ref)),   w_i = 1 / (sigma_i^2 + (s_ref k sigma_T,i)^2)

and no unbiased estimate of Delta has a variance below

    sigma_B^2 = own + g^T I^-1 g

(own: the check's own errors, its fit's and its temperature's; g: Delta's gradient on (s_ref, k)).
The check alarms when Delta is beyond the limit and sure, Delta >= max(z_min sigma, check_warn)
(assess; z_min is what keeps healthy checks quiet). With sigma = sigma_B, a true rise r reads
Delta ~ N(r, sigma_B) and is found by that one check with probability

    P = Phi((r - max(z_min sigma_B, check_warn)) / sigma_B)

and by no comparison more often at that false-alarm rate: a larger sigma raises the bar and
widens the spread. P falls where the check's oil lies beyond the temperatures the earlier checks
saw (g's k part grows with the distance). health.study sums P over its gearboxes: the most of them
any monitor could find a rise in at the first check after it. No ROS.
"""
from __future__ import annotations

import math
from dataclasses import replace
from statistics import NormalDist

import numpy as np

from worm_model.health.assess import Baseline, mu_change, watched_fit
from worm_model.health.record import CheckRecord
from worm_model.health.settings import HealthSettings, Limits
from worm_model.physics.parameters import Rig


def one_check_sigma(record: CheckRecord, earlier: list[CheckRecord], baseline: Baseline, mu_per_kelvin: float,
                    settings: HealthSettings, rig: Rig) -> float:
    """sigma_B of ``record``'s mu change (module docstring): the least standard uncertainty any comparison
    with the ``earlier`` checks can give it, linearised at ``baseline``'s level and at the temperature law
    ``mu_per_kelvin`` [1/K]; the checks' scales watched around the baseline's shape (assess.watched_fit)."""
    prior = settings.temperature
    k, s_ref = mu_per_kelvin, baseline.mu_scale
    information = np.diag([0.0, 1.0 / prior.sigma ** 2])
    for r in earlier:
        _, sigma = watched_fit(r, baseline.shape, rig, settings)
        dt = r.temperature.value - prior.reference
        jacobian = np.array([1.0 + k * dt, s_ref * dt])
        information += np.outer(jacobian, jacobian) / (sigma ** 2 + (s_ref * k * r.temperature.sigma) ** 2)
    at_k = replace(baseline, law=replace(baseline.law, reference=prior.reference, mu_per_kelvin=k))
    _, own, gradient = mu_change(record, at_k, rig, settings)
    return float(math.sqrt(own + gradient @ np.linalg.solve(information, gradient)))


def detection_probability(rise: float, sigma: float, limits: Limits) -> float:
    """P that one check with standard uncertainty ``sigma`` finds a true relative rise ``rise`` of mu
    (module docstring)."""
    bar = max(limits.z_min * sigma, limits.check_warn)
    return NormalDist().cdf((rise - bar) / sigma)


__all__ = ["detection_probability", "one_check_sigma"]
