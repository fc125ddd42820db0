"""estimator_node's per-sample processing as a plain class: one rig sample in, one estimate out.

A disturbance observer in front of a quasi-static map. Per sample (ω_w [rad/s], i [A]):

1. Matched input filter. ω and i pass through identical cascades of
   INPUT_FILTER_STAGES first-order low-passes (time constant ``input_filter``
   each); α is the backward difference of the filtered speed. The current
   that accelerates the inertia, J_eff·α/K_t (Eq. 28), is taken out
   (quasi_static.inertia_free_current). Because the current and the speed
   whose derivative is subtracted went through the same filter, what is left
   is the filtered (K_t·i − J_eff·α), i.e. the filtered load-plus-drag torque,
   at every frequency: current the controller's feedforward spends on
   accelerating the rig is not read as load, so feeding the estimate forward
   does not close a loop through the estimator (physics.md §8). Filtering the
   current once and the acceleration twice, as an earlier version did, left a
   transient loop: after a reversal the estimate sat ~0.4 N·m on the wrong
   side of the load for ~0.2 s.
2. Change-gated smoothing. The compensated current is smoothed by a
   first-order low-pass (``estimate_filter``), which sets the estimate's noise
   in steady state. When it departs from its smoothed value by more than
   ``change_threshold`` times its running noise σ, the smoothed value follows
   the fast one for ``change_hold``: a load step reaches the estimate after
   the fast filter's delay (~3 × input_filter), not the smoothing's. σ² is a
   running mean (time constant NOISE_TIME_CONSTANT) of the squared
   departures, each clipped at the threshold, so a step does not inflate it;
   it is not updated while following, and changes are not looked for during
   the first NOISE_TIME_CONSTANT (σ is being learnt). The speed is not
   smoothed: after the fast filter its noise (~0.2 rad/s) moves the map's
   output far less than the current's does, and it must follow a reversal.
3. The configured estimator (e.g. k-NN) maps (ω_f, smoothed i) to τ_d [N·m]
   (positive opposing positive worm rotation) with an uncertainty and flags;
   a sample taken while |α| > ``transient_acceleration`` is flagged TRANSIENT, and so is every
   sample for TRANSIENT_MEMORY smoothing time constants (``estimate_filter``) after the last such:
   the smoothed current still holds the acceleration's share the compensation left (after a
   reversal the estimate overshoots the load for about two smoothing time constants once the worm's
   acceleration has ended: test_standard_outputs), and the map does not hold for it.
   One that takes the gear ripple out (base.AngleEstimator with ``uses_angle``:
   extended_model with periodic effects) also gets the sample's encoder angle ``theta``
   (the ripple it removes turns once per gear turn, slow beside the filters' delay).
4. What the map's estimate is worth here (:meth:`LiveEstimator.judge`). On a drive that self-locks at
   rest (its mesh's friction at zero speed above cos(phi_n) tan(lambda)), a standing worm shows nothing
   of its load (the mesh's friction holds it): standing is its filtered speed within
   worm_model.physics.resolution.standstill_speed of 0 (twice the rig's own speed noise), and the mean
   of the last STILL_SAMPLES within the same band of that mean's noise (one noisy sample of a slowly
   moving worm does not stop it); the last moving estimate is then held, flagged STANDSTILL, its
   uncertainty growing (branches.Hold), and after a stop until the worm's motion has lasted
   (branches.Hold.keeps: a noisy sample off zero does not end it). The standing test reads every
   filtered sample's speed and the hold counts every filtered sample, so its times (a stop's, the
   motion's before it ends, the uncertainty's growth) are the same when only some samples are mapped and
   judged (estimate_filtered, a JointState's published samples). A moving one where the map found
   two candidate loads (a self-locking drive's V) takes the one the branch tracker tells apart
   (branches.BranchTracker: the load prior, a load that persists across a stop or a reversal);
   AMBIGUOUS is left only where nothing does.

Streaming estimators (base.StreamingEstimator: ``stream(sample_period)`` gives an
EstimateStream, e.g. the model-based observer of estimation/observer/) replace steps 1-3:
every sample goes to the stream as it is, with the applied drive voltage and the encoder
angle (``update``'s ``voltage`` and ``theta``; a missing voltage is an invalid input to the
observer, and not read by the momentum observer of estimation/momentum/), and its estimate is
returned.

A NaN/inf input gives an INVALID_INPUT estimate and leaves every state as it
was. Given each sample's seq, it also follows the stream's continuity: lost
samples (a seq gap up to MAX_GAP) are skipped over (the observer predicts
across them; the filters take the next sample as the next, without an
acceleration across the gap), and a seq that goes back or jumps further
(a restarted rig or driver, a new rig clock) starts every state again, so
nothing of the old session leaks into the new one. Used by estimator_node, replay,
``estimate``, the rig feedforward and the benchmarks (estimation.settings builds it for
them), so all run the same code. No ROS.

Why these defaults (bench/controller_bench.py, the bundled rig: tacho noise
0.5 rad/s, 1 rad/s ADC step and 1 % commutator ripple; current noise 0.02 A):
three 3 ms stages keep α's noise near 45 rad/s² at 150 rad/s (two stages of
3 ms: ~120; three of 2 ms: ~115, and 3-6 % of steady samples cross the
TRANSIENT threshold) while a step takes ~16 ms to 90 %; 50 ms of smoothing
brings the estimate's steady noise back to that of a single 50 ms filter.
With the k-NN map (seeds 0, 1; worst dip / summed IAE of the 4 load steps,
feedforward on; off: 4.90 rad/s / 2.29 rad): input_filter 2, 3, 4 ms: 3.8 / 1.00,
4.0 / 0.96, 4.2 / 0.98 (2 ms: 3-6 % of steady samples falsely flagged TRANSIENT);
change_threshold 0 (plain smoothing): 4.8 / 1.54; 3, 4, 5 sigma alike;
estimate_filter 0.1 s: IAE -4 % but small load changes (below the threshold) take
2x longer. estimator_node declares these options (registry.MAP_OPTIONS) for the
methods that run behind these filters.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import make_gear_side_drag_float
from worm_model.physics.parameters import Rig
from worm_model.physics.resolution import current_sigma, standstill_speed
from worm_model.rig_data.estimate import Estimate

from collections.abc import Sequence

import numpy as np

from torque_estimator.estimation.base import (AngleEstimator, EstimateFlags, EstimateStream, StreamingEstimator,
                                              TorqueEstimator)
from torque_estimator.estimation.branches import BranchTracker, Hold, LoadPrior, arm_of, hold_drift
from torque_estimator.estimation.quasi_static import make_inertia_free_current_float

#: First-order stages of the matched input filter (speed and current alike).
INPUT_FILTER_STAGES = 3
#: Time constant [s] of the running noise estimate of the change detector.
NOISE_TIME_CONSTANT = 0.5
#: Largest seq gap [samples] bridged; a longer one (or a seq going back) is a new rig session.
MAX_GAP = 100
#: Smoothing time constants after the last sample beyond ``transient_acceleration`` that are still TRANSIENT.
TRANSIENT_MEMORY = 3.0
#: Samples whose mean speed decides a standstill with the sample's own (step 4): one noisy sample of a slowly
#: moving worm does not stop it, a stop is seen within these samples.
STILL_SAMPLES = 3


@dataclass(frozen=True)
class Filtered:
    """One sample after LiveEstimator's filters (steps 1-2), before the map (step 3): what
    :func:`estimate_filtered` maps, several at once.

    Attributes:
        omega [rad/s], current [A]: the filtered speed and inertia-free, smoothed current (held over an
            invalid sample); theta [rad]: the encoder angle for a map that takes the ripple out, else None;
        flags: INVALID_INPUT and TRANSIENT of the sample (the map adds its own).
    """

    omega: float
    current: float
    theta: float | None
    flags: int


def estimate_filtered(estimator: TorqueEstimator, samples: Sequence[Filtered]) -> list[Estimate]:
    """The map's estimates of several filtered samples (of one or several rigs) in one vectorised call (step 3),
    at the cost of one (a quasi-static map costs about the same for one sample as for a few hundred); each
    rig's :meth:`LiveEstimator.judge` then takes its own (step 4), as :meth:`LiveEstimator.update` does. The
    angle is passed when every sample has one."""
    if not samples:
        return []
    omega = np.array([s.omega for s in samples])
    current = np.array([s.current for s in samples])
    angles = [s.theta for s in samples]
    if all(a is not None for a in angles) and isinstance(estimator, AngleEstimator) and estimator.uses_angle:
        result = estimator.estimate(omega, current, theta_worm=np.array(angles))
    else:
        result = estimator.estimate(omega, current)
    torque, spread, flags = (np.asarray(x).tolist() for x in (result.torque, result.uncertainty, result.flags))
    other = [math.nan] * len(samples) if result.other is None else np.asarray(result.other).ravel().tolist()
    return [Estimate(float(torque[k]), float(spread[k]), int(flags[k]) | s.flags, s.omega, s.current,
                         float(other[k])) for k, s in enumerate(samples)]


class _Cascade:
    """``stages`` equal first-order low-passes in series; starts at the first sample."""

    def __init__(self, time_constant: float, period: float, stages: int) -> None:
        self.blend = 1.0 if time_constant == 0 else 1.0 - math.exp(-period / time_constant)
        self.state: list[float] | None = None
        self.stages = stages

    def noise_gain(self) -> float:
        """[1] the standard deviation of the output over that of a white input: sqrt of the impulse response's
        sum of squares (each stage's response is geometric; summed until the tail is below 1e-12)."""
        if self.blend >= 1.0:
            return 1.0
        state, total, x = [0.0] * self.stages, 0.0, 1.0
        for _ in range(100000):
            for n in range(self.stages):
                state[n] += self.blend * (x - state[n])
                x = state[n]
            total += x * x
            if x * x < 1e-24 and total > 0.0:
                break
            x = 0.0
        return math.sqrt(total)

    def update(self, sample: float) -> float:
        if self.state is None:
            self.state = [sample] * self.stages
            return sample
        x = sample
        for n in range(self.stages):
            self.state[n] += self.blend * (x - self.state[n])
            x = self.state[n]
        return x


class ChangeGatedLowPass:
    """First-order low-pass that follows its input at once during a detected change.

    Per sample: y += b·(x − y) (b from ``time_constant``). The running noise
    σ² is the mean of min(|x − y|, threshold·σ)² over ``noise_time_constant``
    (unclipped while it is first learnt, during the first
    ``noise_time_constant``). After that, |x − y| > ``threshold``·σ is a
    change: y = x for the next ``hold`` [s], and σ is not updated meanwhile.
    ``threshold`` <= 0: no change detection (a plain low-pass);
    ``time_constant`` 0: y = x. σ is never taken below ``noise_floor`` (the sensor's own noise through
    the filters before the gate, LiveEstimator's input filter: a stream that starts at standstill, where
    a drive's export reads exactly 0, would learn σ = 0 and take every later sample for a change).
    """

    def __init__(self, time_constant: float, period: float, threshold: float, hold: float,
                 noise_time_constant: float = NOISE_TIME_CONSTANT, noise_floor: float = 0.0) -> None:
        if time_constant < 0 or period <= 0 or hold < 0 or noise_time_constant <= 0:
            raise ValueError(f"need time_constant >= 0, period > 0, hold >= 0, noise_time_constant > 0; got "
                             f"{time_constant}, {period}, {hold}, {noise_time_constant}")
        self.blend = 1.0 if time_constant == 0 else 1.0 - math.exp(-period / time_constant)
        self.noise_blend = 1.0 - math.exp(-period / noise_time_constant)
        self.threshold = threshold
        # at least one sample each: at a slow sample rate (an export every 40 ms) a 20 ms hold is still one
        self.noise_floor = float(noise_floor)
        self.hold_samples = max(1, int(round(hold / period))) if hold > 0 else 0
        self.learn_samples = max(1, int(round(noise_time_constant / period)))
        self.value: float | None = None
        self.variance = 0.0  # sigma^2, in the input's unit squared
        self.samples = 0
        self.following = 0  # samples left to follow the input
        self.changes = 0  # changes detected so far

    def update(self, x: float) -> float:
        """Feed one sample; returns the smoothed value."""
        if self.value is None:
            self.value = x
        self.value += self.blend * (x - self.value)
        departure = x - self.value
        learning = self.samples < self.learn_samples
        limit = self.threshold * max(math.sqrt(self.variance), self.noise_floor)
        if not self.following:
            clipped = departure if learning else max(-limit, min(limit, departure))
            self.variance += self.noise_blend * (clipped * clipped - self.variance)
        self.samples += 1
        if self.threshold > 0 and not learning and abs(departure) > limit:
            self.changes += not self.following
            self.following = self.hold_samples
        if self.following:
            self.value = x
            self.following -= 1
        return self.value


class LiveEstimator:
    """Streaming τ_d estimation for one rig (see module docstring).

    Args:
        rig: rig parameters (inertia and motor constant for the compensation).
        estimator: the quasi-static map lookup (e.g. KnnEstimator).
        sample_period: time between samples [s].
        input_filter: time constant [s] of each stage of the matched filter on speed and current (0: none).
        inertia_compensation: remove J_eff·α/K_t from the current.
        transient_acceleration: |α| [rad/s²] above which an estimate is flagged TRANSIENT.
        estimate_filter: time constant [s] of the smoothing of the compensated current (0: none).
        change_threshold: departure of the compensated current from its smoothed value, in running
            noise σ, that is taken for a change and followed at once (<= 0: never).
        change_hold: how long [s] a detected change is followed.
    """

    def __init__(self, rig: Rig, estimator: TorqueEstimator, sample_period: float, input_filter: float = 0.003,
                 inertia_compensation: bool = True, transient_acceleration: float = 200.0,
                 estimate_filter: float = 0.05, change_threshold: float = 4.0, change_hold: float = 0.02) -> None:
        if input_filter < 0 or sample_period <= 0:
            raise ValueError(f"need input_filter >= 0 and sample_period > 0, got {input_filter}, {sample_period}")
        self.rig = rig
        self.estimator = estimator
        self.sample_period = sample_period
        self.inertia_compensation = inertia_compensation
        self.transient_acceleration = transient_acceleration
        self._filters = (input_filter, estimate_filter, change_threshold, change_hold)
        self._memory = int(math.ceil(TRANSIENT_MEMORY * estimate_filter / sample_period))  # [samples]
        self.gaps = 0  # seq gaps bridged (samples lost upstream)
        self.lost = 0  # samples in them
        self.restarts = 0  # new rig sessions seen (seq back or far ahead)
        self._next_seq: int | None = None
        self._uses_angle = isinstance(estimator, AngleEstimator) and bool(estimator.uses_angle)
        self._inertia_free = make_inertia_free_current_float(rig)
        self._gear_drag = make_gear_side_drag_float(rig)  # which arm of the V a lone candidate is on
        #: [rad/s] below which the worm stands (worm_model.physics.resolution: the rig's own speed noise), and what
        #: the last STILL_SAMPLES speeds may sum to: their mean within the band of their own mean's noise
        self.standstill = standstill_speed(rig)
        self._still_sum = STILL_SAMPLES * self.standstill / math.sqrt(STILL_SAMPLES)
        #: a drive that self-locks at rest (its mesh's friction at zero speed above cos(phi_n) tan(lambda)) holds
        #: its load standing by friction: then the estimate is held (step 4)
        self._holds = float(friction_coefficient(rig.friction, rig.gearbox, 0.0)) > rig.gearbox.self_locking_mu
        #: the loads a map's estimate may be (branches.LoadPrior: the estimator's, else unbounded)
        self.prior: LoadPrior = getattr(estimator, "prior", None) or LoadPrior()
        self._start()

    def _start(self) -> None:
        """Every state as before the first sample."""
        input_filter, estimate_filter, change_threshold, change_hold = self._filters
        self.speed = _Cascade(input_filter, self.sample_period, INPUT_FILTER_STAGES)
        self.current = _Cascade(input_filter, self.sample_period, INPUT_FILTER_STAGES)
        self.smooth = ChangeGatedLowPass(estimate_filter, self.sample_period, change_threshold, change_hold,
                                         noise_floor=current_sigma(self.rig) * self.current.noise_gain())
        self._previous_speed: float | None = None
        self._omega = math.nan  # [rad/s] filtered speed of the last valid sample
        self.alpha = 0.0  # [rad/s^2] acceleration of the filtered speed, last sample
        self._transient_left = 0  # samples still TRANSIENT after the last acceleration beyond the threshold
        self.stream: EstimateStream | None = (self.estimator.stream(self.sample_period)
                                              if isinstance(self.estimator, StreamingEstimator) else None)
        # a map's branches and standstill hold (a stream keeps its own: observer.kalman.Branches)
        self.tracker = BranchTracker(self.prior)
        self.hold = Hold(hold_drift(self.prior, self.rig.max_load_torque), self.sample_period)
        self._moving: tuple[float, float] | None = None  # the last moving estimate (torque, uncertainty) [N m]
        self._speeds: deque[float] = deque(maxlen=STILL_SAMPLES)  # the last |omega| [rad/s] filtered
        self._unjudged = 0  # valid samples filtered since the last judged one (they are the hold's time)

    def follow(self, seq: int) -> None:
        """The next sample's seq: bridge a gap or start again (module docstring). update(seq=...) calls it."""
        expected, self._next_seq = self._next_seq, seq + 1
        if expected is None or seq == expected:
            return
        if seq < expected or seq - expected > MAX_GAP:
            self.restarts += 1
            self._start()
            return
        self.gaps += 1
        self.lost += seq - expected
        if self.stream is not None:
            self.stream.skip(seq - expected)
        self._previous_speed = None  # no acceleration across the gap

    @property
    def quasi_static(self) -> bool:
        """Whether the estimator is a map behind this class's filters (:meth:`filter` applies), not a stream."""
        return self.stream is None

    def update(self, omega_worm: float, current_drive: float, *, voltage_drive: float | None = None,
               theta_worm: float | None = None, seq: int | None = None) -> Estimate:
        """Feed one sample: measured worm speed [rad/s] and drive current [A]; by name (RigSample's fields), for a
        streaming estimator also the drive voltage applied during this sample's period [V] and the encoder
        angle [rad] (None: no encoder); seq: the sample's RigSample seq (None: take it as the next)."""
        voltage, theta = voltage_drive, theta_worm
        if self.stream is not None:
            if seq is not None:
                self.follow(seq)
            return self.stream.update(omega_worm=omega_worm, current_drive=current_drive,
                                      voltage_drive=math.nan if voltage is None else voltage, theta_worm=theta)
        f = self.filter(omega_worm, current_drive, theta, seq)
        if f.theta is not None:  # the gear ripple taken out at this angle (extended_model)
            result = self.estimator.estimate(f.omega, f.current, theta_worm=f.theta)
        else:
            result = self.estimator.estimate(f.omega, f.current)
        other = math.nan if result.other is None else float(result.other)
        return self.judge(Estimate(float(result.torque), float(result.uncertainty), int(result.flags) | f.flags,
                                       f.omega, f.current, other))

    def judge(self, raw: Estimate) -> Estimate:
        """Step 4 of the module docstring for one mapped sample (a map's, :meth:`update` or
        :func:`estimate_filtered`; every mapped sample of the stream in order): a standing worm's estimate is
        the last moving one, held (STANDSTILL, its uncertainty growing: branches.Hold); a moving one takes the
        candidate the branch tracker tells apart (AMBIGUOUS only where nothing does: branches.BranchTracker)."""
        if raw.flags & EstimateFlags.INVALID_INPUT or not math.isfinite(raw.omega_worm):
            return raw
        steps, self._unjudged = max(1, self._unjudged), 0  # the samples since the last judged: the hold's time
        if self._holds and abs(raw.omega_worm) <= self.standstill and sum(self._speeds) <= self._still_sum:
            self.tracker.stand()
            start = self._moving if self._moving is not None else (raw.torque, raw.uncertainty)
            self.hold.start(*start)
            torque, spread = self.hold.step(steps)
            flags = (raw.flags & ~int(EstimateFlags.AMBIGUOUS)) | int(EstimateFlags.STANDSTILL)
            return Estimate(torque, spread, flags, raw.omega_worm, raw.current_drive)
        if self.hold.keeps(steps):  # after a stop, motion that has not lasted yet (branches.Hold.keeps)
            torque, spread = self.hold.step(steps)
            flags = (raw.flags & ~int(EstimateFlags.AMBIGUOUS)) | int(EstimateFlags.STANDSTILL)
            return Estimate(torque, spread, flags, raw.omega_worm, raw.current_drive)
        self.hold.end()
        if raw.flags & EstimateFlags.AMBIGUOUS and not math.isfinite(raw.other):  # a map that names no candidate
            self._moving = (raw.torque, raw.uncertainty)
            return raw
        if math.isfinite(raw.other):  # the map's two: its choice on the driving arm, the other on the coast
            driving, coast = raw.torque, raw.other
        elif arm_of(raw.torque, raw.omega_worm, self._gear_drag(raw.omega_worm)) == "driving":
            driving, coast = raw.torque, math.nan
        else:
            driving, coast = math.nan, raw.torque
        settled = (not raw.flags & int(EstimateFlags.TRANSIENT | EstimateFlags.OUT_OF_CALIBRATION)
                   and abs(raw.omega_worm) > 2.0 * self.standstill)  # clearly moving, not a standing worm's jitter
        choice = self.tracker.choose(raw.omega_worm, driving, coast, raw.uncertainty, settled)
        flags = raw.flags & ~int(EstimateFlags.AMBIGUOUS)
        spread = raw.uncertainty
        if choice.ambiguous:
            flags |= int(EstimateFlags.AMBIGUOUS)
            spread = max(spread, abs(choice.other - choice.load))
        if choice.outside:
            flags |= int(EstimateFlags.OUT_OF_CALIBRATION)
        self._moving = (choice.load, raw.uncertainty)
        return Estimate(choice.load, spread, flags, raw.omega_worm, raw.current_drive,
                            choice.other if choice.ambiguous else math.nan)

    def filter(self, omega_worm: float, current_drive: float, theta: float | None = None,
               seq: int | None = None) -> Filtered:
        """Steps 1-2 of the module docstring for one sample of a quasi-static map (not a stream), without
        the map: :meth:`update` is ``filter`` and then the map; :func:`estimate_filtered` maps several
        filtered samples in one call (estimates only where they are read; every sample must be filtered)."""
        if seq is not None:
            self.follow(seq)
        valid = math.isfinite(omega_worm) and math.isfinite(current_drive)
        if valid:
            omega = self.speed.update(omega_worm)
            current = self.current.update(current_drive)
            previous, self._previous_speed = self._previous_speed, omega
            self.alpha = 0.0 if previous is None else (omega - previous) / self.sample_period
            if self.inertia_compensation:
                current = self._inertia_free(current, omega, self.alpha)
            current = self.smooth.update(current)
            self._omega = omega
            self._speeds.append(abs(omega))  # judge's standing test, which reads every sample (step 4)
            self._unjudged += 1
        else:  # hold: the estimate of the state as it was
            omega = self._omega
            current = math.nan if self.smooth.value is None else self.smooth.value
        flags = 0 if valid else int(EstimateFlags.INVALID_INPUT)
        if abs(self.alpha) > self.transient_acceleration:
            self._transient_left = self._memory + 1
        if self._transient_left:
            self._transient_left -= 1
            flags |= int(EstimateFlags.TRANSIENT)
        return Filtered(float(omega), float(current), theta if self._uses_angle else None, flags)


__all__ = ["INPUT_FILTER_STAGES", "MAX_GAP", "NOISE_TIME_CONSTANT", "TRANSIENT_MEMORY", "ChangeGatedLowPass",
           "Filtered", "LiveEstimator", "estimate_filtered"]
