"""When a fit earns its keep: the tests an effect (or a correction beyond its band) must pass to be named.

:func:`accepts`: a held-out improvement of its own signal, consistent over the held-out blocks (block
bootstrap, :func:`paired_interval`), the other signal not made worse, a lower training BIC.
:func:`physical`: every refitted parameter inside its physical range.
"""

from __future__ import annotations

import math

import numpy as np

from worm_model.physics.units import FloatArray

from worm_model.residuals.fitting.fitting import SIGNAL_UNITS, Fit, Problem, bic
from worm_model.residuals.free import TOLERANCES, get_value
from worm_model.residuals.settings import Settings


def delta_bic(before: Fit, after: Fit) -> float:
    """BIC(after) - BIC(before) on the training samples, both signals, with after's effective sample sizes."""
    d = bic(after.rss_train, after.n_train, after.n_eff, after.n_params) - bic(
        before.rss_train, before.n_train, after.n_eff, before.n_params)
    if after.te is not None and before.te is not None:
        a, b = after.te, before.te
        d += bic(a.rss_train, a.n_train, a.n_eff, a.n_params) - bic(b.rss_train, b.n_train, a.n_eff, b.n_params)
    return d


def accepts(before: Fit, after: Fit, settings: Settings, signal: str = "current_drive",
            problem: Problem | None = None) -> bool:
    """Significant evidence: the held-out RMS of ``signal`` down by min_improvement (relative), the other
    signal's not up by as much, a lower training BIC, AND (given ``problem``) an improvement consistent
    over the held-out blocks: the lower end of its block-bootstrap interval above 0.

    The last one is what stops an effect from buying its 2 % from a few blocks where a
    misfit elsewhere in the model happens to resemble it."""
    if problem is not None:
        if signal == "transmission_error" and before.te is not None and after.te is not None:
            r0, r1, mask = before.te.residual, after.te.residual, problem.te_held_out
        else:
            r0, r1, mask = before.residual, after.residual, problem.split.held_out
        low, _high = paired_interval(r0, r1, mask, problem.split.block, settings.bootstrap, settings.confidence)
        if not low > 0.0:
            return False
    other = settings.other_tolerance
    for name in SIGNAL_UNITS:
        old, new = before.rms(name), after.rms(name)
        if not (math.isfinite(old) and math.isfinite(new)):
            if name == signal:
                return False
            continue
        if name == signal and old - new < settings.min_improvement * old:
            return False
        if name != signal and new - old > other * old:
            return False
    return delta_bic(before, after) < 0.0


def _block_sums(residual: FloatArray, mask: np.ndarray, block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sum of squares, count) of the residual on ``mask`` per block id (ids compacted)."""
    ids, index = np.unique(block[mask], return_inverse=True)
    r = np.nan_to_num(residual[mask])
    return np.bincount(index, weights=r**2, minlength=len(ids)), np.bincount(index, minlength=len(ids)).astype(float)


def paired_interval(res_without: FloatArray, res_with: FloatArray, mask: np.ndarray, block: np.ndarray,
                    draws: int, confidence: float, seed: int = 0) -> tuple[float, float]:
    """Block-bootstrap interval of RMS(without) - RMS(with) over the blocks of ``mask`` (paired resampling).

    Held-out blocks are the independent units (residuals within a block are autocorrelated):
    resample them with replacement, recompute both RMS on the same draw.
    """
    s0, n = _block_sums(res_without, mask, block)
    s1, _ = _block_sums(res_with, mask, block)
    if len(n) < 2:
        return (math.nan, math.nan)
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, len(n), size=(draws, len(n)))
    counts = np.apply_along_axis(np.bincount, 1, pick, minlength=len(n)).astype(float)
    total = counts @ n
    diff = np.sqrt(counts @ s0 / total) - np.sqrt(counts @ s1 / total)
    tail = 50.0 * (1.0 - confidence)
    return float(np.percentile(diff, tail)), float(np.percentile(diff, 100.0 - tail))


def physical(problem: Problem, fitted: Fit) -> bool:
    """Every refitted parameter inside its physical range (free.Tolerance.hard_range around the declared value).

    A fit that buys its error with a mu scale of 0.03 or a K_t half the declared one has traded a
    parameter against an effect of nearly the same shape (e.g. a Stribeck law with a decay
    speed beyond the data's range against the mu scale); such a fit names nothing.  (A drag or a
    mu below 0 never gets here: the fit holds them at 0, fitting.fit.)
    """
    for name in fitted.free:
        tol = TOLERANCES.get(name)
        bounds = None if tol is None else tol.hard_range(get_value(problem.rig0, name))
        if bounds is None:
            continue
        # outside by more than its own interval: a poorly identified parameter (a gear-side drag with the
        # load near zero) wandering past a bound is no evidence of anything
        value, half = fitted.free_values[name], fitted.free_ci.get(name, 0.0)
        if value + abs(half) < bounds[0] or value - abs(half) > bounds[1]:
            return False
    return True
