"""report: regenerate the paper's Figures 6-11 (section 3.2) from a calibration dataset.

    ros2 run worm_model report calibration.json --out figures/ [--rig rig.yaml] [--drag none]

What each figure plots is computed in :mod:`worm_model.figures.paper_figures`; this module only
draws it (matplotlib, Agg backend, PNG) and wires the command line.
"""
from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, existing_file, output_path
from worm_model.files.writing import Output, atomic_dir, check_output
from worm_model.figures.paper_figures import DRAG_MODELS, PaperFigures, compute, read_calibration, rig_for, trends

#: what report writes into --out; --force replaces only a folder it wrote (worm_model.files.writing)
OUTPUT = Output("report", names=("fig*.png",))
SPEED_CMAP = "coolwarm"
TORQUE_CMAP = "viridis"
TAU_LABEL = r"load torque $\tau_d$ [N m] (+ opposes + worm rotation)"


def _speed_colours(fig: PaperFigures):
    vmax = float(np.max(np.abs(fig.speed_setpoints)))
    norm = Normalize(-vmax, vmax)
    return norm, plt.get_cmap(SPEED_CMAP)


def _lines_per_speed(ax, fig: PaperFigures, y: np.ndarray) -> None:
    """One line per speed setpoint against tau_d, coloured by signed speed, with a colour bar."""
    norm, cmap = _speed_colours(fig)
    for k, speed in enumerate(fig.speed_setpoints):
        idx = fig.per_speed(k)
        if idx.size:
            ax.plot(fig.tau_load[idx], y[idx], "-o", ms=2.5, lw=1.0, color=cmap(norm(speed)))
    bar = ax.figure.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax)
    bar.set_label(r"worm speed $\omega_w$ [rad/s]")
    ax.set_xlabel(TAU_LABEL)
    ax.axvline(0.0, color="0.6", lw=0.6)
    ax.grid(alpha=0.3)


def plot_normal_force(ax, fig: PaperFigures) -> None:
    _lines_per_speed(ax, fig, fig.normal_force)
    ax.set_ylabel("normal force $N$ [N] (Eq. 21)")
    ax.set_title("Fig. 6: normal force vs load torque, per speed")


def plot_friction_force(ax, fig: PaperFigures) -> None:
    _lines_per_speed(ax, fig, fig.friction_force)
    ax.set_ylabel("friction force $F_f$ [N] (Eq. 22)")
    ax.set_title("Fig. 7: friction force vs load torque, per speed")


def plot_switching_torque(ax, fig: PaperFigures) -> None:
    ok = np.isfinite(fig.switching_torque)
    ax.plot(fig.speed_setpoints[ok], 1e3 * fig.switching_torque[ok], "o-", color="C3", ms=4)
    ax.set_xlabel(r"worm speed $\omega_w$ [rad/s]")
    ax.set_ylabel(r"switching torque $\tau_{sw}$ [mN m]")
    ax.set_title("Fig. 8: switching torque vs speed")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.grid(alpha=0.3)


def _mu_axes(ax, fig: PaperFigures, y: np.ndarray, title: str) -> None:
    _lines_per_speed(ax, fig, y)
    ax.set_ylabel(r"$\mu = F_f / N$ (Eq. 23)")
    ax.set_title(title)


def plot_mu(ax, fig: PaperFigures) -> None:
    finite = fig.mu[np.isfinite(fig.mu)]
    _mu_axes(ax, fig, fig.mu, r"Fig. 9: $\mu$ vs load torque, per speed (unfiltered)")
    if finite.size and (np.max(np.abs(finite)) > 20 * np.median(np.abs(finite))):
        ax.set_yscale("symlog", linthresh=0.1)  # near switching N -> 0 and mu blows up


def plot_mu_filtered(ax, fig: PaperFigures) -> None:
    removed = int(np.sum(np.isnan(fig.mu_filtered)))
    _mu_axes(ax, fig, fig.mu_filtered,
             rf"Fig. 10: $\mu$ kept in $[0, \mu_{{max}}]$, $\mu_{{max}}$ = {fig.mu_max:.3g} (Remark 4), "
             f"{removed} of {len(fig.mu)} removed")
    if fig.mu_max < 2 * np.nanmax(np.append(fig.mu_filtered, 0.0)):
        ax.axhline(fig.mu_max, color="k", ls="--", lw=0.8)


def plot_mu_vs_speed(ax, fig: PaperFigures) -> None:
    tmax = float(np.max(np.abs(fig.torque_setpoints)))
    norm, cmap = Normalize(-tmax, tmax), plt.get_cmap(TORQUE_CMAP)
    for j, torque in enumerate(fig.torque_setpoints):
        idx = fig.per_torque(j)
        if idx.size:
            ax.plot(fig.omega_worm[idx], fig.mu_filtered[idx], "-o", ms=2.5, lw=1.0, color=cmap(norm(torque)))
    bar = ax.figure.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax)
    bar.set_label(r"load torque $\tau_d$ [N m]")
    ax.set_xlabel(r"worm speed $\omega_w$ [rad/s]")
    ax.set_ylabel(r"$\mu$ (filtered, Remark 4)")
    ax.set_title(r"Fig. 11: $\mu$ vs speed, per load torque")
    ax.axvline(0.0, color="0.6", lw=0.6)
    ax.grid(alpha=0.3)


#: file name -> drawing function, in the paper's order
FIGURES: dict[str, Callable[[plt.Axes, PaperFigures], None]] = {
    "fig06_normal_force.png": plot_normal_force,
    "fig07_friction_force.png": plot_friction_force,
    "fig08_switching_torque.png": plot_switching_torque,
    "fig09_mu.png": plot_mu,
    "fig10_mu_filtered.png": plot_mu_filtered,
    "fig11_mu_vs_speed.png": plot_mu_vs_speed,
}


def write_figures(fig: PaperFigures, out: Path, note: str = "") -> list[Path]:
    """Draw every figure of :data:`FIGURES` into the folder ``out`` (which must exist); returns the paths."""
    written = []
    for name, draw in FIGURES.items():
        figure, ax = plt.subplots(figsize=(7.0, 4.6), dpi=110)
        draw(ax, fig)
        if note:
            figure.text(0.01, 0.01, note, fontsize=7, color="0.4")
        figure.tight_layout(rect=(0, 0.03 if note else 0, 1, 1))
        path = out / name
        figure.savefig(path)
        plt.close(figure)
        written.append(path)
    return written


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
        prog="report",
        description="Regenerate the paper's Figures 6-11 (normal force, friction force, switching torque, "
                    "mu, mu filtered by Remark 4, mu vs speed) as PNG files from a calibration database.",
        epilog="Writes fig06_normal_force.png ... fig11_mu_vs_speed.png into --out and prints the trend "
               "figures behind the paper's section 3.2 narrative. Exit code 2 on bad input.")
    p.add_argument("calibration", type=existing_file,
                   help="calibration database (JSON, format worm_torque_calibration v1, as written by "
                        "'ros2 run torque_estimator calibrate')")
    p.add_argument("--out", type=output_path, required=True,
                   help="directory for the PNG files (created; an existing one only with --force)")
    p.add_argument("--force", action="store_true", help="replace an existing --out directory")
    p.add_argument("--rig", type=existing_file, default=None,
                   help="rig parameter YAML (geometry, K_t, drags); default: the rig stored in the "
                        "calibration file (required if it holds none)")
    p.add_argument("--drag", choices=DRAG_MODELS, default="none",
                   help="input torque: 'none' = K_t i as in the paper (drags show up in F_f); "
                        "'declared' = motor and load-motor drags of the rig file taken out first")
    return p


def main(argv: list[str] | None = None) -> int:
    return run_tool("report", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    points = read_calibration(args.calibration)
    rig = rig_for(points, args.rig)
    inputs = [args.calibration, args.rig]
    check_output(args.out, args.force, folder=True, inputs=inputs, output=OUTPUT)
    fig = compute(points, rig, args.drag)
    with atomic_dir(args.out, args.force, inputs=inputs, output=OUTPUT) as folder:
        written = write_figures(fig, folder, note=f"{args.calibration.name}, {len(points)} points, "
                                                  f"rig: {rig.name}, drag: {args.drag}")
    paths = [args.out / p.name for p in written]
    print(f"report: {len(points)} calibration points ({len(fig.speed_setpoints)} speeds x "
          f"{len(fig.torque_setpoints)} torques), drag model '{args.drag}'")
    for name, value in trends(fig).items():
        print(f"  {name}: {value:.4g}" if math.isfinite(value) else f"  {name}: nan")
    for path in paths:
        print(f"  wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
