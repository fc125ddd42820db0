"""PNG figures of the demo and the evaluation (matplotlib, no display needed)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def held_out_deviation(path: Path, tau_true, tau_est, torque_range: float) -> Path:
    """Like the paper's Fig. 13: true and estimated load torque of each held-out test."""
    idx = np.arange(1, len(tau_true) + 1)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    top.plot(idx, tau_true, "o", label="true τ_d")
    top.plot(idx, tau_est, "x", label="k-NN estimate")
    top.set_ylabel("load torque [N·m]")
    top.legend()
    bottom.bar(idx, 100 * (np.asarray(tau_est) - tau_true) / torque_range)
    bottom.set_ylabel("error [% of range]")
    bottom.set_xlabel("held-out test")
    bottom.set_xticks(idx)
    bottom.axhline(0.0, color="black", lw=0.6)
    fig.suptitle("Held-out operating points (not in the calibration grid)")
    return _save(fig, path)


def estimate_vs_truth(path: Path, runs: dict) -> Path:
    """Estimated and true load torque over time for each run."""
    fig, axes = plt.subplots(len(runs), 1, figsize=(10, 3.2 * len(runs)), sharex=True, squeeze=False)
    for ax, (name, r) in zip(axes[:, 0], runs.items()):
        ax.plot(r["t_est"], r["estimate"], lw=0.6, label="estimate (live, 1 kHz)")
        ax.plot(r["t_truth"], r["truth"], lw=1.5, label="true τ_d (simulator)")
        ax.set_ylabel("τ_d [N·m]")
        ax.set_title(name)
        ax.legend(loc="upper right")
    axes[-1, 0].set_xlabel("time [s]")
    return _save(fig, path)


def tracking(path: Path, runs: dict) -> Path:
    """Worm speed against its set-point, feedforward off and on."""
    fig, ax = plt.subplots(figsize=(10, 4))
    for name, r in runs.items():
        ax.plot(r["t_speed"], r["omega"], lw=0.7, label=f"ω, {name}")
    first = next(iter(runs.values()))
    ax.plot(first["t_speed"], first["setpoint"], "k--", lw=1, label="set-point")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("worm speed [rad/s]")
    ax.legend(loc="lower left")
    ax.set_title("Speed tracking through load steps")
    return _save(fig, path)


def sweeps(path: Path, results, reference: dict | None = None) -> Path:
    """Held-out error against each swept quantity (evaluation.SweepResult), one panel each.

    Solid lines: mean error; dashed: largest error; both in % of the calibrated torque range.
    reference: swept name -> the value the main evaluation used (marked by a vertical line).
    """
    fig, axes = plt.subplots(1, len(results), figsize=(4.6 * len(results), 4), squeeze=False)
    for ax, result in zip(axes[0], results):
        for i, (label, mae) in enumerate(result.mae_pct.items()):
            color = f"C{i}"
            ax.plot(result.values, mae, "o-", color=color, label=f"{label}: mean")
            ax.plot(result.values, result.max_pct[label], "s--", color=color, alpha=0.7, label=f"{label}: max")
        if reference and result.name in reference:
            ax.axvline(reference[result.name], color="grey", lw=0.8, ls=":")
        if result.name == "calibration points":
            ax.set_xscale("log")
        ax.set_xlabel(result.name)
        ax.set_ylabel("held-out error [% of torque range]")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("k-NN held-out error against k, grid density and sensor noise")
    return _save(fig, path)


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
