"""PNG figures of the demo's live runs (matplotlib, no display needed)."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from torque_estimator.evaluation.plots import save_figure  # noqa: E402


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
    return save_figure(fig, path)


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
    return save_figure(fig, path)
