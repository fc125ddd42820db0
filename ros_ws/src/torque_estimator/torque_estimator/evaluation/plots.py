"""PNG figures of the evaluation (matplotlib, no display needed)."""
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
    return save_figure(fig, path)


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
    return save_figure(fig, path)


def save_figure(fig, path: Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` (its folder made if missing), close it, return ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
