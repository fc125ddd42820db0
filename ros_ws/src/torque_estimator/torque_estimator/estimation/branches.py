"""Two loads, one current: which is the load, on a self-locking drive (physics.md section 8).

A worm drive self-locks when mu > cos(phi_n) tan(lambda): the load cannot back-drive the worm, and
the motor drives whichever way the load pulls. Then the motor torque is V-shaped in the load: the
load being lowered on the coast flank and a smaller one driven on the driving flank ask for the same
torque, so one speed and one current give two candidate loads (the estimators' AMBIGUOUS). What
tells them apart, with what a user knows and what the motion shows:

* **A declared prior** (:class:`LoadPrior`): the load lies in [``load_min``, ``load_max``] [N m]
  (gear frame, + opposing + rotation: a hanging mass lifted by + rotation is positive whatever way
  the drive turns). A candidate outside it is not the load. Without one, the range the model was
  identified or calibrated over stands in (what the estimators' tables span).
* **The motion** (:class:`BranchTracker`): a load that persists across a reversal or a stop has
  one value that both moves' candidates share, and the other candidates differ (the V's arms move
  apart as the flanks swap). The tracker keeps the last load it could tell (a *reference*, from a
  sample where only one candidate was admitted, or one it resolved) and, where two are admitted,
  takes the one within MATCH_SIGMAS of it; on a new move without a reference it compares the
  candidates with the previous move's. Once it has told them apart in a move it keeps that arm of
  the V while the move lasts and the load stays (a ripple of the current that brings both candidates
  near the V's vertex does not move a load off its flank); a load that jumps by more than
  MATCH_SIGMAS is a new load, its arm unknown. Where nothing tells them apart (the load changed, or
  before the first reversal without a prior) the estimate stays AMBIGUOUS: two loads explain it.

A move is the motion between two stops or reversals: :meth:`BranchTracker.choose` sees the sign of
the worm's speed change, :meth:`BranchTracker.stand` a stop. Units SI; loads on the gear shaft. No
ROS; plain Python.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

#: a candidate matches a reference when within this many of their combined standard deviations
MATCH_SIGMAS = 3.0
#: a held load's uncertainty grows by this fraction of the admitted span per square root of a second (Hold)
HOLD_DRIFT = 0.01
#: a standstill is a stop (Hold.stopped) once it lasted this long [s] and this many samples: a reversal passes
#: through zero in a few milliseconds
STOP_TIME, STOP_SAMPLES = 0.1, 3
#: after a stop, the worm moves again once its motion lasted this long [s] and STOP_SAMPLES samples in a row
#: (Hold.keeps): a sample or two off zero is the speed sensor's noise (beyond the 2-sigma band one sample in 22)
RESUME_TIME = 0.02


@dataclass(frozen=True)
class LoadPrior:
    """The loads [N m] the estimate may be: [low, high] (module docstring); ``declared``: the user's, else the
    identification's or calibration's range standing in."""

    low: float = -math.inf
    high: float = math.inf
    declared: bool = False

    def __post_init__(self) -> None:
        if not self.low < self.high:
            raise ValueError(f"load_min / load_max: load_min ({self.low:g} N m) must be below load_max "
                             f"({self.high:g} N m)")

    def admits(self, load: float) -> bool:
        return self.low <= load <= self.high

    def nearest(self, load: float) -> float:
        """How far [N m] ``load`` lies outside the prior (0 inside)."""
        return max(self.low - load, load - self.high, 0.0)

    @classmethod
    def of(cls, load_min: float, load_max: float, fallback: tuple[float, float] | None = None) -> "LoadPrior":
        """The prior of estimator parameters ``load_min``/``load_max`` [N m]: both 0 (their default) means none
        declared, and ``fallback`` (low, high) stands in (None: unbounded).

        Raises:
            ValueError: load_min not below load_max (both 0 aside), or a non-finite bound.
        """
        if load_min == 0.0 and load_max == 0.0:
            return cls(*fallback) if fallback is not None else cls()
        if not (math.isfinite(load_min) and math.isfinite(load_max)):
            raise ValueError(f"load_min / load_max: both must be finite, got {load_min!r}, {load_max!r}")
        if not load_min < load_max:
            raise ValueError(f"load_min / load_max: load_min ({load_min:g} N m) must be below load_max "
                             f"({load_max:g} N m)")
        return cls(float(load_min), float(load_max), declared=True)


@dataclass(frozen=True)
class Choice:
    """What :meth:`BranchTracker.choose` decided: the load [N m], the other candidate still admitted (NaN: none),
    whether nothing told them apart (AMBIGUOUS), and whether no candidate lay in the prior (the nearest taken)."""

    load: float
    other: float
    ambiguous: bool
    outside: bool = False


class BranchTracker:
    """Which candidate is the load, one stream's (module docstring).

    Candidates come labelled by the V's arm: ``driving`` (the flank engaged when the load opposes the motion) and
    ``coast``. Within a move, once the tracker has told them apart it keeps that arm: the branch that persists (a
    load carried along one flank stays on it while the motion does). At a new move it tells them apart again: by
    the reference (the last load it could tell), else by the previous move's candidates.

    Args:
        prior: the admitted loads.
        match: MATCH_SIGMAS.
    """

    def __init__(self, prior: LoadPrior = LoadPrior(), match: float = MATCH_SIGMAS) -> None:
        self.prior = prior
        self.match = match
        self.reference: tuple[float, float] | None = None  # (load, sigma) [N m]: the last load told apart
        self.direction = 0  # sign of the current move's speed, 0 standing
        self.arm: str | None = None  # the arm this move's load is on, once told ("driving", "coast")
        # this move's unresolved candidates (driving, coast, sigma), and the previous move's
        self._pair: tuple[float, float, float] | None = None
        self._previous: tuple[float, float, float] | None = None
        self._count = 0
        self.resolved = 0  # samples told apart by the motion (the arm kept, a reference, the previous move)

    def reset(self) -> None:
        """Forget everything (a new session)."""
        self.__init__(self.prior, self.match)

    def stand(self) -> None:
        """The drive stopped: the move ends (the reference, a load that persists, is kept)."""
        self._end_move()
        self.direction = 0

    def _end_move(self) -> None:
        if self._pair is not None:
            self._previous = self._pair
        self._pair, self._count, self.arm = None, 0, None

    def _matches(self, load: float, sigma: float, reference: tuple[float, float]) -> bool:
        return abs(load - reference[0]) <= self.match * math.hypot(sigma, reference[1])

    def _told(self, arm: str, driving: float, coast: float, sigma: float, settled: bool) -> Choice:
        load, other = (driving, coast) if arm == "driving" else (coast, driving)
        if settled:
            self.arm = arm
            self.reference = (load, sigma)
        self.resolved += 1
        return Choice(load, other, False)

    def choose(self, omega: float, driving: float, coast: float, sigma: float, settled: bool = True) -> Choice:
        """One sample's decision (module docstring): the candidates on the ``driving`` and the ``coast`` arm [N m]
        (NaN: none there; :func:`arm_of` says which arm a lone candidate is on), ``sigma`` [N m] their standard
        deviation, ``omega`` [rad/s] the worm's speed. ``settled``: the estimator trusts the sample otherwise (not
        TRANSIENT: a filter still finding the load, a start from rest): only such a sample tells the tracker a
        reference or an arm; any sample is told by what the tracker knows."""
        direction = (omega > 0) - (omega < 0)
        if direction != self.direction:
            self._end_move()
            self.direction = direction
        candidates = [c for c in (driving, coast) if math.isfinite(c)]
        in_driving = math.isfinite(driving) and self.prior.admits(driving)
        in_coast = math.isfinite(coast) and self.prior.admits(coast)
        if not (in_driving or in_coast):
            if not candidates:
                return Choice(driving, math.nan, False)
            nearest = min(candidates, key=self.prior.nearest)
            return Choice(nearest, math.nan, False, outside=True)
        if in_driving != in_coast:  # one candidate admitted: the load, and the arm it is on
            load = driving if in_driving else coast
            if settled:
                self.reference = (load, sigma)
                self.arm = "driving" if in_driving else "coast"
            return Choice(load, math.nan, False)
        if self.arm is not None:  # the arm this move's load was told on, while the load stays
            kept = driving if self.arm == "driving" else coast
            if self.reference is None or self._matches(kept, sigma, self.reference):
                return self._told(self.arm, driving, coast, sigma, settled)
            self.arm, self.reference = None, None  # the load changed: nothing tells its arm now
        if self.reference is not None:
            hit_d, hit_c = self._matches(driving, sigma, self.reference), self._matches(coast, sigma, self.reference)
            if hit_d != hit_c:
                return self._told("driving" if hit_d else "coast", driving, coast, sigma, settled)
        if self._previous is not None:
            pd, pc, ps = self._previous
            hits = [arm for arm, c in (("driving", driving), ("coast", coast))
                    if any(self._matches(c, sigma, (p, ps)) for p in (pd, pc))]
            if len(hits) == 1:
                return self._told(hits[0], driving, coast, sigma, settled)
        if not settled:
            return Choice(driving, coast, True)
        # nothing tells them apart: this move's candidates, averaged, for the next move to compare with
        self._count += 1
        if self._pair is None:
            self._pair = (driving, coast, sigma)
        else:
            w = 1.0 / self._count
            pd, pc, ps = self._pair
            self._pair = (pd + w * (driving - pd), pc + w * (coast - pc), ps + w * (sigma - ps))
        return Choice(driving, coast, True)


def arm_of(load: float, omega: float, gear_drag: float) -> str:
    """The V's arm a load [N m] is on at worm speed ``omega`` [rad/s]: "driving" where the mesh carries it against
    the motion, sigma (load + gear-side drag) >= 0 (physics.md section 5: the switching torque), else "coast"."""
    sigma = -1.0 if omega < 0 else 1.0
    return "driving" if sigma * (load + gear_drag) >= 0 else "coast"


class Hold:
    """The standstill hold (module docstring of EstimateFlags.STANDSTILL): a standing worm shows nothing of its
    load, so the last moving estimate is held and its uncertainty grows as a random walk of ``drift``
    [N m/sqrt(s)] (the load may change while nothing shows it)."""

    def __init__(self, drift: float, period: float) -> None:
        self.variance_rate = drift * drift * period  # [(N m)^2] per sample
        self.held: tuple[float, float] | None = None  # (load, variance)
        self.samples = 0  # of the standstill so far
        self.stop_samples = max(STOP_SAMPLES, int(math.ceil(STOP_TIME / period)))
        self.resume_samples = max(STOP_SAMPLES, int(math.ceil(RESUME_TIME / period)))
        self.moving = 0  # moving samples in a row since the last standing one

    @property
    def stopped(self) -> bool:
        """The standstill has lasted STOP_TIME and STOP_SAMPLES: a stop, not a reversal's pass through zero."""
        return self.samples >= self.stop_samples

    def start(self, load: float, sigma: float) -> None:
        """A standing sample: hold (``load`` [N m], ``sigma`` [N m]) unless a load is held already."""
        self.moving = 0
        if self.held is None:
            self.held = (load, sigma * sigma)
            self.samples = 0

    def step(self, samples: int = 1) -> tuple[float, float]:
        """(held load [N m], its sigma [N m]) ``samples`` further into the standstill (more than one where only
        some samples are judged: the hold's times are in samples of the stream)."""
        load, variance = self.held
        self.held = (load, variance + samples * self.variance_rate)
        self.samples += samples
        return load, math.sqrt(self.held[1])

    def keeps(self, samples: int = 1) -> bool:
        """On a moving sample (``samples`` of them since the last judged): whether the hold stays. A stop's hold
        ends once the motion has lasted RESUME_TIME and STOP_SAMPLES samples in a row (a sample off zero is
        noise; a start is motion that lasts); any other standstill's (a reversal's pass through zero) at once."""
        if self.held is None or not self.stopped:
            return False
        self.moving += samples
        return self.moving < self.resume_samples

    def end(self) -> None:
        self.held = None
        self.moving = 0


def hold_drift(prior: LoadPrior, scale: float) -> float:
    """[N m/sqrt(s)] a held load's uncertainty grows by: 1 % of the admitted span (or of ``scale`` [N m] when the
    prior is unbounded) per square root of a second, the load process' drift (observer.noise.LoadProcess)."""
    span = prior.high - prior.low if math.isfinite(prior.high - prior.low) else 2.0 * scale
    return HOLD_DRIFT * span


__all__ = ["BranchTracker", "Choice", "HOLD_DRIFT", "Hold", "LoadPrior", "MATCH_SIGMAS", "RESUME_TIME", "STOP_SAMPLES",
           "STOP_TIME", "arm_of", "hold_drift"]
