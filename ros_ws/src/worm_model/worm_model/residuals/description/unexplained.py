"""The noise floor of the current, estimated from the data, and the description of a residual left above it:
its size and the quantities it goes with (speed, load, time, direction, temperature, worm and gear angle orders).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from worm_model.residuals.description.descriptors import (angles, direction, explained_by_bins, explained_by_orders,
                                                          quantities)
from worm_model.residuals.fitting.fitting import Fit, Problem


@dataclass
class NoiseFloor:
    """The white-noise level of the current, estimated from the data [A]."""

    rms: float
    samples: int
    method: str


@dataclass
class Correlation:
    """How much of the unexplained residual one quantity accounts for (held-out samples)."""

    quantity: str  # "speed", "load", "worm angle", ...
    share: float  # fraction of the unexplained variance (rms_after^2 - floor^2) it explains
    detail: str  # e.g. the best order and its amplitude


@dataclass
class Unexplained:
    """A residual the accepted effects leave above the noise floor: its size and what it goes with."""

    rms: float  # sqrt(rms_after^2 - floor^2) [A]
    ratio: float  # rms_after / floor
    correlations: list[Correlation]



def noise_floor(problem: Problem, final: Fit) -> NoiseFloor:
    """White-noise level of the current [A] from second differences of the final residual.

    e_k = (r_{k-1} - 2 r_k + r_{k+1}) / sqrt(6) has the variance sigma^2 of white noise in r
    and removes whatever changes slowly against the sample period (model errors of the
    operating point, drifts, ripples below ~1/10 of the sample rate; Gasser, Sroka and
    Jennetten-Steinmetz 1986).  Only triples of consecutive used samples of one run enter.
    A residual that varies as fast as the noise (a ripple near the Nyquist rate) counts as noise.
    """
    r, sig = final.residual, problem.signals
    used = problem.split.train | problem.split.held_out
    period = sig.sample_period
    ok = np.zeros(len(r), dtype=bool)
    ok[1:-1] = (used[:-2] & used[1:-1] & used[2:] & (sig.run[:-2] == sig.run[2:])
                & (np.abs(sig.t[2:] - sig.t[:-2] - 2 * period) < 0.5 * period))
    k = np.flatnonzero(ok)
    e = (r[k - 1] - 2.0 * r[k] + r[k + 1]) / math.sqrt(6.0)
    rms = float(np.sqrt(np.mean(e**2))) if len(e) else math.nan
    return NoiseFloor(rms, int(len(e)), "second differences of the final residual within runs, "
                                        "sqrt(mean((r[k-1] - 2 r[k] + r[k+1])^2) / 6) (white noise)")


def describe_unexplained(problem: Problem, final: Fit, noise: NoiseFloor) -> Unexplained:
    """Size of the residual above the noise floor and the quantities it goes with (held-out samples).

    Each quantity's share is the variance its best description (binned means; for angles a
    sinusoid of the best order, each direction of rotation its own: descriptors) takes out of the
    excess variance rms_after^2 - floor^2, corrected for what noise alone would give.
    """
    held = problem.split.held_out
    sig, r = problem.signals, final.residual[held]
    floor = noise.rms
    excess = max(float(np.mean(r**2)) - floor**2, 1e-30)
    found: list[Correlation] = []
    for name, x, bins, label in quantities(sig, held):
        explained, centre, mean = explained_by_bins(x[held], r, bins, floor)
        peak = centre[np.argmax(np.abs(mean))] if len(mean) else math.nan
        found.append(Correlation(name, min(explained / excess, 1.0),
                                 f"binned over {label}; "
                                 f"largest bin mean {np.max(np.abs(mean)) if len(mean) else 0:.3g} A "
                                 f"at {peak:.3g}"))
    sigma = direction(sig)[held]
    for name, angle, orders in angles(sig):
        k, explained, amplitude = explained_by_orders(angle[held], sigma, r, orders, floor)
        found.append(Correlation(name, min(explained / excess, 1.0),
                                 f"best order {k:g} per turn, amplitude {amplitude:.3g} A "
                                 "(each direction its own phase)"))
    found.sort(key=lambda c: -c.share)
    rms_after = float(np.sqrt(np.mean(r**2)))
    return Unexplained(math.sqrt(excess), rms_after / floor, found)
