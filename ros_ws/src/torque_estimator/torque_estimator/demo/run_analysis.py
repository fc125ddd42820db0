"""Figures of merit of a live run, from its recorded streams (plain numpy, no ROS).

Times are seconds from the scenario's start. Each segment is split into a
transient part (the first `settle` seconds after a set-point or load change)
and a steady part (the rest), so tracking and estimation are judged where the
paper judged them (quasi-static) and load-step rejection where it happens.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_rig_driver.robot.standard_outputs import UNTRUSTED

from torque_estimator.evaluation.scenario import segment_starts

#: [s] after a set-point or load change that counts as transient (the steady part starts after it)
SETTLE = 0.8


@dataclass
class RunMetrics:
    speed_rms_error: float  # [rad/s] RMS of omega - set-point over the whole run after the first segment
    peak_dip: float  # [rad/s] largest |omega - set-point| in the transient after a load step
    iae: float  # [rad] integral of |omega - set-point| over the run after the first segment
    estimate_mae_pct: float  # mean |estimate - truth| over the trusted estimates of the steady parts, % of the range
    estimate_max_pct: float  # largest steady-part segment-mean error (trusted estimates), % of the calibrated range
    modes_seen: tuple[int, ...]  # worm_model.physics.modes.Mode values the truth visited
    steady_estimates: int  # estimates in the steady parts
    steady_flagged: int  # of them, flagged untrusted (standard_outputs.UNTRUSTED): left out of the two above
    flagged_max_pct: float  # largest |estimate - truth| among the flagged ones, % of the range (nan: none)


def sample_period(t) -> float:
    """The period [s] each sample of a uniformly sampled record stands for in an integral (IAE): a gap in
    the record (batches not recorded, or the rig's time dilated while its simulation stood still) adds
    nothing, as it would if the step to the next sample were weighted."""
    return float(np.median(np.diff(np.asarray(t, float))))


def load_steps(scenario) -> list[int]:
    """Indices of the segments that start with a pure load step: same speed as the segment before,
    other load."""
    return [k for k in range(1, len(scenario))
            if scenario[k].speed == scenario[k - 1].speed and scenario[k].load != scenario[k - 1].load]


@dataclass
class LoadStepResponse:
    """How the speed loop rejected one load step (times from the step)."""

    segment: int  # index of the segment the step starts
    speed: float  # [rad/s] set-point held through the step
    load_before: float  # [N m]
    load_after: float  # [N m]
    peak_dip: float  # [rad/s] largest |omega - set-point| after the step, within the segment
    settling_time: float  # [s] until |omega - set-point| stays within the band; nan if it never does
    iae: float  # [rad] integral of |omega - set-point| from the step to the segment's end
    band: float  # [rad/s] the settling band used


def load_step_responses(scenario, t, omega, setpoint, band_fraction: float = 0.01,
                        band_floor: float = 0.5) -> list[LoadStepResponse]:
    """Peak dip, settling time and IAE of every pure load step of a scenario.

    Args:
        t: sample times [s] from the scenario's start (uniformly spaced); omega: worm speed
            [rad/s] (the true speed, where known: tacho noise is not a dip); setpoint [rad/s].
        band_fraction, band_floor: settled means |omega - set-point| <= max(band_fraction x
            |set-point|, band_floor) from then to the end of the segment.
    """
    t, error = np.asarray(t), np.abs(np.asarray(omega) - np.asarray(setpoint))
    dt = sample_period(t)
    starts = segment_starts(scenario)
    responses = []
    for k in load_steps(scenario):
        seg = scenario[k]
        inside = (t >= starts[k]) & (t < starts[k] + seg.duration)
        e, te = error[inside], t[inside] - starts[k]
        band = max(band_fraction * abs(seg.speed), band_floor)
        outside = np.flatnonzero(e > band)
        if outside.size == 0:
            settling = 0.0
        elif outside[-1] == len(e) - 1:
            settling = float("nan")  # still outside at the segment's end
        else:
            settling = float(te[outside[-1] + 1])
        responses.append(LoadStepResponse(
            segment=k, speed=seg.speed, load_before=scenario[k - 1].load, load_after=seg.load,
            peak_dip=float(e.max()), settling_time=settling, iae=float(e.sum() * dt), band=band))
    return responses


def setpoints_in_force(t_samples, command_seq, t_commands, setpoints, command_sample_seq) -> np.ndarray:
    """The speed set-point [rad/s] the rig held at each of its samples, from the record alone.

    Each rig sample names the speed command in force (RigSamples command_seq: the sample_seq of that
    SpeedCommand, 0 for none), which is exact whatever the transit: a command stamped at t and taken by
    the rig at the next sample after it arrived counts from there. A sample naming no command, or one the
    record lacks, takes the command stamped last before it (the set-point the graph had asked for).

    Args:
        t_samples, command_seq: each sample's time [s] and the command it names.
        t_commands, setpoints, command_sample_seq: each recorded SpeedCommand's stamp [s], speed_setpoint
            [rad/s] and sample_seq.
    """
    t_samples, named = np.asarray(t_samples, float), np.asarray(command_seq, float)
    t_commands, setpoints = np.asarray(t_commands, float), np.asarray(setpoints, float)
    by_stamp = np.argsort(t_commands, kind="stable")
    last = np.clip(np.searchsorted(t_commands[by_stamp], t_samples, side="right") - 1, 0, len(t_commands) - 1)
    result = setpoints[by_stamp][last]
    command_sample_seq = np.asarray(command_sample_seq, float)
    by_seq = np.argsort(command_sample_seq, kind="stable")
    seqs = command_sample_seq[by_seq]
    at = np.clip(np.searchsorted(seqs, named), 0, len(seqs) - 1)
    found = (named > 0) & (seqs[at] == named)
    result[found] = setpoints[by_seq][at[found]]
    return result


@dataclass
class RecordedLoadStep:
    """One load step as a live run recorded it (times [s] on the run's own clock)."""

    time: float  # [s] when the applied load changed
    load_before: float  # [N m]
    load_after: float  # [N m]
    end: float  # [s] next change of load or set-point (or the end of the record)
    peak_dip: float  # [rad/s] largest |omega - set-point| in the first `settle` s after the step
    iae: float  # [rad] integral of |omega - set-point| from the step to `end`


def recorded_load_steps(t_load, load, t_speed, omega, setpoint, *, settle: float = SETTLE,
                        tolerance: float = 1e-4) -> list[RecordedLoadStep]:
    """Pure load steps of a recorded run, found in the record itself rather than in the schedule.

    On the live graph the rig's clock and the scenario's wall clock drift apart
    (a starved sim_node dilates the rig's time), so a scheduled segment can hold
    the transient of the set-point change after it. Here a load step is where
    the applied load (e.g. /sim/truth_samples tau_load) changes by more than
    ``tolerance`` [N m] while the set-point holds; its window runs to the next
    change of either (changes closer than 50 ms are one).

    Args:
        t_load, load: applied load [N m] over time [s].
        t_speed, omega, setpoint: worm speed [rad/s] (the true one where known) and the
            set-point in force at each of its samples [rad/s].
    """
    t_load, load = np.asarray(t_load, float), np.asarray(load, float)
    t_speed, error = np.asarray(t_speed, float), np.abs(np.asarray(omega, float) - np.asarray(setpoint, float))
    if len(t_load) < 2 or len(t_speed) < 2:
        return []
    period = sample_period(t_speed)

    def events(t, x, tol):
        changes = t[:-1][np.abs(np.diff(x)) > tol]
        keep = np.concatenate(([True], np.diff(changes) > 0.05)) if changes.size else changes.astype(bool)
        return changes[keep]

    load_changes = events(t_load, load, tolerance)
    setpoint_changes = events(t_speed, np.asarray(setpoint, float), 1e-9)
    ends = np.sort(np.concatenate((load_changes, setpoint_changes, [t_speed[-1]])))
    steps = []
    for t0 in load_changes:
        if np.any(np.abs(setpoint_changes - t0) < 0.05):
            continue  # the set-point changed with it: not a pure load step
        end = float(ends[ends > t0][0])
        window = (t_speed >= t0) & (t_speed < end)
        if not window.any():
            continue
        first = window & (t_speed < t0 + settle)
        steps.append(RecordedLoadStep(
            time=float(t0), load_before=float(np.interp(t0 - 0.02, t_load, load)),
            load_after=float(np.interp(min(t0 + 0.05, end), t_load, load)), end=end,
            peak_dip=float(error[first].max()), iae=float(error[window].sum() * period)))
    return steps


def steady_spans(scenario, settle: float = SETTLE) -> list[tuple[float, float]]:
    """(start, end) [s] of each segment's steady part: from ``settle`` s after its start to its end."""
    starts = segment_starts(scenario)
    return [(float(s + settle), float(s + seg.duration)) for s, seg in zip(starts, scenario) if seg.duration > settle]


def _steady_mask(t: np.ndarray, scenario, settle: float) -> np.ndarray:
    mask = np.zeros(np.shape(t), bool)
    for start, end in steady_spans(scenario, settle):
        mask |= (t >= start) & (t < end)
    return mask


def analyse_run(scenario, t_speed, omega, setpoint, t_est, estimate, t_truth, truth, modes,
                torque_range: float, settle: float = SETTLE, flags=None) -> RunMetrics:
    """Tracking and estimation figures of one run (see module docstring).

    ``flags``: the estimates' TorqueEstimate flags (None: all trusted). The estimation error is the
    trusted estimates' (what the standard outputs carry as a load); the flagged ones in the steady parts
    (a step detector's false alarm at a constant load, say) are counted and their worst error reported
    apart, so that one flagged spike does not stand for a segment's accuracy, nor vanish.
    """
    after_first = t_speed >= scenario[0].duration
    error = omega - setpoint
    period = sample_period(t_speed)
    starts = segment_starts(scenario)
    dips = []
    for k in load_steps(scenario):
        window = (t_speed >= starts[k]) & (t_speed < starts[k] + settle)
        dips.append(np.max(np.abs(error[window])) if window.any() else np.nan)

    truth_at_est = np.interp(t_est, t_truth, truth)
    in_steady = _steady_mask(t_est, scenario, settle)
    flagged = np.zeros(np.shape(t_est), bool) if flags is None else (np.asarray(flags, int) & UNTRUSTED) != 0
    steady_flagged = in_steady & flagged
    steady = in_steady & np.isfinite(estimate) & ~flagged
    abs_err = np.abs(estimate - truth_at_est)
    flagged_err = abs_err[steady_flagged & np.isfinite(estimate)]
    seg_index = np.searchsorted(starts, t_est, side="right") - 1
    seg_means = [np.mean(abs_err[steady & (seg_index == k)]) for k in range(len(scenario))
                 if np.any(steady & (seg_index == k))]
    return RunMetrics(
        speed_rms_error=float(np.sqrt(np.mean(error[after_first] ** 2))),
        peak_dip=float(np.nanmax(dips)) if dips else float("nan"),
        iae=float(np.abs(error[after_first]).sum() * period),
        estimate_mae_pct=float(100 * np.mean(abs_err[steady]) / torque_range),
        estimate_max_pct=float(100 * np.max(seg_means) / torque_range),
        modes_seen=tuple(sorted(set(int(m) for m in modes))),
        steady_estimates=int(np.sum(in_steady)),
        steady_flagged=int(np.sum(steady_flagged)),
        flagged_max_pct=float(100 * flagged_err.max() / torque_range) if flagged_err.size else float("nan"),
    )
