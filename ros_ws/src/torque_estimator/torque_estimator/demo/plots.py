"""PNG figures of the demo's live runs (matplotlib, no display needed).

Each figure is drawn from plain arrays (:class:`EstimateTrace`, :class:`SpeedTrace`, the
:class:`~torque_estimator.demo.run_analysis.RecordedLoadStep` list of each run) by a ``draw_*``
function that returns the matplotlib Figure; the function without the prefix writes it as a PNG.
Times are seconds from the scenario's start; torques [N m], positive opposing positive worm rotation;
speeds [rad/s].

The axes are scaled to what a figure is there to show, not to its largest sample: the estimate's to
the applied loads, the speed error's to the load steps' dips. Estimates whose TorqueEstimate flags are
set (``estimation.base.EstimateFlags``: out of calibration, ambiguous, invalid input, transient) are
not drawn as estimates: a grey band marks where they fall and a marker each shows its value, at the
axis' edge with the value printed when it is off the scale (the estimate's spike at the speed reversal).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from torque_estimator.demo.run_analysis import RecordedLoadStep  # noqa: E402
from torque_estimator.estimation.base import EstimateFlags  # noqa: E402
from torque_estimator.evaluation.plots import save_figure  # noqa: E402

#: the label of the estimate's line (tests find it by this label)
ESTIMATE_LABEL = "estimate"
#: flagged estimates, most telling bit first: (bit, legend text, marker colour)
FLAG_KINDS = ((EstimateFlags.INVALID_INPUT, "invalid input", "black"),
              (EstimateFlags.OUT_OF_CALIBRATION, "out of calibration", "tab:red"),
              (EstimateFlags.TRANSIENT, "transient", "tab:purple"),
              (EstimateFlags.AMBIGUOUS, "ambiguous", "tab:brown"))
RUN_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red")


@dataclass(frozen=True)
class EstimateTrace:
    """One run's live estimate beside the simulator's truth."""

    t_est: np.ndarray  # [s] stamp of each estimate
    estimate: np.ndarray  # [N m] TorqueEstimate.torque
    flags: np.ndarray  # TorqueEstimate.flags (EstimateFlags bits) of each estimate
    t_truth: np.ndarray  # [s]
    truth: np.ndarray  # [N m] the load torque the simulator applied


@dataclass(frozen=True)
class SpeedTrace:
    """One run's worm speed against its set-point."""

    t: np.ndarray  # [s]
    omega: np.ndarray  # [rad/s] worm speed (the simulator's true one: tacho noise is not a dip)
    setpoint: np.ndarray  # [rad/s] set-point in force at each sample


def load_limits(loads, margin: float = 0.5) -> tuple[float, float]:
    """Axis limits [N m] that hold the applied loads with ``margin`` x their span to spare each side."""
    loads = np.asarray(loads, float)
    loads = loads[np.isfinite(loads)]
    lo, hi = (float(loads.min()), float(loads.max())) if loads.size else (0.0, 0.0)
    span = max(hi - lo, abs(lo), abs(hi), 1e-3)  # a constant load still gets an axis around it
    return lo - margin * span, hi + margin * span


def flagged_spans(t, flagged) -> list[tuple[float, float]]:
    """(start, end) [s] of each run of consecutive flagged samples, half a sample period wider each side."""
    t, flagged = np.asarray(t, float), np.asarray(flagged, bool)
    if not flagged.any():
        return []
    half = 0.5 * float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    edges = np.diff(np.concatenate(([0], flagged.astype(int), [0])))
    return [(float(t[a]) - half, float(t[b - 1]) + half)
            for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))]


def group_steps(step_times: Mapping[str, Sequence[float]], tolerance: float = 0.5) -> list[dict[str, int]]:
    """The same load step in every run: groups of {run name: index into its steps}, in time order.

    Steps of different runs closer than ``tolerance`` [s] are one (each run keeps its own clock, so
    the same scheduled step lands a few ms apart)."""
    events = sorted((t, name, k) for name, times in step_times.items() for k, t in enumerate(times))
    groups: list[dict[str, int]] = []
    first_time = None
    for t, name, k in events:
        if not groups or t - first_time > tolerance or name in groups[-1]:
            groups.append({})
            first_time = t
        groups[-1][name] = k
    return groups


def _mark_flagged(ax, t, value, flags, limits) -> None:
    """Shade the spans of flagged estimates and mark each one's value: a circle on the scale, a triangle
    at the axis' edge off it (the largest of each off-scale run printed)."""
    t, value, flags = np.asarray(t, float), np.asarray(value, float), np.asarray(flags, int)
    for k, (start, end) in enumerate(flagged_spans(t, flags != 0)):
        ax.axvspan(start, end, color="tab:purple", alpha=0.25, lw=0,
                   label="flagged estimates" if k == 0 else None)
    lo, hi = limits
    edge = 0.04 * (hi - lo)
    above, below = value > hi, value < lo
    taken = ~np.isfinite(value)  # an invalid input's NaN has only its band
    for bit, text, colour in FLAG_KINDS:
        kind = ((flags & int(bit)) != 0) & ~taken
        taken |= kind
        on_scale = kind & ~above & ~below
        ax.plot(t[on_scale], value[on_scale], "o", ms=3.5, mfc="none", color=colour,
                label=f"flagged: {text}" if kind.any() else None)
        ax.plot(t[kind & above], np.full((kind & above).sum(), hi - edge), "^", ms=6, color=colour)
        ax.plot(t[kind & below], np.full((kind & below).sum(), lo + edge), "v", ms=6, color=colour)
    for off, y, dy in ((above, hi - edge, -4), (below, lo + edge, 0)):
        for start, end in flagged_spans(t, off & (flags != 0)):
            inside = off & (t >= start) & (t <= end)
            extreme = value[inside][np.argmax(np.abs(value[inside]))]
            ax.annotate(f"{extreme:+.1f} N·m (off scale)", (end, y), xytext=(4, dy), textcoords="offset points",
                        fontsize=8, color="0.2")


def draw_estimate_vs_truth(runs: Mapping[str, EstimateTrace], torque_range: float,
                           judged: Sequence[tuple[float, float]] = (), error_limit: float = 5.0) -> Figure:
    """Estimated and true load torque of each run, and the estimate's error.

    Per run two panels: the torque on an axis scaled to the applied loads (flagged estimates marked,
    not drawn as estimates), and estimate - truth in % of the calibrated range ``torque_range`` [N m]
    (the unit of the demo's table). judged: the (start, end) [s] spans the table's live error is taken
    over; the rest (the settling after each change) is shaded on the error panels. error_limit: the error
    axis' half-height [% of range] (the table's means are well under 1 %, the held-out points' up to ~2 %).
    """
    fig, axes = plt.subplots(2 * len(runs), 1, figsize=(10, 3.9 * len(runs)), sharex=True, squeeze=False,
                             gridspec_kw={"height_ratios": [2.2, 1] * len(runs)})
    limits = load_limits(np.concatenate([r.truth for r in runs.values()]))
    t_end = max(float(np.max(r.t_truth)) for r in runs.values())
    for k, (name, r) in enumerate(runs.items()):
        top, bottom = axes[2 * k, 0], axes[2 * k + 1, 0]
        t, value, flags = (np.asarray(a) for a in (r.t_est, r.estimate, r.flags))
        clean = np.where(flags == 0, value, np.nan)  # NaN breaks the line: a gap where the flags are
        rate = 1.0 / float(np.median(np.diff(t)))
        top.plot(r.t_truth, r.truth, color="tab:orange", lw=2.2, label="true τ_d (simulator)")
        top.plot(t, clean, color="tab:blue", lw=0.8, label=f"{ESTIMATE_LABEL} (live, {rate:.0f} Hz)")
        _mark_flagged(top, t, value, flags, limits)
        top.set_ylim(*limits)
        top.set_ylabel("τ_d [N·m]")
        top.set_title(name, loc="left", fontsize=11, fontweight="bold")
        top.grid(alpha=0.3)

        error = 100 * (clean - np.interp(t, r.t_truth, r.truth)) / torque_range
        bottom.plot(t, error, color="tab:blue", lw=0.6)
        bottom.axhline(0.0, color="black", lw=0.6)
        edges = [0.0] + [x for span in sorted(judged) for x in span] + [t_end]
        gaps = [(start, end) for start, end in zip(edges[::2], edges[1::2]) if judged and end > start]
        for j, (start, end) in enumerate(gaps):
            bottom.axvspan(start, end, color="0.88", lw=0,
                           label="settling: not in the table's live error" if j == 0 else None)
        bottom.set_ylim(-error_limit, error_limit)
        bottom.set_ylabel("estimate − truth\n[% of range]")
        bottom.grid(alpha=0.3)
    # one legend for every panel, above the first (the panels' own corners hold data and off-scale notes)
    entries = {}
    for ax in axes[:, 0]:
        for handle, text in zip(*ax.get_legend_handles_labels()):
            entries.setdefault(text, handle)
    axes[0, 0].legend(entries.values(), entries.keys(), loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=4,
                      fontsize=7, frameon=False)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 0].set_xlim(0.0, t_end)
    fig.suptitle("Live load-torque estimate against the simulator's truth")
    return fig


def estimate_vs_truth(path: Path, runs: Mapping[str, EstimateTrace], torque_range: float,
                      judged: Sequence[tuple[float, float]] = ()) -> Path:
    """:func:`draw_estimate_vs_truth` written as a PNG at ``path``."""
    return save_figure(draw_estimate_vs_truth(runs, torque_range, judged), path)


def torque_text(tau: float) -> str:
    """A load torque for a label: signed, as many decimals as it needs up to three (+0.2, -0.004, 0)."""
    return "0" if abs(tau) < 5e-4 else f"{tau:+.3f}".rstrip("0").rstrip(".")


def speed_text(omega: float) -> str:
    """A speed [rad/s] for a label: signed, whole (+150, -150, 0)."""
    return "0" if abs(omega) < 0.5 else f"{omega:+.0f}"


def dip_limit(steps: Mapping[str, Sequence[RecordedLoadStep]], margin: float = 1.3) -> float:
    """Half-height [rad/s] of a speed-error axis that holds every load step's dip with ``margin`` to spare."""
    dips = [s.peak_dip for run in steps.values() for s in run if np.isfinite(s.peak_dip)]
    return margin * max(dips, default=1.0)


def setpoint_changes(t, setpoint) -> list[tuple[float, float, float]]:
    """(time [s], from, to [rad/s]) of each change of the set-point."""
    t, setpoint = np.asarray(t, float), np.asarray(setpoint, float)
    at = np.flatnonzero(np.diff(setpoint) != 0) + 1
    return [(float(t[k]), float(setpoint[k - 1]), float(setpoint[k])) for k in at]


def draw_tracking(runs: Mapping[str, SpeedTrace], steps: Mapping[str, Sequence[RecordedLoadStep]]) -> Figure:
    """The whole run: speed and set-point at full scale above, the speed error on the load steps' scale below.

    steps: each run's recorded load steps (run_analysis.recorded_load_steps), marked on the error panel; the
    set-point changes (start-up, reversal) run off its scale and are marked as such.
    """
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True, gridspec_kw={"height_ratios": [1, 1.8]})
    limit = dip_limit(steps)
    first = next(iter(runs.values()))
    for colour, (name, r) in zip(RUN_COLOURS, runs.items()):
        top.plot(r.t, r.omega, color=colour, lw=0.8, label=name)
        bottom.plot(r.t, np.asarray(r.omega) - np.asarray(r.setpoint), color=colour, lw=0.8)
    top.plot(first.t, first.setpoint, "k--", lw=1, label="set-point")
    top.set_ylabel("worm speed\n[rad/s]")
    top.set_title("Speed tracking through the scenario (true speed, every sample)")
    top.grid(alpha=0.3)
    label = {"bbox": {"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 1}}
    for k, step in enumerate(next(iter(steps.values()), [])):
        bottom.axvline(step.time, color="0.4", lw=0.8, ls=":", label="load step" if k == 0 else None)
        bottom.annotate(f"{torque_text(step.load_before)} → {torque_text(step.load_after)} N·m", (step.time, limit),
                        xytext=(3, -11), textcoords="offset points", fontsize=7, color="0.2", **label)
    for k, (t, before, after) in enumerate(setpoint_changes(first.t, first.setpoint)):
        bottom.axvline(t, color="tab:red", lw=0.8, ls="--", label="set-point change (off scale)" if k == 0 else None)
        bottom.annotate(f"set-point {speed_text(before)} → {speed_text(after)} rad/s", (t, -limit), xytext=(3, 4),
                        textcoords="offset points", fontsize=7, color="tab:red", **label)
    bottom.axhline(0.0, color="black", lw=0.6)
    bottom.set_ylim(-limit, limit)
    bottom.set_ylabel("ω − set-point\n[rad/s]")
    bottom.set_xlabel("time [s]")
    bottom.grid(alpha=0.3)
    handles, texts = (a + b for a, b in zip(top.get_legend_handles_labels(), bottom.get_legend_handles_labels()))
    # the top panel's lower left is empty (the speed is +150 rad/s there); the error panel's corners are not
    top.legend(handles, texts, loc="lower left", fontsize=7, ncol=2)
    return fig


def tracking(path: Path, runs: Mapping[str, SpeedTrace], steps: Mapping[str, Sequence[RecordedLoadStep]]) -> Path:
    """:func:`draw_tracking` written as a PNG at ``path``."""
    return save_figure(draw_tracking(runs, steps), path)


def draw_load_steps(runs: Mapping[str, SpeedTrace], steps: Mapping[str, Sequence[RecordedLoadStep]],
                    before: float = 0.05, after: float = 0.6) -> Figure:
    """A panel per load step: the speed error from ``before`` [s] before it to ``after`` [s] after it, runs overlaid.

    Each run is drawn on its own clock, from its own recorded step (run_analysis.recorded_load_steps); a
    dot marks its peak dip, and its legend gives the dip and the IAE, the step's share of the demo's table.
    """
    groups = group_steps({name: [s.time for s in run] for name, run in steps.items()})
    cols = 2 if len(groups) > 1 else 1
    rows = max(1, -(-len(groups) // cols))
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.4 * rows), sharey=True, squeeze=False)
    limit = dip_limit(steps)
    for ax, group in zip(axes.flat, groups):
        for colour, (name, r) in zip(RUN_COLOURS, runs.items()):
            if name not in group:
                continue
            step = steps[name][group[name]]
            t = np.asarray(r.t) - step.time
            window = (t >= -before) & (t <= min(after, step.end - step.time))
            error = (np.asarray(r.omega) - np.asarray(r.setpoint))[window]
            ms = 1e3 * t[window]
            ax.plot(ms, error, color=colour, lw=1.2,
                    label=f"{name}: dip {step.peak_dip:.2f} rad/s, IAE {step.iae:.2f} rad")
            peak = np.argmax(np.abs(error))
            ax.plot(ms[peak], error[peak], "o", color=colour, ms=5)
        name, index = next(iter(group.items()))
        step = steps[name][index]
        speed = float(np.interp(step.time, runs[name].t, runs[name].setpoint))
        ax.set_title(f"load {torque_text(step.load_before)} → {torque_text(step.load_after)} N·m "
                     f"at {speed:+.0f} rad/s", fontsize=10)
        ax.axhline(0.0, color="black", lw=0.6)
        ax.axvline(0.0, color="0.4", lw=0.8, ls=":")
        ax.set_ylim(-limit, limit)
        ax.set_xlim(-1e3 * before, 1e3 * after)
        ax.set_xlabel("time from the load step [ms]")
        ax.set_ylabel("ω − set-point [rad/s]")
        ax.legend(loc="lower right", fontsize=7)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(groups):]:
        ax.set_visible(False)
    fig.suptitle("Speed error at each load step, feedforward off and on (true speed, every sample)")
    return fig


def load_steps(path: Path, runs: Mapping[str, SpeedTrace], steps: Mapping[str, Sequence[RecordedLoadStep]]) -> Path:
    """:func:`draw_load_steps` written as a PNG at ``path``."""
    return save_figure(draw_load_steps(runs, steps), path)
