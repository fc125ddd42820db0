"""Close the loop on measured data: fit, residual, rank candidate effects, add the significant ones.

The fitted signal is the drive current [A]; with a gear encoder in the data, also the
transmission error ratio theta_worm - theta_gear [rad at the gear] (declared model: a
constant per run, the encoders' zeros; effects with ``fitted_signal = "transmission_error"``,
i.e. backlash, add to it).  The two are fitted separately (the transmission-error terms
are linear and do not enter the current; they see the current model through its mesh
force) and scored each in its own unit; the BIC of a fit is the sum of both signals'.
Procedure (issue 7, physics.md section 9):

1. Split the samples into interleaved time blocks: a fraction is *held out* and never
   enters a fit (:func:`make_split`); a guard interval at every block edge belongs to
   neither set, so no filter reaches across from one set into the other.
2. Fit the declared model (its free parameters) to the training samples (:func:`fit`).
3. Rank every candidate effect by the held-out RMS error left after adding it
   (:func:`screen`: a Gauss-Newton step from the current fit with the effect's
   regressors and the model's own Jacobian, its grid parameters chosen on training data).
4. Take the best candidate (largest relative held-out improvement of its own signal) whose
   full refit lowers that signal's held-out RMS by at least ``min_improvement`` (relative),
   does not raise the other signal's by as much, lowers the BIC on the training samples,
   *and* keeps every refitted parameter physical (:func:`physical`); repeat while one is
   left and the current is above ``at_floor`` x its noise floor.
5. Backward elimination on the held-out blocks: drop any accepted effect that no longer
   earns its keep in the final set (the rest refitted without it: not accepted by the
   criteria of step 4, or the current within ``at_floor`` x its floor without it).
6. Name the effects that are aliases of refitted parameters beyond their tolerance
   (:func:`resolve_aliases`, free.TOLERANCES), report every accepted effect's unique
   contribution with a block-bootstrap interval (:func:`contributions`), estimate the noise
   floor from the data (:func:`noise_floor`) and, when the held-out RMS stays above
   ``unexplained_factor`` x that floor, describe the unexplained residual
   (:func:`describe_unexplained`).

Why this shape (issue 15).  The parameters a rig file typically gets wrong (mu scale, K_t,
drags, rotor inertia: free.STANDARD_REFIT) are refitted always, so that a wrong declared
value, or a wrong reference state of a mu effect (oil temperature, load, speed: they all
modulate mu, whose scale is refitted), shows as a *parameter correction* and not as a
string of effects that each buy 2 %.  Forward selection then only sees what no
correction can produce; backward elimination and the floor rule remove what a later
effect made redundant; an effect that would need a nonphysical correction (a mu scale of
0.03 bought with a 78-fold Stribeck rise) is not taken.  What is left above the floor is
reported as unexplained rather than forced onto a name.

BIC and confidence intervals use an effective sample size n_eff = n (1 - rho)/(1 + rho),
rho the lag-1 autocorrelation of the training residual (AR(1) approximation), because
1 kHz residuals are not independent samples; confidence intervals are then
least-squares intervals inflated by sqrt(n / n_eff).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2, norm

from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects import EFFECTS, Effect, Shapes, channels_of, mask_shapes, regressors
from worm_model.residuals.free import PURE_ALIASES, STANDARD_REFIT, TOLERANCES, get_value, set_values
from worm_model.residuals.model import ALPHA_TIME_CONSTANT, REFERENCE_TEMPERATURE, ModelState, Signals, evaluate, sensitivities


@dataclass(frozen=True)
class Settings:
    """Options of the analysis (the CLI exposes each one)."""

    holdout_fraction: float = 1.0 / 3.0  # share of the blocks held out
    block_seconds: float = 2.0  # length of a split block [s]
    guard_seconds: float = 0.05  # excluded at both ends of every block [s]
    min_speed: float = 5.0  # samples slower than this [rad/s] are not used (no kinetic model at rest)
    min_improvement: float = 0.02  # relative held-out RMS improvement an effect must bring
    # relative held-out RMS rise of the *other* signal (current vs transmission error) an effect may cause;
    # None: min_improvement (a tiny min_improvement would otherwise refuse an effect for a 1e-4 wobble there)
    other_signal_tolerance: float | None = None
    max_effects: int = 6
    alpha_time_constant: float = ALPHA_TIME_CONSTANT  # [s]
    reference_temperature: float = REFERENCE_TEMPERATURE  # [degC] oil temperature at which the declared mu holds
    confidence: float = 0.95
    candidates: tuple[str, ...] = tuple(EFFECTS)
    # refitted always, on top of the caller's free list (free.STANDARD_REFIT: why these)
    refit: tuple[str, ...] = STANDARD_REFIT
    # held-out RMS above this multiple of the noise floor: an unexplained residual is reported
    unexplained_factor: float = 1.3
    # held-out RMS of the current within this multiple of its noise floor: no further current effect is
    # added, and one whose removal stays within it is dropped (its share is below ~half the noise)
    at_floor: float = 1.1
    bootstrap: int = 400  # block-bootstrap resamples for the intervals of unique contributions

    @property
    def other_tolerance(self) -> float:
        """The other signal's allowed relative rise: other_signal_tolerance, or min_improvement when None."""
        return self.min_improvement if self.other_signal_tolerance is None else self.other_signal_tolerance


# --------------------------------------------------------------------------- split
@dataclass
class Split:
    """Boolean masks over the samples; train and held_out never overlap."""

    train: np.ndarray
    held_out: np.ndarray
    block: np.ndarray  # block index per sample (global over runs)

    def __post_init__(self) -> None:
        assert not np.any(self.train & self.held_out)


def make_split(signals: Signals, settings: Settings, finite: np.ndarray | None = None) -> Split:
    """Interleaved block split: of consecutive blocks, a share ``holdout_fraction`` is held out.

    Block j (counted over all runs) is held out when floor((j + 1) f) > floor(j f): the
    held-out blocks are spread evenly over the record, so both sets see every part of
    the experiment (and slow drift).  Samples within ``guard_seconds`` of a block edge,
    slower than ``min_speed``, or not finite (``finite`` mask) are in neither set.
    """
    n = len(signals)
    block = np.zeros(n, dtype=int)
    edge_distance = np.zeros(n)
    offset = 0
    for r in np.unique(signals.run):
        idx = np.flatnonzero(signals.run == r)
        t = signals.t[idx] - signals.t[idx][0]
        local = np.floor(t / settings.block_seconds).astype(int)
        block[idx] = local + offset
        start = local * settings.block_seconds
        end = np.minimum(start + settings.block_seconds, t[-1])
        edge_distance[idx] = np.minimum(t - start, end - t)
        offset += int(local.max()) + 1
    f = settings.holdout_fraction
    held = np.floor((block + 1) * f) > np.floor(block * f)
    usable = (edge_distance >= settings.guard_seconds) & (np.abs(signals.omega) >= settings.min_speed)
    if finite is not None:
        usable &= finite
    return Split(train=usable & ~held, held_out=usable & held, block=block)


# --------------------------------------------------------------------------- fit
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


def _rms(x: FloatArray) -> float:
    return float(np.sqrt(np.mean(x**2))) if len(x) else math.nan


class Problem:
    """Data, split and settings of one analysis, with a cache of effect shapes."""

    def __init__(self, rig: Rig, free: Sequence[str], signals: Signals, current: FloatArray,
                 split: Split, settings: Settings) -> None:
        self.rig0 = rig
        self.free = list(free) + [p for p in settings.refit if p not in free]
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


def _by_signal(specs, signal: str) -> list:
    return [(e, g) for e, g in specs if e.fitted_signal == signal]


def _grid_count(problem: Problem, specs) -> int:
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
               rms_train=_rms(sol.residual[train]), rms_held_out=_rms(sol.residual[held]), rss_train=sol.rss,
               n_train=n_train, n_eff=n_eff, n_params=k + _grid_count(problem, specs))
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
    train, held = problem.split.train, problem.split.held_out
    cur = _by_signal(specs, "current_drive")
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
    state, rig, _, _ = problem.predict(theta, cur, None, shapes)
    res = problem.current - state.current
    n_train = int(train.sum())
    rss = float(np.sum(res[train] ** 2))
    n_eff = effective_samples(res, train, problem.signals.run)
    # least-squares covariance, inflated for autocorrelation
    free_ci: dict[str, float] = {}
    cis: list[dict[str, float]] = [{} for _ in cur]
    if len(theta):
        J = problem.jacobian(theta, cur, train, shapes)
        dof = max(n_train - len(theta), 1)
        cov = rss / dof * np.linalg.pinv(J.T @ J) * (n_train / n_eff)
        half = norm.ppf(0.5 + problem.settings.confidence / 2.0) * np.sqrt(np.clip(np.diag(cov), 0.0, None))
        nf = len(problem.free)
        free_ci = dict(zip(problem.free, half[:nf].tolist()))
        k = nf
        for idx, (effect, _g) in enumerate(cur):
            p = len(effect.parameters)
            cis[idx] = {q.name: float(h) for q, h in zip(effect.parameters, half[k:k + p])}
            k += p
    _, fitted = problem._unpack(theta, cur)
    by_name = {e.name: EffectFit(e, dict(g), v, cis[i]) for i, (e, v, g) in enumerate(fitted)}
    te = None
    if problem.has_te:
        te_specs = _by_signal(specs, "transmission_error")
        te, te_values, te_cis = fit_te(problem, te_specs, rig, state)
        for (e, g), v, c in zip(te_specs, te_values, te_cis):
            by_name[e.name] = EffectFit(e, dict(g), v, c)
    effects = [by_name[e.name] for e, _g in specs if e.name in by_name]
    return Fit(rig=rig, free=list(problem.free), free_values={p: get_value(rig, p) for p in problem.free},
               free_ci=free_ci, effects=effects, prediction=state.current, residual=res,
               rms_train=_rms(res[train]), rms_held_out=_rms(res[held]), rss_train=rss, n_train=n_train,
               n_eff=n_eff, n_params=len(theta) + _grid_count(problem, cur), te=te)


# --------------------------------------------------------------------------- screening
#: the fitted signals and their units
SIGNAL_UNITS = {"current_drive": "A", "transmission_error": "rad"}


@dataclass
class Candidate:
    """One candidate effect's score in one round (linearised from the current fit)."""

    name: str
    grid: dict[str, float]
    rms_held_out: float  # held-out RMS of its signal left after adding it [unit of the signal]
    improvement: float  # relative held-out improvement of its signal over the current fit
    delta_bic: float  # BIC(with) - BIC(without) on training data; < 0 favours the effect
    guess: dict[str, float]  # linear parameter estimates
    note: str = ""
    profile: list[tuple[float, float]] = field(default_factory=list)  # (grid value, training RSS)
    signal: str = "current_drive"  # the signal it acts on

    @property
    def significant(self) -> bool:
        return self.delta_bic < 0.0 and self.improvement >= 0.0

    @property
    def unit(self) -> str:
        return SIGNAL_UNITS[self.signal]


def _screen_te(problem: Problem, current: Fit, effect: Effect, rig: Rig, state: ModelState) -> Candidate:
    """A transmission-error candidate: linear least squares with the TE terms already in, per grid value."""
    base = te_columns(problem, _by_signal([(e.effect, e.grid) for e in current.effects], "transmission_error"),
                      rig, state)
    train, held = problem.te_train, problem.te_held_out
    best, profile = None, []
    for grid in effect.grid(rig, problem.signals):
        cols = effect.te_columns(rig, problem.signals, state, grid)
        sol = te_solve(problem, np.hstack([base, cols]))
        profile.append((grid, sol.rss))
        if best is None or sol.rss < best[1].rss:
            best = (grid, sol)
    grid, sol = best
    te0 = current.te
    n_eff = effective_samples(np.nan_to_num(sol.residual), train, problem.signals.run)
    k_new = len(effect.parameters) + (len(effect.grid_parameters) if len(profile) > 1 else 0)
    d_bic = bic(sol.rss, te0.n_train, n_eff, te0.n_params + k_new) - bic(te0.rss_train, te0.n_train, n_eff,
                                                                         te0.n_params)
    rms_ho = _rms(sol.residual[held])
    coef = sol.coef[base.shape[1]:]
    return Candidate(effect.name, dict(grid), rms_ho, 1.0 - rms_ho / te0.rms_held_out, d_bic,
                     {p.name: float(c) for p, c in zip(effect.parameters, coef)},
                     profile=[(next(iter(g.values()), math.nan), r) for g, r in profile], signal="transmission_error")


def screen(problem: Problem, current: Fit, progress: Callable[[int], None] | None = None) -> list[Candidate]:
    """Score every candidate effect not yet in ``current``; largest relative improvement first.

    A current candidate's columns are fitted together with the model's own Jacobian (free
    parameters and effects already in), i.e. one Gauss-Newton step from the current fit,
    on the training samples.  By Frisch-Waugh-Lovell the candidate's coefficients come
    from its columns projected off the Jacobian (one QR per round), so a candidate costs
    a least-squares problem of its own few columns.  A transmission-error candidate is
    linear: fitted with the offsets and the TE terms already in.  Each is scored on its
    own signal (relative held-out improvement, BIC change).
    """
    train, held = problem.split.train, problem.split.held_out
    use = train | held
    specs = _by_signal([(e.effect, e.grid) for e in current.effects], "current_drive")
    theta = problem.theta0(current, specs)
    state, rig, _, _ = problem.predict(theta, specs)
    sens = sensitivities(rig, problem.signals, state)
    base = problem.jacobian(theta, specs, use)  # model's own directions, re-adjusted with each candidate
    r = current.residual[use]
    tr = train[use]
    b_tr, r_tr = base[tr], r[tr]
    if base.shape[1]:
        q, _ = np.linalg.qr(b_tr / np.maximum(np.linalg.norm(b_tr, axis=0), 1e-300))
    else:
        q = np.zeros((len(r_tr), 0))
    r_perp = r_tr - q @ (q.T @ r_tr)
    out: list[Candidate] = []
    done = 0
    for name in problem.settings.candidates:
        effect = EFFECTS[name]
        if name in current.names:
            continue
        te_effect = effect.fitted_signal == "transmission_error"
        why = effect.unavailable(rig, problem.signals)
        aliased = PURE_ALIASES.get(name, ())
        if not why and aliased and all(p in problem.free for p in aliased):
            why = (f"the same function of the data as the refitted {', '.join(aliased)}: named only when that "
                   f"correction leaves its tolerance band (free.TOLERANCES)")
        if not why and te_effect and not problem.has_te:
            why = "too few transmission-error samples (theta_gear) in the training or held-out set"
        if why:
            rms0 = current.rms(effect.fitted_signal)
            out.append(Candidate(name, {}, rms0, 0.0, math.inf, {}, note=why, signal=effect.fitted_signal))
            continue
        if te_effect:
            out.append(_screen_te(problem, current, effect, rig, state))
            done += 1
            if progress:
                progress(done)
            continue
        best = None
        profile = []
        for grid in effect.grid(rig, problem.signals):
            X = regressors(effect, rig, problem.signals, state, problem.shapes(effect, rig, grid), sens)[use]
            x_tr = X[tr]
            x_perp = x_tr - q @ (q.T @ x_tr)
            norms = np.linalg.norm(x_perp, axis=0)
            norms[norms == 0] = 1.0
            coef, *_ = np.linalg.lstsq(x_perp / norms, r_perp, rcond=1e-10)
            coef = coef / norms
            rss = float(np.sum((r_perp - x_perp @ coef) ** 2))
            profile.append((grid, rss))
            if best is None or rss < best[1]:
                best = (grid, rss, X, coef)
        grid, rss, X, coef = best
        # the model's own parameters move with the candidate: their step from the training rows
        delta, *_ = np.linalg.lstsq(b_tr, r_tr - X[tr] @ coef, rcond=None) if base.shape[1] else (np.zeros(0),)
        left = r - base @ delta - X @ coef
        full = np.zeros(len(problem.current))
        full[use] = left
        n_eff = effective_samples(full, train, problem.signals.run)
        k_new = len(effect.parameters) + (len(effect.grid_parameters) if len(profile) > 1 else 0)
        d_bic = bic(rss, current.n_train, n_eff, current.n_params + k_new) - bic(
            current.rss_train, current.n_train, n_eff, current.n_params)
        rms_ho = _rms(left[~tr])
        out.append(Candidate(name, dict(grid), rms_ho, 1.0 - rms_ho / current.rms_held_out, d_bic,
                             {p.name: float(c) for p, c in zip(effect.parameters, coef)},
                             profile=[(next(iter(g.values()), math.nan), s) for g, s in profile]))
        done += 1
        if progress:
            progress(done)
    return sorted(out, key=lambda c: -c.improvement)


def grid_interval(candidate: Candidate, n_eff: float, n: int, confidence: float) -> tuple[float, float]:
    """Profile-likelihood interval of a 1-D grid parameter: grid values within the chi2(1) bound."""
    if len(candidate.profile) < 2:
        return (math.nan, math.nan)
    rss = np.array([s for _g, s in candidate.profile])
    values = np.array([g for g, _s in candidate.profile])
    stat = n_eff * np.log(rss / rss.min())
    inside = values[stat <= chi2.ppf(confidence, 1)]
    return float(inside.min()), float(inside.max())


# --------------------------------------------------------------------------- the loop
@dataclass
class Round:
    """One round of the search: the ranking and what was added."""

    candidates: list[Candidate]
    accepted: str | None
    refit_rms_held_out: float | None = None
    baseline_rms_held_out: float = math.nan  # held-out RMS of the fit the round started from [A]
    baseline_te_rms_held_out: float = math.nan  # the same for the transmission error [rad] (NaN: none)


@dataclass
class AliasFinding:
    """An effect named because a refitted parameter it is an alias of left its tolerance band.

    ``parameters``: dotted name -> (declared, identified, CI half-width) [SI];
    ``values``/``grid``: the effect in the analysis' parametrisation (effects.py) that, with
    those parameters back at their declared values, gives the same model current;
    ``clamped``: the fit with the parameters held at the band's edge (what "without it" means).
    """

    effect: str
    parameters: dict[str, tuple[float, float, float]]
    values: dict[str, float]
    ci: dict[str, float]
    grid: dict[str, float]
    clamped: Fit


@dataclass
class Contribution:
    """What one accepted effect buys on held-out data: RMS of its signal without it minus with it.

    ``interval``: block-bootstrap interval (held-out blocks resampled, paired) at Settings.confidence.
    """

    name: str
    signal: str
    rms_without: float
    rms_with: float
    interval: tuple[float, float]

    @property
    def delta(self) -> float:
        return self.rms_without - self.rms_with

    @property
    def unit(self) -> str:
        return SIGNAL_UNITS[self.signal]


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


@dataclass
class Analysis:
    declared: Fit  # the declared model, its free parameters fitted (the corrections)
    final: Fit  # with the effects found
    rounds: list[Round]
    split: Split
    pruned: list[str] = field(default_factory=list)
    aliases: list[AliasFinding] = field(default_factory=list)
    contributions: list[Contribution] = field(default_factory=list)
    noise: NoiseFloor | None = None
    unexplained: Unexplained | None = None
    nominal: Fit | None = None  # the rig file as declared, nothing fitted (encoder offsets aside)

    @property
    def rms_before(self) -> float:
        """Held-out RMS of the current [A] by the rig file as declared (nothing fitted)."""
        return (self.nominal or self.declared).rms_held_out

    @property
    def found(self) -> list[str]:
        """Effects named: those fitted, then those named through a parameter beyond its tolerance."""
        names = list(self.final.names)
        names += [a.effect for a in self.aliases if a.effect not in names]
        return names

    @property
    def aliased_parameters(self) -> set[str]:
        return {p for a in self.aliases for p in a.parameters}


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


def analyse(problem: Problem, progress: Callable[[str, int, int], None] | None = None) -> Analysis:
    """Fit the declared model, then add significant effects one at a time (module docstring)."""
    settings = problem.settings
    declared = fit(problem, [])
    current = declared
    rounds: list[Round] = []
    total = len(settings.candidates)
    while len(current.effects) < settings.max_effects:
        label = f"round {len(rounds) + 1}"
        ranking = screen(problem, current, (lambda k: progress(label, k, total)) if progress else None)
        accepted = fallback = None
        at_floor = current.rms_held_out <= settings.at_floor * noise_floor(problem, current).rms
        sane = physical(problem, current)
        tried: list[tuple[Candidate, Fit]] = []  # significant, accepted by the test (unphysical start)
        for cand in ranking:
            if not cand.significant or cand.improvement < settings.min_improvement:
                continue
            if at_floor and cand.signal == "current_drive":
                continue  # the current is already at its noise floor: nothing there left to name
            effect = EFFECTS[cand.name]
            specs = [(e.effect, e.grid) for e in current.effects] + [(effect, cand.grid)]
            trial = fit(problem, specs, current, {cand.name: cand.guess})
            if not accepts(current, trial, settings, effect.fitted_signal, problem):
                continue
            if sane:
                if physical(problem, trial):
                    accepted = (cand, trial)
                    break
                continue
            tried.append((cand, trial))
            # from an unphysical start (an effect the corrections twisted themselves around) every significant
            # candidate is tried: the best held-out one that makes the fit physical, failing one the best
            key = (not physical(problem, trial), trial.rms(effect.fitted_signal) / current.rms(effect.fitted_signal))
            if fallback is None or key < fallback[0]:
                fallback = (key, (cand, trial))
        if accepted is None and fallback is not None:
            fallback = _look_ahead(problem, tried, fallback)
        accepted = accepted or (fallback[1] if fallback else None)
        if accepted is not None:
            cand, trial = accepted
            n_eff = trial.te.n_eff if cand.signal == "transmission_error" else trial.n_eff
            interval = grid_interval(cand, n_eff, trial.n_train, settings.confidence)
            for g in EFFECTS[cand.name].grid_parameters:
                if len(cand.profile) > 1:
                    trial.effects[-1].grid_ci[g.name] = interval
            accepted = (cand.name, trial)
        rounds.append(Round(ranking, accepted[0] if accepted else None,
                            accepted[1].rms_held_out if accepted else None, current.rms_held_out,
                            current.te.rms_held_out if current.te is not None else math.nan))
        if accepted is None:
            break
        grid_cis = {e.name: e.grid_ci for e in current.effects}
        current = accepted[1]
        for e in current.effects:
            e.grid_ci = e.grid_ci or grid_cis.get(e.name, {})
    # backward pass: an effect the later ones made redundant is dropped
    pruned: list[str] = []
    changed = len(current.effects) > 1
    while changed and len(current.effects) > 1:
        changed = False
        for e in list(current.effects):
            rest = [(x.effect, x.grid) for x in current.effects if x is not e]
            without = fit(problem, rest, current)
            # dropped: no longer significant, or not needed to reach the current's noise floor; but never
            # when the rest alone is unphysical (the effect keeps the refitted parameters sane)
            needless = e.effect.fitted_signal == "current_drive" and \
                without.rms_held_out <= settings.at_floor * noise_floor(problem, current).rms
            if (needless or not accepts(without, current, settings, e.effect.fitted_signal, problem)) and (
                    physical(problem, without) or not physical(problem, current)):
                grid_cis = {x.name: x.grid_ci for x in current.effects}
                current = without
                for x in current.effects:
                    x.grid_ci = grid_cis.get(x.name, {})
                pruned.append(e.name)
                changed = True
                break
    aliases = resolve_aliases(problem, current)
    noise = noise_floor(problem, current)
    nominal = fit(Problem(problem.rig0, [], problem.signals, problem.current, problem.split,
                          _replace_settings(settings, refit=())), [])
    unexplained = None
    if current.rms_held_out > settings.unexplained_factor * noise.rms:
        unexplained = describe_unexplained(problem, current, noise)
    return Analysis(declared=declared, final=current, rounds=rounds, split=problem.split, pruned=pruned,
                    aliases=aliases, contributions=contributions(problem, current, aliases), noise=noise,
                    unexplained=unexplained, nominal=nominal)


#: from an unphysical start, the physical first steps judged by what they let in next (see _look_ahead)
LOOK_AHEAD = 3


def _look_ahead(problem: Problem, tried: Sequence[tuple[Candidate, Fit]], fallback):
    """From an unphysical start, pick the first step by the best physical fit two steps make.

    The corrections can twist around an effect (a x3 Stribeck rise at low speed lets the Coulomb and
    viscous drags grow ten-fold); then several effects each make the fit physical again, and the best
    of them alone (a viscous drag) need not be the one that lets the others in (the Stribeck law, after
    which the cogging the twisted start refused is accepted).  So each of the LOOK_AHEAD physical first
    steps with the lowest held-out RMS is paired with each significant candidate it has not taken, and
    the best physical pair that the acceptance test passes is taken, both effects at once (taking only
    its first step let the viscous drag in and kept a x3 Stribeck rise out); the backward pass then
    drops whichever of the two the rest makes needless.  Without such a pair the single best
    (``fallback``) stands.  Only runs from an unphysical start.
    """
    settings = problem.settings
    firsts = sorted(((c, t) for c, t in tried if physical(problem, t)),
                    key=lambda ct: ct[1].rms(EFFECTS[ct[0].name].fitted_signal))[:LOOK_AHEAD]
    if len(firsts) < 2:
        return fallback
    best = None
    for cand, trial in firsts:
        for other, _t in tried:
            if other.name == cand.name:
                continue
            effect = EFFECTS[other.name]
            specs = [(e.effect, e.grid) for e in trial.effects] + [(effect, other.grid)]
            pair = fit(problem, specs, trial, {other.name: other.guess})
            if not (physical(problem, pair) and accepts(trial, pair, settings, effect.fitted_signal, problem)):
                continue
            if best is None or pair.rms_held_out < best[0]:
                best = (pair.rms_held_out, (cand, pair))
    if best is None:
        return fallback
    return ((False, 0.0), best[1])


def physical(problem: Problem, fitted: Fit) -> bool:
    """Every refitted parameter inside its physical range (free.Tolerance.hard: identified / declared).

    A fit that buys its error with a mu scale of 0.03 or a negative drag has traded a
    parameter against an effect of nearly the same shape (e.g. a Stribeck law with a decay
    speed beyond the data's range against the mu scale); such a fit names nothing.
    """
    for name in fitted.free:
        tol = TOLERANCES.get(name)
        declared = get_value(problem.rig0, name)
        if tol is None or tol.hard is None or declared == 0.0:
            continue
        # outside by more than its own interval: a poorly identified parameter (a gear-side drag with the
        # load near zero) wandering past a bound is no evidence of anything
        value, half = fitted.free_values[name], fitted.free_ci.get(name, 0.0)
        low, high = sorted(((value - half) / declared, (value + half) / declared))
        if high < tol.hard[0] or low > tol.hard[1]:
            return False
    return True


# --------------------------------------------------------------------------- aliases of refitted parameters
def _band_edge(name: str, declared: float, identified: float) -> float | None:
    """The nearest edge of the tolerance band when ``identified`` lies beyond it on an alias side, else None."""
    tol = TOLERANCES.get(name)
    if tol is None or tol.effect is None or declared == 0.0:
        return None
    ratio = identified / declared
    if tol.high is not None and ratio > tol.high:
        return tol.high * declared
    if tol.low is not None and ratio < tol.low and not tol.upward_only:
        return tol.low * declared
    return None


def _alias_values(effect: str, rig0: Rig, fitted: Rig, params: Sequence[str]) -> tuple[dict, dict]:
    """The effect's values (and grid) that, with ``params`` back at rig0's values, give ``fitted``'s current."""
    if effect == "sensor_gain":  # i = (1 + g) torque / K_t,declared = torque / K_t,identified
        k0, k1 = rig0.drive_motor.torque_constant, fitted.drive_motor.torque_constant
        return {"drive_current": k0 / k1 - 1.0, "load_current": 0.0}, {}
    if effect == "bearing_coulomb":  # worm: sigma c; gear: load_motor_count c_l sign(omega_gear)
        worm = gear = 0.0
        if "drive_motor.coulomb_drag" in params:
            worm = fitted.drive_motor.coulomb_drag - rig0.drive_motor.coulomb_drag
        if "load_motor.coulomb_drag" in params:
            gear = rig0.load_motor_count * (fitted.load_motor.coulomb_drag - rig0.load_motor.coulomb_drag)
        return {"worm_torque": worm, "gear_torque": gear}, {}
    if effect == "viscous_drag":  # b omega = T_ref omega / omega_ref, exponent 1
        ref = EFFECTS["viscous_drag"].reference_speed
        return ({"worm_torque": (fitted.drive_motor.viscous_drag - rig0.drive_motor.viscous_drag) * ref,
                 "gear_torque": 0.0}, {"exponent": 1.0})
    if effect == "inertia_error":
        return {"worm": fitted.total_worm_inertia / rig0.total_worm_inertia - 1.0}, {}
    raise ValueError(f"no alias translation for {effect}")


def resolve_aliases(problem: Problem, final: Fit) -> list[AliasFinding]:
    """Name the effects whose aliased parameters left their tolerance band *and* earn it on held-out data.

    For each alias effect (free.TOLERANCES), the refitted parameters beyond their band are
    clamped to its edge and the rest refitted: if the final fit beats that clamped fit by
    :func:`accepts`' criteria, the deviation is named as the effect (its whole size from the
    declared value: within the band the split between parameter and effect is not identifiable).
    """
    groups: dict[str, dict[str, float]] = {}
    for name in problem.free:
        edge = _band_edge(name, get_value(problem.rig0, name), final.free_values[name])
        if edge is not None:
            groups.setdefault(TOLERANCES[name].effect, {})[name] = edge
    out = []
    specs = [(e.effect, e.grid) for e in final.effects]
    # significance, not size: the evidence is a fitted parameter already beyond its band, and the clamped
    # fit asks only whether that departure is real or a trade-off with the rest (held-out blocks, BIC). The
    # 2 % rule is for effects that buy their keep from a misfit; with the mu scale free, a 30 % current-sensor
    # gain on top of a K_t declared 5 % low left 1.3 % to the clamp. (The other signal keeps its tolerance.)
    significance = _replace_settings(problem.settings, min_improvement=0.0,
                                     other_signal_tolerance=problem.settings.other_tolerance)
    for effect, edges in groups.items():
        clamped_rig = set_values(problem.rig0, list(edges), list(edges.values()))
        rest = [p for p in problem.free if p not in edges]
        sub = Problem(clamped_rig, rest, problem.signals, problem.current, problem.split,
                      _replace_settings(problem.settings, refit=()))
        clamped = fit(sub, specs, final)
        if not accepts(clamped, final, significance, EFFECTS[effect].fitted_signal, problem):
            continue
        values, grid = _alias_values(effect, problem.rig0, final.rig, list(edges))
        # intervals: the parameters' own, carried through the (linear or 1/x) translation
        ci: dict[str, float] = {}
        for p in edges:
            half = final.free_ci.get(p, math.nan)
            if p == "drive_motor.torque_constant":
                ci["drive_current"] = problem.rig0.drive_motor.torque_constant / final.free_values[p] ** 2 * half
            elif p == "drive_motor.coulomb_drag":
                ci["worm_torque"] = half
            elif p == "load_motor.coulomb_drag":
                ci["gear_torque"] = problem.rig0.load_motor_count * half
            elif p == "drive_motor.viscous_drag":
                ci["worm_torque"] = half * EFFECTS["viscous_drag"].reference_speed
            elif p == "drive_motor.rotor_inertia":
                ci["worm"] = half / problem.rig0.total_worm_inertia
        params = {p: (get_value(problem.rig0, p), final.free_values[p], final.free_ci.get(p, math.nan))
                  for p in edges}
        out.append(AliasFinding(effect, params, values, ci, grid, clamped))
    return out


def _replace_settings(settings: Settings, **changes) -> Settings:
    return replace(settings, **changes)


def extended_effects(result: Analysis) -> tuple[Rig, list[tuple[Effect, dict, dict]]]:
    """The extended model as (rig, [(effect, values, grid)]): alias effects written as effects.

    A parameter named through an alias goes back to its declared value and the effect
    carries the deviation, so the simulator's ``effects:`` section names what was found; the
    model current is the same.  (A viscous_drag already fitted with another exponent cannot
    absorb it: then the parameter keeps its identified value.)
    """
    rig = result.final.rig
    effects = [(e.effect, dict(e.values), dict(e.grid)) for e in result.final.effects]
    for alias in result.aliases:
        existing = next((k for k, (e, _v, _g) in enumerate(effects) if e.name == alias.effect), None)
        if existing is not None:
            e, values, grid = effects[existing]
            if alias.grid and any(grid.get(k) != v for k, v in alias.grid.items()):
                continue
            effects[existing] = (e, {k: values[k] + alias.values.get(k, 0.0) for k in values}, grid)
        else:
            effects.append((EFFECTS[alias.effect], dict(alias.values), dict(alias.grid)))
        rig = set_values(rig, list(alias.parameters), [v[0] for v in alias.parameters.values()])
    return rig, effects


# --------------------------------------------------------------------------- unique contributions
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


def contributions(problem: Problem, final: Fit, aliases: Sequence[AliasFinding]) -> list[Contribution]:
    """Each accepted effect's unique contribution: the final fit against the final fit without it.

    "Without" refits everything else (a fitted effect dropped; an alias's parameters clamped
    at their band edge), so shared explanatory power is not counted twice.
    """
    s = problem.settings
    out = []
    pairs = []
    for e in final.effects:
        rest = [(x.effect, x.grid) for x in final.effects if x is not e]
        pairs.append((e.name, e.effect.fitted_signal, fit(problem, rest, final)))
    pairs += [(a.effect, EFFECTS[a.effect].fitted_signal, a.clamped) for a in aliases]
    for name, signal, without in pairs:
        if signal == "transmission_error" and final.te is not None and without.te is not None:
            r0, r1, mask = without.te.residual, final.te.residual, problem.te_held_out
        else:
            signal = "current_drive"
            r0, r1, mask = without.residual, final.residual, problem.split.held_out
        out.append(Contribution(name, signal, without.rms(signal), final.rms(signal),
                                paired_interval(r0, r1, mask, problem.split.block, s.bootstrap, s.confidence)))
    return out


# --------------------------------------------------------------------------- noise floor, unexplained residual
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


def _explained_by_bins(x: FloatArray, r: FloatArray, bins: int, floor: float) -> tuple[float, FloatArray, FloatArray]:
    """Variance of r explained by its binned means over x (quantile bins), less the noise's share [A^2]."""
    edges = np.unique(np.quantile(x, np.linspace(0.0, 1.0, bins + 1)))
    if len(edges) < 2:
        return 0.0, np.zeros(0), np.zeros(0)
    which = np.clip(np.digitize(x, edges) - 1, 0, len(edges) - 2)
    count = np.bincount(which, minlength=len(edges) - 1).astype(float)
    mean = np.bincount(which, weights=r, minlength=len(edges) - 1) / np.maximum(count, 1.0)
    explained = float(np.sum(count * mean**2) / len(r)) - (len(edges) - 1) * floor**2 / len(r)
    return max(explained, 0.0), 0.5 * (edges[1:] + edges[:-1]), mean


def _explained_by_orders(angle: FloatArray, sigma: FloatArray, r: FloatArray, orders: Sequence[float],
                         floor: float) -> tuple[float, float, float]:
    """(best order, explained variance [A^2], amplitude [A]): sin/cos of order*angle, per direction."""
    best = (math.nan, 0.0, 0.0)
    for k in orders:
        s, c = np.sin(k * angle), np.cos(k * angle)
        X = np.column_stack([s, c, sigma * s, sigma * c])
        coef, *_ = np.linalg.lstsq(X, r, rcond=None)
        fitted = X @ coef
        explained = float(np.mean(fitted**2)) - 4 * floor**2 / len(r)
        if explained > best[1]:
            best = (float(k), explained, float(math.sqrt(2.0 * np.mean(fitted**2))))
    return best


def describe_unexplained(problem: Problem, final: Fit, noise: NoiseFloor) -> Unexplained:
    """Size of the residual above the noise floor and the quantities it goes with (held-out samples).

    Each quantity's share is the variance its best description (binned means; for angles a
    sinusoid of the best order, each direction of rotation its own) takes out of the excess
    variance rms_after^2 - floor^2, corrected for what noise alone would give.
    """
    held = problem.split.held_out
    sig, r = problem.signals, final.residual[held]
    floor = noise.rms
    excess = max(float(np.mean(r**2)) - floor**2, 1e-30)
    sigma = np.where(sig.omega[held] < 0.0, -1.0, 1.0)
    runs, first = np.unique(sig.run, return_index=True)
    t_run = sig.t - sig.t[first][np.searchsorted(runs, sig.run)]  # time since the start of its run [s]
    found: list[Correlation] = []
    binned = [("speed", sig.omega[held], 20, "omega_worm [rad/s]"), ("load", sig.tau_load[held], 20, "tau_load [N m]"),
              ("time", t_run[held], 20, "time within the run [s]"), ("direction", sigma, 2, "sign of omega")]
    if sig.temperature is not None and np.all(np.isfinite(sig.temperature[held])):
        binned.append(("temperature", sig.temperature[held], 20, "temperature [degC]"))
    for name, x, bins, label in binned:
        explained, centre, mean = _explained_by_bins(x, r, bins, floor)
        peak = centre[np.argmax(np.abs(mean))] if len(mean) else math.nan
        found.append(Correlation(name, min(explained / excess, 1.0),
                                 f"binned over {label}; largest bin mean {np.max(np.abs(mean)) if len(mean) else 0:.3g} A "
                                 f"at {peak:.3g}"))
    worm_orders = [float(k) for k in range(1, 61)]
    gear_orders = [float(k) for k in range(1, 31)]
    for name, angle, orders in (("worm angle orders", sig.theta_worm[held], worm_orders),
                                ("gear angle orders", sig.theta_gear[held], gear_orders)):
        k, explained, amplitude = _explained_by_orders(angle, sigma, r, orders, floor)
        found.append(Correlation(name, min(explained / excess, 1.0),
                                 f"best order {k:g} per turn, amplitude {amplitude:.3g} A (each direction its own phase)"))
    found.sort(key=lambda c: -c.share)
    rms_after = float(np.sqrt(np.mean(r**2)))
    return Unexplained(math.sqrt(excess), rms_after / floor, found)
