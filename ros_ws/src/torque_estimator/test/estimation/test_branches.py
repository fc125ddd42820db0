"""Which of two candidate loads is the load on a self-locking drive (torque_estimator.estimation.branches).

The prior (LoadPrior: declared, a fallback standing in, or none), the tracker's decisions sample by sample
(BranchTracker: one admitted candidate, a reference, the previous move, the arm kept within a move, a load that
jumps, unsettled samples, stops), the V's arm of a load (arm_of) and the standstill hold (Hold, hold_drift). The
candidate pairs are made up: the tracker sees numbers, not a model.
"""
from __future__ import annotations

import math

import pytest

from torque_estimator.estimation.branches import (HOLD_DRIFT, MATCH_SIGMAS, RESUME_TIME, STOP_SAMPLES, STOP_TIME,
                                                  BranchTracker, Choice, Hold, LoadPrior, arm_of, hold_drift)

SIGMA = 0.005  # [N m] the candidates' standard deviation in the tracker cases
MATCH = MATCH_SIGMAS * math.hypot(SIGMA, SIGMA)  # how far a candidate may lie from a reference of the same sigma
PRIOR = LoadPrior.of(-0.1, 0.3)  # [N m] both arms' candidates of the cases below lie in it unless said


def _ambiguous_move(tracker: BranchTracker, omega: float, driving: float, coast: float, samples: int = 3) -> None:
    """A move in which nothing tells the candidates apart: every sample AMBIGUOUS."""
    for _ in range(samples):
        assert tracker.choose(omega, driving, coast, SIGMA) == Choice(driving, coast, True)


# --------------------------------------------------------------------------- LoadPrior
def test_no_declared_prior_is_the_fallback_or_unbounded() -> None:
    """load_min = load_max = 0 (the estimators' defaults) declares nothing: the fallback range stands in, else
    every load is admitted."""
    none = LoadPrior.of(0.0, 0.0)
    assert (none.low, none.high, none.declared) == (-math.inf, math.inf, False)
    assert none.admits(-1e9) and none.admits(1e9) and none.nearest(1e9) == 0.0
    fallback = LoadPrior.of(0.0, 0.0, (-0.2, 0.25))
    assert (fallback.low, fallback.high, fallback.declared) == (-0.2, 0.25, False)
    with pytest.raises(ValueError, match="below"):
        LoadPrior.of(0.0, 0.0, (0.25, -0.2))  # a fallback is checked like any prior


def test_a_declared_prior() -> None:
    """Declared bounds are kept as floats and marked declared; a 0 at one end is a bound, not "none"."""
    prior = LoadPrior.of(-1, 2)
    assert (prior.low, prior.high, prior.declared) == (-1.0, 2.0, True)
    assert isinstance(prior.low, float) and isinstance(prior.high, float)
    lifting_only = LoadPrior.of(0.0, 0.5)
    assert lifting_only.declared and lifting_only.low == 0.0 and not lifting_only.admits(-0.01)


@pytest.mark.parametrize("low, high", [(0.2, 0.2), (0.3, -0.1), (math.nan, 0.1), (-0.1, math.nan),
                                       (-math.inf, 0.1), (0.0, math.inf), (math.nan, math.nan)])
def test_an_impossible_prior_raises(low: float, high: float) -> None:
    """load_min not below load_max, or a bound that is not finite (NaN included), is refused."""
    with pytest.raises(ValueError, match="load_m"):
        LoadPrior.of(low, high)


def test_admits_and_nearest() -> None:
    """The bounds are admitted; nearest is the distance outside (0 inside), on either side."""
    prior = LoadPrior.of(-0.1, 0.3)
    assert prior.admits(-0.1) and prior.admits(0.3) and prior.admits(0.0)
    assert not prior.admits(-0.1000001) and not prior.admits(0.3000001) and not prior.admits(math.nan)
    assert prior.nearest(0.1) == 0.0 and prior.nearest(-0.1) == 0.0 and prior.nearest(0.3) == 0.0
    assert prior.nearest(0.35) == pytest.approx(0.05) and prior.nearest(-0.4) == pytest.approx(0.3)


# --------------------------------------------------------------------------- BranchTracker
@pytest.mark.parametrize("driving, coast, arm", [(0.2, -0.5, "driving"), (0.7, 0.1, "coast"),
                                                 (math.nan, 0.1, "coast"), (0.2, math.nan, "driving")])
def test_one_admitted_candidate_is_the_load(driving: float, coast: float, arm: str) -> None:
    """A candidate outside the prior (or none on that arm: NaN) is not the load: the other is, not AMBIGUOUS, and
    a settled sample makes it the reference and its arm this move's."""
    load = driving if arm == "driving" else coast
    tracker = BranchTracker(PRIOR)
    choice = tracker.choose(10.0, driving, coast, SIGMA)
    assert (choice.load, choice.ambiguous, choice.outside) == (load, False, False) and math.isnan(choice.other)
    assert tracker.reference == (load, SIGMA) and tracker.arm == arm


def test_an_unsettled_lone_candidate_sets_nothing() -> None:
    """settled=False (a filter still finding the load): the lone admitted candidate is still the answer, but
    neither the reference nor the arm is taken from it."""
    tracker = BranchTracker(PRIOR)
    choice = tracker.choose(10.0, 0.2, -0.5, SIGMA, settled=False)
    assert choice.load == 0.2 and not choice.ambiguous
    assert tracker.reference is None and tracker.arm is None


def test_two_admitted_without_anything_to_tell_them_apart_are_ambiguous() -> None:
    """No reference and no previous move: both candidates are returned, AMBIGUOUS, over the whole first move."""
    tracker = BranchTracker(PRIOR)
    _ambiguous_move(tracker, 10.0, 0.10, -0.05, samples=5)
    assert tracker.reference is None and tracker.arm is None and tracker.resolved == 0


def test_a_load_persisting_across_a_reversal_is_told_and_its_arm_kept() -> None:
    """First move: (0.10 driving, -0.05 coast), nothing tells them apart. Reversed, the load that persists is on
    the other flank: (-0.02 driving, 0.10 coast); only 0.10 matches a previous candidate, so it is the load (coast
    arm, the reference). Later in that move a ripple brings both candidates within MATCH_SIGMAS of it: the kept
    arm (coast) still answers, which the reference alone could not."""
    tracker = BranchTracker(PRIOR)
    _ambiguous_move(tracker, 10.0, 0.10, -0.05)
    assert abs(-0.02 - -0.05) > MATCH  # the other candidate matches neither of the previous move's
    choice = tracker.choose(-10.0, -0.02, 0.10, SIGMA)
    assert choice == Choice(0.10, -0.02, False)
    assert tracker.arm == "coast" and tracker.reference == (0.10, SIGMA) and tracker.resolved == 1
    close = (0.095, 0.105)  # (driving, coast): both within MATCH of 0.10
    assert all(abs(c - 0.10) <= MATCH for c in close)
    assert tracker.choose(-10.0, *close, SIGMA) == Choice(0.105, 0.095, False)
    assert tracker.arm == "coast" and tracker.reference == (0.105, SIGMA) and tracker.resolved == 2
    # the same sample at the start of a new move (the arm forgotten, the reference kept): nothing tells them apart
    tracker.stand()
    assert tracker.arm is None and tracker.reference == (0.105, SIGMA)
    assert tracker.choose(-10.0, *close, SIGMA).ambiguous


def test_the_previous_move_is_its_candidates_averaged() -> None:
    """The previous move is compared by its candidates' mean: samples at 0.09 and 0.11 (tight sigma) make 0.10,
    which a reversed candidate of 0.10 matches, though it is 3.5 sigma off each sample."""
    sigma = 0.001
    tracker = BranchTracker(PRIOR)
    for driving in (0.09, 0.11):
        assert tracker.choose(10.0, driving, -0.05, sigma).ambiguous
    assert abs(0.10 - 0.11) > MATCH_SIGMAS * math.hypot(sigma, sigma)
    assert tracker.choose(-10.0, 0.25, 0.10, sigma) == Choice(0.10, 0.25, False)


def test_a_load_that_jumps_is_a_new_load_its_arm_unknown() -> None:
    """Told on the coast arm at 0.10; then the coast candidate jumps to 0.20, beyond MATCH_SIGMAS: the arm and
    the reference are forgotten and, neither candidate matching the previous move's, the sample is AMBIGUOUS."""
    tracker = BranchTracker(PRIOR)
    _ambiguous_move(tracker, 10.0, 0.10, -0.05)
    assert not tracker.choose(-10.0, -0.02, 0.10, SIGMA).ambiguous
    jumped = (-0.09, 0.20)
    assert all(abs(c - p) > MATCH for c in jumped for p in (0.10, -0.05))
    assert tracker.choose(-10.0, *jumped, SIGMA) == Choice(*jumped, True)
    assert tracker.arm is None and tracker.reference is None


def test_unsettled_samples_are_told_but_teach_nothing() -> None:
    """settled=False: a sample the previous move resolves is answered, but sets neither reference nor arm; an
    unresolved move of unsettled samples leaves nothing for the next move to compare with."""
    tracker = BranchTracker(PRIOR)
    _ambiguous_move(tracker, 10.0, 0.10, -0.05)
    assert tracker.choose(-10.0, -0.02, 0.10, SIGMA, settled=False) == Choice(0.10, -0.02, False)
    assert tracker.arm is None and tracker.reference is None and tracker.resolved == 1

    unsettled = BranchTracker(PRIOR)
    for _ in range(3):
        assert unsettled.choose(10.0, 0.10, -0.05, SIGMA, settled=False) == Choice(0.10, -0.05, True)
    assert unsettled.choose(-10.0, -0.02, 0.10, SIGMA).ambiguous  # the settled one would have told 0.10


def test_stand_ends_the_move_and_keeps_the_reference() -> None:
    """A stop ends the move: the same direction afterwards is a new move, compared with the one before it (which
    it is not while the move lasts); the reference survives the stop and tells the next move's load."""
    tracker = BranchTracker(PRIOR)
    _ambiguous_move(tracker, 10.0, 0.10, -0.05)
    assert tracker.choose(10.0, 0.10, 0.25, SIGMA).ambiguous  # same move: no previous move yet
    tracker.stand()
    assert tracker.direction == 0
    assert tracker.choose(10.0, 0.10, 0.25, SIGMA) == Choice(0.10, 0.25, False)  # the previous move's 0.10
    assert tracker.reference == (0.10, SIGMA)
    tracker.reset()
    assert tracker.reference is None and tracker.resolved == 0 and tracker.prior is PRIOR

    told = BranchTracker(PRIOR)  # a reference from a lone admitted candidate, no previous move
    assert told.choose(10.0, 0.2, -0.5, SIGMA).load == 0.2
    told.stand()
    assert told.reference == (0.2, SIGMA) and told.arm is None and told.direction == 0
    assert told.choose(10.0, 0.05, 0.2, SIGMA) == Choice(0.2, 0.05, False)  # told by the reference alone
    assert told.arm == "coast"


def test_candidates_outside_the_prior_give_the_nearest() -> None:
    """No candidate admitted: the one nearest the prior, marked outside, not AMBIGUOUS, nothing learned."""
    tracker = BranchTracker(PRIOR)
    choice = tracker.choose(10.0, 0.35, -0.5, SIGMA)
    assert (choice.load, choice.ambiguous, choice.outside) == (0.35, False, True) and math.isnan(choice.other)
    choice = tracker.choose(10.0, -0.6, -0.2, SIGMA)
    assert (choice.load, choice.outside) == (-0.2, True)
    choice = tracker.choose(10.0, math.nan, 0.5, SIGMA)
    assert (choice.load, choice.outside) == (0.5, True)
    assert tracker.reference is None and tracker.arm is None


def test_no_candidate_at_all() -> None:
    """Both candidates NaN (the model has no load for this sample): NaN, neither AMBIGUOUS nor outside."""
    tracker = BranchTracker(PRIOR)
    choice = tracker.choose(10.0, math.nan, math.nan, SIGMA)
    assert math.isnan(choice.load) and math.isnan(choice.other) and not choice.ambiguous and not choice.outside
    assert tracker.reference is None


# --------------------------------------------------------------------------- arm_of
def test_arm_of_follows_the_sign_of_the_rotation() -> None:
    """Driving where sigma (load + gear drag) >= 0, sigma the sign of the worm speed (0 counts as +): a mass
    lifted by + rotation is on the driving arm, lowered by - rotation on the coast arm; the drag shifts the
    switch."""
    assert arm_of(0.1, 10.0, 0.0) == "driving" and arm_of(-0.1, 10.0, 0.0) == "coast"
    assert arm_of(0.1, -10.0, 0.0) == "coast" and arm_of(-0.1, -10.0, 0.0) == "driving"
    assert arm_of(-0.005, 10.0, 0.01) == "driving" and arm_of(-0.015, 10.0, 0.01) == "coast"
    assert arm_of(0.005, -10.0, -0.01) == "driving" and arm_of(0.015, -10.0, -0.01) == "coast"
    assert arm_of(-0.01, 10.0, 0.01) == "driving" and arm_of(0.01, -10.0, -0.01) == "driving"  # the switch itself
    assert arm_of(0.1, 0.0, 0.0) == "driving" and arm_of(-0.1, 0.0, 0.0) == "coast"


# --------------------------------------------------------------------------- Hold
@pytest.mark.parametrize("period, samples", [(1e-3, 100), (3e-3, 34), (0.04, 3), (0.1, STOP_SAMPLES)])
def test_a_stop_is_stop_time_and_stop_samples(period: float, samples: int) -> None:
    """Stopped after STOP_TIME of samples (rounded up) and never fewer than STOP_SAMPLES: a reversal's pass
    through zero is not a stop."""
    assert samples * period >= STOP_TIME - 1e-12 and samples >= STOP_SAMPLES
    hold = Hold(0.01, period)
    hold.start(0.1, 0.002)
    for _ in range(samples - 1):
        hold.step()
        assert not hold.stopped
    hold.step()
    assert hold.stopped and hold.stop_samples == samples


def test_the_held_sigma_grows_as_the_square_root_of_time() -> None:
    """sigma^2 = sigma_0^2 + drift^2 t: the load kept, the variance a random walk; a second start keeps the first
    hold, end forgets it."""
    drift, period, sigma0 = 0.02, 1e-3, 0.003
    hold = Hold(drift, period)
    hold.start(0.12, sigma0)
    hold.start(0.5, 0.1)  # already holding: ignored
    out = [hold.step() for _ in range(4000)]
    for k in (1, 100, 1000, 4000):
        load, sigma = out[k - 1]
        assert load == 0.12 and sigma == pytest.approx(math.sqrt(sigma0 ** 2 + drift ** 2 * k * period), rel=1e-12)
    # long after the start the growth is sqrt(t): four times the time, twice the sigma less the start's share
    assert math.sqrt(out[3999][1] ** 2 - sigma0 ** 2) == pytest.approx(2 * math.sqrt(out[999][1] ** 2 - sigma0 ** 2))
    hold.end()
    assert hold.held is None
    hold.start(-0.05, 0.001)
    assert hold.step()[0] == -0.05 and hold.samples == 1


def _stopped(period: float) -> Hold:
    """A hold through a whole stop (STOP_TIME of standing samples)."""
    hold = Hold(0.01, period)
    while not hold.stopped:
        hold.start(0.1, 0.002)
        hold.step()
    return hold


def test_a_stops_hold_outlasts_noise_and_ends_with_motion() -> None:
    """After a stop the hold stays through RESUME_TIME (and STOP_SAMPLES) of motion in a row: 20 samples at 1 kHz,
    the 20th moving sample ends it; a standing sample in between (a blip of speed noise) starts the count again.
    A standstill that was no stop (a reversal's pass through zero) or no hold at all: ended at once."""
    assert RESUME_TIME == 0.02
    hold = _stopped(1e-3)
    assert hold.resume_samples == 20
    assert all(hold.keeps() for _ in range(5))
    hold.start(0.5, 0.1)  # standing again: the count restarts, the load held stays
    assert hold.step()[0] == 0.1
    assert [hold.keeps() for _ in range(20)] == [True] * 19 + [False]
    assert _stopped(0.05).resume_samples == STOP_SAMPLES  # 0.02 s is one sample: STOP_SAMPLES still
    passing = Hold(0.01, 1e-3)
    passing.start(0.1, 0.002)
    for _ in range(10):
        passing.step()
    assert not passing.stopped and not passing.keeps()
    assert not Hold(0.01, 1e-3).keeps()
    hold.end()
    assert not hold.keeps() and hold.moving == 0


def test_hold_drift_is_a_share_of_the_span() -> None:
    """HOLD_DRIFT of the prior's span per sqrt(s); an unbounded (or half-bounded) prior takes 2 x scale."""
    assert hold_drift(LoadPrior.of(-0.1, 0.3), 5.0) == pytest.approx(HOLD_DRIFT * 0.4)
    assert hold_drift(LoadPrior.of(0.0, 0.0, (-0.2, 0.2)), 5.0) == pytest.approx(HOLD_DRIFT * 0.4)
    assert hold_drift(LoadPrior(), 0.275) == pytest.approx(HOLD_DRIFT * 0.55)
    assert hold_drift(LoadPrior(high=0.3), 0.275) == pytest.approx(HOLD_DRIFT * 0.55)
    assert HOLD_DRIFT == 0.01
