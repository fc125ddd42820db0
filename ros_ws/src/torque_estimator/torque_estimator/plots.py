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


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
