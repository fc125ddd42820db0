"""The trend over a gearbox's life with its alarm bands, and the live monitor's window (matplotlib, no display).

Top: each check's mu scale against the baseline at the reference temperature (Delta, with its 95 %
interval), the trend's running mean, and the bands: WARN from ``limits.check_warn``, ERROR from
``limits.check_error`` (the trend's own WARN limit dashed). Middle: the drive- and gear-side drags
against the baseline. Bottom: the oil temperature each check ran at (measured or estimated, with its
interval): what the compensation took out. Checks are placed by hours run where every check has
them, else by their order.
"""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from worm_model.health.assess import Z95, Assessment, Baseline, mu_change  # noqa: E402
from worm_model.health.record import CheckRecord  # noqa: E402
from worm_model.health.settings import HealthSettings  # noqa: E402
from worm_model.physics.parameters import Rig  # noqa: E402

COLOURS = {"OK": "tab:green", "WARN": "tab:orange", "ERROR": "tab:red"}


def trend_figure(path: Path, records: list[CheckRecord], assessments: list[Assessment | None],
                 settings: HealthSettings, rig: Rig, baseline: Baseline | None = None,
                 title: str = "Gearbox health: the trend of its checks") -> Path:
    """Write the trend PNG (module docstring) for records assessed in order (assess.assess_trend); the baseline
    checks (no assessment) are drawn grey against ``baseline`` (the trend's, assess.baseline_of) if given."""
    limits = settings.limits
    hours = np.array([r.hours for r in records])
    by_hours = len(records) > 0 and bool(np.all(np.isfinite(hours)))
    x = hours if by_hours else np.arange(1, len(records) + 1, dtype=float)
    fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(9, 8.5), sharex=True,
                                              gridspec_kw={"height_ratios": [3, 1.6, 1.4]})
    pad = 0.04 * (x.max() - x.min()) + (0.0 if by_hours else 0.5) if len(x) else 1.0
    lo, hi = (x.min() - pad, x.max() + pad) if len(x) else (0, 1)
    top.axhspan(100 * limits.check_warn, 100 * limits.check_error, color="tab:orange", alpha=0.12,
                label=f"WARN (one check, > {limits.check_warn:.0%})")
    top.axhspan(100 * limits.check_error, max(100 * limits.check_error * 1.6, 30), color="tab:red", alpha=0.12,
                label=f"ERROR (> {limits.check_error:.0%})")
    top.axhline(100 * limits.trend_warn, color="tab:orange", ls="--", lw=1,
                label=f"WARN (mean of {limits.trend_window} checks, > {limits.trend_warn:.0%})")
    top.axhline(0.0, color="black", lw=0.6)
    base = [i for i, a in enumerate(assessments) if a is None]
    if base:
        half = 0.5 if not by_hours else 0.5 * pad
        top.axvspan(x[base[0]] - half, x[base[-1]] + half, color="grey", alpha=0.1, label="baseline checks")
        if baseline is not None:
            changes = [mu_change(records[i], baseline, rig, settings) for i in base]
            top.errorbar([x[i] for i in base], [100 * c[0] for c in changes],
                         yerr=[100 * Z95 * math.sqrt(c[1]) for c in changes], fmt="o", ms=4, color="grey",
                         ecolor="lightgrey", elinewidth=1, capsize=2)
    done = [(i, a) for i, a in enumerate(assessments) if a is not None]
    if done:
        xi = np.array([x[i] for i, _ in done])
        d = np.array([100 * a.mu_change.value for _, a in done])
        e = np.array([100 * Z95 * a.mu_change.sigma for _, a in done])
        top.errorbar(xi, d, yerr=e, fmt="none", ecolor="grey", elinewidth=1, capsize=2)
        top.scatter(xi, d, c=[COLOURS[a.level] for _, a in done], zorder=3, s=28, label="check (95 % interval)")
        trend = [(xx, 100 * a.trend_change.value) for xx, (_, a) in zip(xi, done) if a.trend_change is not None]
        if trend:
            top.plot(*zip(*trend), color="tab:blue", lw=1.5, label="trend (running mean)")
        drive = [(x[i], _change(a, "drive_drag")) for i, a in done]
        gear = [(x[i], _change(a, "gear_drag")) for i, a in done]
        for series, label, colour in ((drive, "drive-side drag", "tab:purple"), (gear, "gear-side drag", "tab:brown")):
            pts = [(xx, 100 * c) for xx, c in series if math.isfinite(c)]
            if pts:
                middle.plot(*zip(*pts), "o-", ms=3, lw=1, color=colour, label=label)
    middle.axhspan(100 * limits.drag_warn, 100 * limits.drag_error, color="tab:orange", alpha=0.12)
    middle.axhline(0.0, color="black", lw=0.6)
    middle.set_ylabel("drag at\n%g rad/s [%% of baseline]" % limits.drag_speed)
    middle.legend(fontsize=7, loc="upper left")
    temps = np.array([r.temperature.value for r in records])
    t_err = np.array([Z95 * r.temperature.sigma for r in records])
    sources = {r.temperature.source for r in records}
    bottom.errorbar(x, temps, yerr=t_err, fmt="o", ms=3, color="tab:cyan", ecolor="lightgrey",
                    label=f"oil ({', '.join(sorted(sources))})")
    bottom.set_ylabel("oil [degC]")
    bottom.legend(fontsize=7, loc="upper left")
    bottom.set_xlabel("hours run" if by_hours else "check")
    top.set_ylabel("mu scale vs baseline [%]\n(at the reference temperature)")
    top.set_xlim(lo, hi)
    top.set_ylim(min(-10.0, *(100 * a.mu_change.value - 5 for _, a in done)) if done else -10,
                 max(100 * limits.check_error * 1.4, *(100 * a.mu_change.value + 5 for _, a in done)) if done else 30)
    top.legend(fontsize=7, loc="upper left", ncol=2)
    top.set_title(title)
    for ax in (top, middle, bottom):
        ax.grid(alpha=0.3)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _change(assessment: Assessment, quantity: str) -> float:
    return next((f.change for f in assessment.findings if f.quantity == quantity), math.nan)




def live_figure(path: Path, panels: list[tuple[str, dict]], limits, title: str = "The live monitor") -> Path:
    """The live monitor's window over rig time, one column per scenario: mu's reading with its 95 % interval
    (the reading drawn where that interval is narrower than the WARN limit: at light loads the window
    cannot judge mu) and the WARN / ERROR limits (top), the level (middle), the oil temperature it used and
    the true one (bottom).

    Args:
        panels: (title, {mode: trace}) per column; a trace has time, level, mu_change, mu_sigma, temperature,
            true_temperature arrays (torque_estimator.health.study.LiveTrace); modes "measured" and "estimated".
        limits: settings.Limits (live_warn, live_error).
    """
    fig, axes = plt.subplots(3, len(panels), figsize=(6.2 * len(panels), 8), sharex="col", squeeze=False,
                             gridspec_kw={"height_ratios": [3, 0.8, 1.6]})
    colours = {"measured": "tab:blue", "estimated": "tab:purple"}
    for col, (name, traces) in enumerate(panels):
        top, mid, bottom = axes[:, col]
        top.axhspan(100 * limits.live_warn, 100 * limits.live_error, color="tab:orange", alpha=0.12, label="WARN")
        top.axhspan(100 * limits.live_error, 100 * max(limits.live_error * 1.5, 0.6), color="tab:red", alpha=0.12,
                    label="ERROR")
        top.axhline(0.0, color="black", lw=0.6)
        for j, (mode, tr) in enumerate(traces.items()):
            c = colours.get(mode, f"C{j}")
            t = np.asarray(tr.time)
            m, s = 100 * np.asarray(tr.mu_change), 100 * Z95 * np.asarray(tr.mu_sigma)
            step = max(1, len(t) // 4000)
            # drawn where the window can judge (its 95 % interval narrower than the WARN limit); the band everywhere
            judged = np.where(s < 100 * limits.live_warn, m, np.nan)
            top.fill_between(t[::step], (m - s)[::step], (m + s)[::step], color=c, alpha=0.12, lw=0)
            top.plot(t[::step], judged[::step], color=c, lw=0.8, label=f"mu reading, oil {mode}")
            level = np.array([ORDER_LEVEL[x] for x in tr.level])
            mid.step(t[::step], level[::step] + 0.06 * j, where="post", color=c, lw=1.2, label=mode)
            bottom.plot(t[::step], np.asarray(tr.temperature)[::step], color=c, lw=1, label=f"oil used ({mode})")
            if j == 0:
                bottom.plot(t[::step], np.asarray(tr.true_temperature)[::step], color="black", lw=0.8, ls="--",
                            label="oil, true")
        top.set_ylim(-40, 100 * max(limits.live_error * 1.5, 0.6))
        top.set_ylabel("friction as mu vs reference [%]")
        top.set_title(name)
        top.legend(fontsize=7, loc="upper left")
        mid.set_yticks([0, 1, 2], ["OK", "WARN", "ERROR"])
        mid.set_ylim(-0.3, 2.4)
        mid.legend(fontsize=7, loc="upper left")
        bottom.set_ylabel("oil [degC]")
        bottom.set_xlabel("rig time [s]")
        bottom.legend(fontsize=7, loc="lower right")
        for ax in (top, mid, bottom):
            ax.grid(alpha=0.3)
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


ORDER_LEVEL = {"OK": 0, "WARN": 1, "ERROR": 2}


__all__ = ["live_figure", "trend_figure"]
