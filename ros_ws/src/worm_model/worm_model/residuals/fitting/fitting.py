"""Fits of the model to the training samples: the drive current (free rig parameters and current effects, by
least squares) and, with a gear encoder, the transmission error (per-run offsets and position effects, linear).

:class:`Problem` holds one analysis' data, split and settings (and the effects' shapes); :func:`fit` fits a set
of effects and returns a :class:`Fit` with its training and held-out errors, BIC terms and intervals.

BIC and confidence intervals use an effective sample size n_eff = n (1 - rho)/(1 + rho),
rho the lag-1 autocorrelation of the training residual (AR(1) approximation), because
1 kHz residuals are not independent samples; confidence intervals are then
least-squares intervals inflated by sqrt(n / n_eff).

Physical bounds: a refitted parameter that cannot be negative (a drag, a friction coefficient:
free.LOWER_BOUNDS) is held at its bound when the unconstrained least squares would take it below
(the fit is then repeated as a bounded least-squares problem), so that a trade-off with the other
parameters never reports a negative drag.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects import Effect, Shapes, channels_of, mask_shapes, regressors
from worm_model.residuals.free import LOWER_BOUNDS, get_value, resolve_parameters, set_values
from worm_model.residuals.model import ModelState, Signals, evaluate
from worm_model.residuals.settings import Settings
from worm_model.residuals.fitting.split import Split

#: the fitted signals and their units
SIGNAL_UNITS = {"current_drive": "A", "transmission_error": "rad"}


@dataclass
class EffectFit:
    """One effect in a fit: its grid parameters and identified values with CI half-widths."""

    effect: Effect
    grid: dict[str, float]
    values: dict[str, float]
    ci: dict[str, float] = field(default_factory=dict)  # half-width at Settings.confidence
    grid_ci: dict[str, tuple[float, float]] = field(default_factory=dict)  # profile interval on the grid

    @property
    def name(self) -> str:
        return self.effect.name


@dataclass
class TeFit:
    """The transmission-error part of a fit [rad at the gear]: per-run offsets plus position effects."""

    offsets: dict[int, float]  # run -> encoder offset [rad]
    prediction: FloatArray
    residual: FloatArray  # measured - model [rad], NaN where not measured
    rms_train: float
    rms_held_out: float
    rss_train: float
    n_train: int
    n_eff: float
    n_params: int


@dataclass
class Fit:
    """A fitted model (declared + effects) and its errors (current; transmission error in ``te``)."""

    rig: Rig
    free: list[str]
    free_values: dict[str, float]
    free_ci: dict[str, float]
    effects: list[EffectFit]
    prediction: FloatArray  # model current [A], every sample
    residual: FloatArray  # measured - model [A]
    rms_train: float
    rms_held_out: float
    rss_train: float
    n_train: int
    n_eff: float
    n_params: int  # of the current model (free parameters, current effects' parameters and grids)
    te: TeFit | None = None
    #: correlation matrix of the free parameters' estimates (order: ``free``); None without any
    free_correlation: np.ndarray | None = None

    @property
    def bic(self) -> float:
        total = bic(self.rss_train, self.n_train, self.n_eff, self.n_params)
        if self.te is not None:
            total += bic(self.te.rss_train, self.te.n_train, self.te.n_eff, self.te.n_params)
        return total

    def rms(self, signal: str) -> float:
        """Held-out RMS of one fitted signal (its own unit)."""
        if signal == "current_drive":
            return self.rms_held_out
        return self.te.rms_held_out if self.te is not None else math.nan

    @property
    def names(self) -> list[str]:
        return [e.name for e in self.effects]


def bic(rss: float, n: int, n_eff: float, k: int) -> float:
    """Gaussian BIC with an effective sample size: n_eff ln(RSS / n) + k ln(n_eff)."""
    return n_eff * math.log(max(rss, 1e-300) / n) + k * math.log(n_eff)


def effective_samples(residual: FloatArray, mask: np.ndarray, run: np.ndarray) -> float:
    """n (1 - rho)/(1 + rho), rho the lag-1 autocorrelation of the residual on mask (AR(1))."""
    n = int(mask.sum())
    pair = mask[:-1] & mask[1:] & (run[:-1] == run[1:])
    if n < 3 or pair.sum() < 2:
        return float(max(n, 1))
    r = residual - residual[mask].mean()
    rho = float(np.sum(r[:-1][pair] * r[1:][pair]) / np.sum(r[mask] ** 2))
    rho = min(max(rho, 0.0), 0.999)
    return float(max(2.0, n * (1.0 - rho) / (1.0 + rho)))


def rms_of(x: FloatArray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else math.nan


class Problem:
    """Data, split and settings of one analysis, with a cache of effect shapes."""

    def __init__(self, rig: Rig, free: Sequence[str], signals: Signals, current: FloatArray,
                 split: Split, settings: Settings) -> None:
        self.rig0 = rig
        # the friction model's mu parameter for free.MU; raises ParameterError for a friction parameter it does not read
        self.free = resolve_parameters(rig, list(free) + [p for p in settings.refit if p not in free])
        self.signals = signals
        self.current = np.asarray(current, dtype=float)
        self.split = split
        self.settings = settings
        self._shapes: dict[tuple, Shapes] = {}
        te = signals.transmission_error
        self.te = None if te is None else np.asarray(te, dtype=float)
        measured = np.zeros(len(signals), dtype=bool) if te is None else np.isfinite(self.te)
        self.te_train = split.train & measured
        self.te_held_out = split.held_out & measured

    def lower_bounds(self, size: int) -> FloatArray:
        """Lower bounds of a parameter vector of ``size`` (free parameters first, then effects' values): the
        physical bound of a free parameter that has one (free.LOWER_BOUNDS), else -inf."""
        low = np.full(size, -np.inf)
        for k, name in enumerate(self.free):
            low[k] = LOWER_BOUNDS.get(name, -np.inf)
        return low

    @property
    def has_te(self) -> bool:
        """The data has a gear encoder and enough transmission-error samples in both sets."""
        return self.te is not None and self.te_train.sum() >= 10 and self.te_held_out.sum() >= 10

    def shapes(self, effect: Effect, rig: Rig, grid: Mapping[str, float]) -> Shapes:
        """(n, p) shapes on every sample, at the declared rig and cached; only the thermal proxy follows ``rig``.

        Always the declared rig, whatever ``rig`` a caller is at: shapes such as a ripple's seen
        response (the rotor inertia, K_t) depend on it, and a cache filled by whichever call
        came first made the fit depend on the order of the search (a screening round at a
        twisted intermediate fit, rotor inertia 0, froze a cogging shape that fitted half the
        ripple).
        """
        key = (effect.name, tuple(sorted(grid.items())))
        if effect.family == "thermal" and self.signals.temperature is None:
            return effect.shapes(rig, self.signals, grid)  # the heating proxy follows the fit
        if key not in self._shapes:
            self._shapes[key] = effect.shapes(self.rig0, self.signals, grid)
        return self._shapes[key]

    # ------------------------------------------------------------------ model as a function of theta
    def _unpack(self, theta: FloatArray, specs: Sequence[tuple[Effect, dict[str, float]]]
                ) -> tuple[Rig, list[tuple[Effect, dict[str, float], dict[str, float]]]]:
        nf = len(self.free)
        rig = set_values(self.rig0, self.free, theta[:nf])
        fitted, k = [], nf
        for effect, grid in specs:
            p = len(effect.parameters)
            fitted.append((effect, {q.name: float(v) for q, v in zip(effect.parameters, theta[k:k + p])}, grid))
            k += p
        return rig, fitted

    def predict(self, theta: FloatArray, specs, mask: np.ndarray | None = None,
                shapes: Sequence[Shapes] | None = None) -> tuple[ModelState, Rig, Signals, list[Shapes]]:
        rig, fitted = self._unpack(theta, specs)
        sig = self.signals if mask is None else self.signals.subset(mask)
        if shapes is None:
            shapes = [self.shapes(e, rig, g) for e, g in specs]
        shapes = [s if mask is None else mask_shapes(s, mask) for s in shapes]
        return evaluate(rig, sig, channels_of(fitted, rig, sig, shapes)), rig, sig, shapes

    def jacobian(self, theta: FloatArray, specs, mask: np.ndarray | None = None,
                 shapes: Sequence[Shapes] | None = None) -> FloatArray:
        """d model current / d theta on the masked samples: numeric for rig parameters, exact for effects."""
        state, rig, sig, sh = self.predict(theta, specs, mask, shapes)
        cols = []
        for k in range(len(self.free)):
            step = 1e-6 * max(abs(theta[k]), 1e-9) if theta[k] != 0 else 1e-9
            bumped = theta.copy()
            bumped[k] += step
            cols.append((self.predict(bumped, specs, mask, shapes)[0].current - state.current) / step)
        for (effect, _grid), s in zip(specs, sh):
            cols.extend(regressors(effect, rig, sig, state, s).T)
        return np.column_stack(cols) if cols else np.zeros((len(sig), 0))

    def theta0(self, previous: Fit | None, specs, guesses: Mapping[str, Mapping[str, float]] | None = None
               ) -> FloatArray:
        base = previous.rig if previous is not None else self.rig0
        theta = [get_value(base, p) for p in self.free]
        known = {e.name: e.values for e in previous.effects} if previous is not None else {}
        guesses = guesses or {}
        for effect, _grid in specs:
            values = known.get(effect.name) or guesses.get(effect.name) or {}
            theta.extend(values.get(p.name, 0.0) for p in effect.parameters)
        return np.asarray(theta, dtype=float)


def by_signal(specs, signal: str) -> list:
    return [(e, g) for e, g in specs if e.fitted_signal == signal]


def grid_count(problem: Problem, specs) -> int:
    return sum(1 for e, _g in specs for _ in e.grid_parameters if len(e.grid(problem.rig0, problem.signals)) > 1)


@dataclass
class _TeSolution:
    coef: FloatArray  # effect coefficients
    cov: FloatArray  # their covariance (least squares, not yet inflated)
    offsets: dict[int, float]
    prediction: FloatArray
    residual: FloatArray
    rss: float


def te_solve(problem: Problem, columns: FloatArray) -> _TeSolution:
    """Least squares of the transmission error on per-run offsets plus ``columns`` (n, p), training samples.

    The offsets are taken out by demeaning each run (Frisch-Waugh); a run without training
    samples gets the median offset of the others.
    """
    te, train, run = problem.te, problem.te_train, problem.signals.run
    y = np.where(np.isfinite(te), te, 0.0)
    X = np.asarray(columns, dtype=float).reshape(len(y), -1)
    runs, index = np.unique(run, return_inverse=True)
    count = np.bincount(index[train], minlength=len(runs)).astype(float)
    fitted = count > 0
    safe = np.maximum(count, 1.0)

    def run_means(v: FloatArray) -> FloatArray:  # (len(runs),) mean of v over each run's training samples
        return np.bincount(index[train], weights=v[train], minlength=len(runs)) / safe

    yc = y[train] - run_means(y)[index[train]]
    Xc = np.column_stack([X[train, j] - run_means(X[:, j])[index[train]] for j in range(X.shape[1])]) \
        if X.shape[1] else np.zeros((int(train.sum()), 0))
    if X.shape[1]:
        coef, *_ = np.linalg.lstsq(Xc, yc, rcond=None)
        cov = np.linalg.pinv(Xc.T @ Xc)
    else:
        coef, cov = np.zeros(0), np.zeros((0, 0))
    part = X @ coef
    offset = run_means(y - part)
    if fitted.any():
        offset[~fitted] = float(np.median(offset[fitted]))
    prediction = offset[index] + part
    residual = np.where(np.isfinite(te), te - prediction, np.nan)
    return _TeSolution(coef, cov, {int(r): float(o) for r, o in zip(runs, offset)}, prediction, residual,
                       float(np.sum(residual[train] ** 2)))


def te_columns(problem: Problem, specs, rig: Rig, state: ModelState) -> FloatArray:
    """Columns of the transmission-error effects in ``specs`` at the model state, (n, p)."""
    cols = [e.te_columns(rig, problem.signals, state, g) for e, g in specs]
    return np.column_stack(cols) if cols else np.zeros((len(problem.signals), 0))


def fit_te(problem: Problem, specs, rig: Rig, state: ModelState) -> tuple[TeFit, list[dict[str, float]],
                                                                             list[dict[str, float]]]:
    """The transmission-error part of a fit: (TeFit, values per TE effect, CI half-widths per TE effect)."""
    # imported at first use: scipy.stats takes ~0.4 s to import, paid at start by every executable
    from scipy.stats import norm

    sol = te_solve(problem, te_columns(problem, specs, rig, state))
    train, held = problem.te_train, problem.te_held_out
    n_train = int(train.sum())
    n_eff = effective_samples(np.nan_to_num(sol.residual), train, problem.signals.run)
    k = len(np.unique(problem.signals.run[train])) + len(sol.coef)
    values, cis = [], []
    if len(sol.coef):
        var = sol.rss / max(n_train - k, 1) * np.diag(sol.cov) * (n_train / n_eff)
        half = norm.ppf(0.5 + problem.settings.confidence / 2.0) * np.sqrt(np.clip(var, 0.0, None))
    j = 0
    for effect, _g in specs:
        p = len(effect.parameters)
        values.append({q.name: float(v) for q, v in zip(effect.parameters, sol.coef[j:j + p])})
        cis.append({q.name: float(h) for q, h in zip(effect.parameters, half[j:j + p])})
        j += p
    te = TeFit(offsets=sol.offsets, prediction=sol.prediction, residual=sol.residual,
               rms_train=rms_of(sol.residual[train]), rms_held_out=rms_of(sol.residual[held]), rss_train=sol.rss,
               n_train=n_train, n_eff=n_eff, n_params=k + grid_count(problem, specs))
    return te, values, cis


def fit(problem: Problem, specs: Sequence[tuple[Effect, dict[str, float]]], previous: Fit | None = None,
        guesses: Mapping[str, Mapping[str, float]] | None = None) -> Fit:
    """Least-squares fit of the free parameters and the effects' parameters on the training samples.

    The current model (free parameters, current effects) by Levenberg-Marquardt; then, with a
    gear encoder, the transmission error (offsets, position effects) linearly at the fitted
    model's state.

    Args:
        specs: [(effect, grid values), ...] to include.
        previous: a fit to start from (its rig and effect values).
        guesses: start values per effect name (e.g. from :func:`screen`).
    """
    # imported at first use: scipy.optimize and scipy.stats take ~0.4 s to import, paid at start by every executable
    from scipy.optimize import least_squares
    from scipy.stats import norm

    train, held = problem.split.train, problem.split.held_out
    cur = by_signal(specs, "current_drive")
    y = problem.current[train]
    shapes = [problem.shapes(e, problem.rig0, g) for e, g in cur]
    theta = problem.theta0(previous, cur, guesses)
    if len(theta):
        sub_shapes = [mask_shapes(s, train) for s in shapes]
        sig_train = problem.signals.subset(train)
        # shapes are passed already masked: predict on the training signals directly
        def residual(th: FloatArray) -> FloatArray:
            rig, fitted = problem._unpack(th, cur)
            return y - evaluate(rig, sig_train, channels_of(fitted, rig, sig_train, sub_shapes)).current

        def jac(th: FloatArray) -> FloatArray:
            return -problem.jacobian(th, cur, train, shapes)

        result = least_squares(residual, theta, jac=jac, method="lm", x_scale="jac", max_nfev=200)
        theta = result.x
        low = problem.lower_bounds(len(theta))
        if np.any(theta < low):  # a drag (mu, inertia) traded below 0: the same problem with the bound held
            result = least_squares(residual, np.maximum(theta, low), jac=jac, bounds=(low, np.inf), method="trf",
                                   x_scale="jac", max_nfev=200)
            theta = np.where(result.active_mask < 0, low, np.maximum(result.x, low))  # on the bound: exactly there
    state, rig, _, _ = problem.predict(theta, cur, None, shapes)
    res = problem.current - state.current
    n_train = int(train.sum())
    rss = float(np.sum(res[train] ** 2))
    n_eff = effective_samples(res, train, problem.signals.run)
    # least-squares covariance, inflated for autocorrelation
    free_ci: dict[str, float] = {}
    free_correlation = None
    cis: list[dict[str, float]] = [{} for _ in cur]
    if len(theta):
        J = problem.jacobian(theta, cur, train, shapes)
        dof = max(n_train - len(theta), 1)
        cov = rss / dof * np.linalg.pinv(J.T @ J) * (n_train / n_eff)
        half = norm.ppf(0.5 + problem.settings.confidence / 2.0) * np.sqrt(np.clip(np.diag(cov), 0.0, None))
        nf = len(problem.free)
        free_ci = dict(zip(problem.free, half[:nf].tolist()))
        sd = np.sqrt(np.clip(np.diag(cov)[:nf], 0.0, None))
        with np.errstate(divide="ignore", invalid="ignore"):
            free_correlation = cov[:nf, :nf] / np.outer(sd, sd)
        k = nf
        for idx, (effect, _g) in enumerate(cur):
            p = len(effect.parameters)
            cis[idx] = {q.name: float(h) for q, h in zip(effect.parameters, half[k:k + p])}
            k += p
    _, fitted = problem._unpack(theta, cur)
    by_name = {e.name: EffectFit(e, dict(g), v, cis[i]) for i, (e, v, g) in enumerate(fitted)}
    te = None
    if problem.has_te:
        te_specs = by_signal(specs, "transmission_error")
        te, te_values, te_cis = fit_te(problem, te_specs, rig, state)
        for (e, g), v, c in zip(te_specs, te_values, te_cis):
            by_name[e.name] = EffectFit(e, dict(g), v, c)
    effects = [by_name[e.name] for e, _g in specs if e.name in by_name]
    return Fit(rig=rig, free=list(problem.free), free_values={p: get_value(rig, p) for p in problem.free},
               free_ci=free_ci, effects=effects, prediction=state.current, residual=res,
               rms_train=rms_of(res[train]), rms_held_out=rms_of(res[held]), rss_train=rss, n_train=n_train,
               n_eff=n_eff, n_params=len(theta) + grid_count(problem, cur), te=te, free_correlation=free_correlation)


