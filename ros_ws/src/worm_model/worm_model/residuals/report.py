"""Report of a residual analysis: report.json, PNG plots (matplotlib Agg) and the console summary.

Units: currents [A]; "as torque" figures are K_t x current [N m] at the drive motor's
shaft; tau_d errors are load-torque errors [N m] on the gear shaft; the transmission error
(second fitted signal when the data has theta_gear) in rad at the gear shaft.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from worm_model.physics.friction import friction_coefficient, sliding_velocity
from worm_model.physics.units import FloatArray

from worm_model.residuals.analysis import Analysis
from worm_model.residuals.description.descriptors import time_in_run
from worm_model.residuals.fitting.fitting import Problem, fit
from worm_model.residuals.free import FREE_PARAMETERS, LOWER_BOUNDS, TOLERANCES, get_value, mu_parameter

UNIT = "A"


def order_spectrum(residual: FloatArray, angle: FloatArray, mask: np.ndarray, orders: FloatArray,
                   max_samples: int = 40000) -> FloatArray:
    """Angle-domain amplitude spectrum [unit of residual]: 2 |mean(r exp(-j k angle))| per order k.

    A non-uniform DFT in the angle domain: it needs no resampling, works across runs and
    both directions of rotation, and a ripple a sin(k angle + p) gives amplitude a at k.
    """
    idx = np.flatnonzero(mask)
    if len(idx) > max_samples:  # evenly thinned: the spectrum's noise floor barely moves
        idx = idx[np.linspace(0, len(idx) - 1, max_samples).astype(int)]
    r = residual[idx] - residual[idx].mean()
    th = angle[idx]
    out = np.empty(len(orders))
    for start in range(0, len(orders), 200):
        k = orders[start:start + 200]
        out[start:start + 200] = 2.0 * np.abs(np.exp(-1j * np.outer(k, th)) @ r) / len(r)
    return out


def windowed_rms(error: FloatArray, mask: np.ndarray, run: np.ndarray, window: int) -> float:
    """RMS of the means of consecutive `window`-sample stretches of `error` inside `mask` (one run each).

    Averaging over a few tens of ms removes the per-sample sensor noise and keeps the
    systematic error an estimator that filters its output would still show.
    """
    idx = np.flatnonzero(mask & np.isfinite(error))
    if len(idx) == 0:
        return math.nan
    breaks = np.flatnonzero((np.diff(idx) != 1) | (np.diff(run[idx]) != 0)) + 1
    means = [seg[: len(seg) // window * window].reshape(-1, window).mean(axis=1)
             for seg in np.split(error[idx], breaks) if len(seg) >= window]
    means = np.concatenate(means) if means else np.array([])
    return float(np.sqrt(np.mean(means**2))) if len(means) else math.nan


def effect_record(effect_fit, confidence: float) -> dict[str, Any]:
    e = effect_fit.effect
    params = {p.name: {"value": effect_fit.values[p.name], "ci_half_width": effect_fit.ci.get(p.name, math.nan),
                       "unit": p.unit, "description": p.description} for p in e.parameters}
    grid = {g.name: {"value": effect_fit.grid[g.name], "unit": g.unit,
                     "interval": list(effect_fit.grid_ci.get(g.name, (math.nan, math.nan)))}
            for g in e.grid_parameters}
    return {"name": e.name, "family": e.family, "description": e.description, "parameters": params,
            "grid_parameters": grid, "confidence": confidence,
            "simulator_entry": e.simulator_entry(effect_fit.values, effect_fit.grid)}


def build_report(problem: Problem, result: Analysis, tau_d: dict[str, float], files: dict[str, str]) -> dict[str, Any]:
    """The report.json document."""
    kt = problem.rig0.drive_motor.torque_constant
    declared, final = result.declared, result.final
    split = result.split
    rounds = []
    for k, rnd in enumerate(result.rounds):
        rounds.append({
            "round": k + 1, "accepted": rnd.accepted, "refit_rms_held_out": rnd.refit_rms_held_out,
            "candidates": [{"name": c.name, "signal": c.signal, "unit": c.unit, "grid": c.grid,
                            "rms_held_out": c.rms_held_out,
                            "improvement": c.improvement, "delta_bic": c.delta_bic, "significant": c.significant
                            and c.improvement >= problem.settings.min_improvement, "note": c.note}
                           for c in rnd.candidates],
        })
    s = problem.settings
    signals = {"current_drive": {"unit": UNIT, "rms_before": declared.rms_held_out, "rms_after": final.rms_held_out,
                                 "rms_train_before": declared.rms_train, "rms_train_after": final.rms_train}}
    if final.te is not None and declared.te is not None:
        signals["transmission_error"] = {
            "unit": "rad", "rms_before": declared.te.rms_held_out, "rms_after": final.te.rms_held_out,
            "rms_train_before": declared.te.rms_train, "rms_train_after": final.te.rms_train,
            "note": "ratio * theta_worm - theta_gear [rad at the gear shaft]; declared model: a constant per run "
                    "(encoder zeros); backlash acts here, not on the current"}
    return {
        "format": "worm_residuals_report", "version": 1,
        "data": {"source": files.get("data", ""), "samples": int(len(problem.signals)),
                 "runs": int(len(np.unique(problem.signals.run))),
                 "train_samples": int(split.train.sum()), "held_out_samples": int(split.held_out.sum())},
        "settings": {"holdout_fraction": s.holdout_fraction, "block_seconds": s.block_seconds,
                     "guard_seconds": s.guard_seconds, "min_speed": s.min_speed,
                     "min_improvement": s.min_improvement, "max_effects": s.max_effects,
                     "alpha_time_constant": s.alpha_time_constant, "confidence": s.confidence,
                     "reference_temperature": s.reference_temperature,
                     "check_outside_vocabulary": s.check_outside_vocabulary,
                     "candidates": list(s.candidates)},
        "fitted_signal": "current_drive",
        "unit": UNIT,
        "signals": signals,
        "effects_found": result.found,
        "rms_before": result.rms_before,
        "rms_corrected": declared.rms_held_out,
        "rms_after": final.rms_held_out,
        "rms_note": "held-out RMS of the drive current: before = the rig file as declared (nothing fitted); "
                    "corrected = its refitted parameters (parameter_corrections); after = with the effects found",
        "torque_unit": "N m",
        "rms_before_torque": result.rms_before * kt,
        "rms_after_torque": final.rms_held_out * kt,
        "parameter_corrections": corrections(problem, result),
        "contributions": [{"name": c.name, "signal": c.signal, "unit": c.unit, "rms_without": c.rms_without,
                           "rms_with": c.rms_with, "unique_contribution": c.delta,
                           "interval": list(c.interval), "confidence": s.confidence,
                           "note": "held-out RMS of its signal with every other effect and correction refitted, "
                                   "without it minus with it; interval: block bootstrap over held-out blocks"}
                          for c in result.contributions],
        "aliases": [{"effect": a.effect, "parameters": {p: {"declared": d, "identified": v, "ci_half_width": h}
                                                        for p, (d, v, h) in a.parameters.items()},
                     "values": a.values, "ci_half_width": a.ci} for a in result.aliases],
        "noise_floor": None if result.noise is None else {
            "rms": result.noise.rms, "unit": UNIT, "samples": result.noise.samples, "method": result.noise.method},
        "unexplained": None if result.unexplained is None else {
            "rms": result.unexplained.rms, "unit": UNIT, "ratio_to_floor": result.unexplained.ratio,
            "threshold": s.unexplained_factor,
            "correlations": [{"quantity": c.quantity, "share": c.share, "detail": c.detail}
                             for c in result.unexplained.correlations]},
        "rms_train_before": declared.rms_train,
        "rms_train_after": final.rms_train,
        "tau_d_unit": "N m",
        "tau_d_rms_before": tau_d.get("before", math.nan),
        "tau_d_rms_after": tau_d.get("after", math.nan),
        "tau_d_rms_before_20ms": tau_d.get("before_20ms", math.nan),
        "tau_d_rms_after_20ms": tau_d.get("after_20ms", math.nan),
        "tau_d_note": "tau_d inverted from each held-out sample's current by the declared (before) and the "
                      "extended (after) model; the _20ms figures average the error over 20 ms stretches first",
        "free_parameters": {
            name: {"declared": get_value(problem.rig0, name), "value": final.free_values[name],
                   "ci_half_width": final.free_ci.get(name, math.nan)} for name in final.free},
        "effects": [effect_record(e, s.confidence) for e in final.effects],
        "pruned": result.pruned,
        "outside_vocabulary": {"dropped": result.outside,
                               "note": "effects accepted by the search that do not earn their keep beside a generic "
                                       "description of the residual left above the floor: not named"},
        "rounds": rounds,
        "effective_samples": {"declared": declared.n_eff, "final": final.n_eff, "train": declared.n_train,
                              "transmission_error": None if final.te is None else final.te.n_eff,
                              "note": "BIC and confidence intervals use n_eff = n (1 - rho) / (1 + rho), rho the "
                                      "lag-1 autocorrelation of the training residual (AR(1)); intervals are "
                                      "least-squares intervals inflated by sqrt(n / n_eff)"},
        "files": files,
    }


def corrections(problem: Problem, result: Analysis) -> list[dict[str, Any]]:
    """Every fitted rig parameter: declared and identified value, interval, band, and what became of it.

    ``ratio`` is identified / declared (None around a declared 0, where the band is absolute: free.Tolerance);
    ``band`` the band's edges [SI] (None: unbounded), ``band_text`` as the console prints it.
    """
    out = []
    final = result.final
    for name in final.free:
        declared, value = get_value(problem.rig0, name), final.free_values[name]
        tol = TOLERANCES.get(name)
        alias = next((a.effect for a in result.aliases if name in a.parameters), None)
        outside = tol is not None and tol.outside(declared, value, problem.rig0)
        status = (f"beyond its tolerance: named as the effect {alias}" if alias else
                  "beyond its tolerance band, kept as a correction" if outside else "correction")
        low_bound = LOWER_BOUNDS.get(name)
        if low_bound is not None and value <= low_bound:
            status += f" (held at its physical bound {low_bound:g})"
        unit = FREE_PARAMETERS.get(name, ("", ""))[0]
        out.append({"name": name, "declared": declared, "identified": value,
                    "ci_half_width": final.free_ci.get(name, math.nan),
                    "ratio": value / declared if declared else None,
                    "band": None if tol is None else list(tol.band(declared, problem.rig0)),
                    "band_text": "" if tol is None else tol.describe(declared, problem.rig0, unit),
                    "unit": unit, "status": status})
    return out


def correction_line(row: dict[str, Any]) -> str:
    """One row of :func:`corrections` as the console prints it."""
    ratio = "" if row["ratio"] is None else f"; x{row['ratio']:.3g}"
    band = f", tolerance {row['band_text']}" if row["band_text"] else ""
    return (f"parameter {row['name']}: declared {row['declared']:.6g} -> {row['identified']:.6g} "
            f"+- {row['ci_half_width']:.2g} (95 %{ratio}{band}): {row['status']}")


def mu_line(problem: Problem, result: Analysis) -> str | None:
    """The mu correction as a friction coefficient at the data's median sliding speed and reference temperature."""
    name = mu_parameter(problem.rig0.friction.model)
    if name not in result.final.free:
        return None
    used = result.split.train | result.split.held_out
    omega = np.array([float(np.median(np.abs(problem.signals.omega[used])))])
    rig0, final = problem.rig0, result.final
    mu0 = float(friction_coefficient(rig0.friction, rig0.gearbox, omega)[0])
    mu1 = float(friction_coefficient(final.rig.friction, final.rig.gearbox, omega)[0])
    value = get_value(final.rig, name)
    half = mu1 / value * final.free_ci.get(name, math.nan) if value else math.nan
    vs = float(sliding_velocity(rig0.gearbox, omega)[0])
    return (f"correction mu: declared {mu0:.4f}, identified {mu1:.4f} +- {half:.4f} at "
            f"{problem.settings.reference_temperature:g} degC (sliding speed {vs:.2f} m/s, the data's median; "
            f"friction model {rig0.friction.model}: {name} {get_value(rig0, name):.4g} -> {value:.4g})")


# --------------------------------------------------------------------------- plots
def write_plots(out: Path, problem: Problem, result: Analysis, progress: Callable[[int], None] | None = None
                ) -> list[str]:
    """PNG plots; returns the file names written."""
    import matplotlib  # noqa: PLC0415  (Agg before pyplot)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    sig, split = problem.signals, result.split
    declared, final = result.declared, result.final
    written: list[str] = []

    def save(fig, name: str, step: int | None) -> None:
        """Write ``fig`` as ``out/name`` and close it; ``step``: the progress count reached (None: no tick)."""
        fig.tight_layout()
        fig.savefig(out / name, dpi=90)
        plt.close(fig)
        written.append(name)
        if progress and step is not None:
            progress(step)

    # 1. before and after on held-out data
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.5))
    ho = split.held_out
    t = sig.t[ho]
    axes[0].plot(t, declared.residual[ho], ".", ms=1, alpha=0.4,
                 label=f"declared model: RMS {declared.rms_held_out:.4f} A")
    axes[0].plot(t, final.residual[ho], ".", ms=1, alpha=0.4, label=f"with effects: RMS {final.rms_held_out:.4f} A")
    axes[0].set(xlabel="t [s]", ylabel="residual (measured - model) [A]",
                title="held-out residual of the drive current")
    axes[0].legend(markerscale=8, loc="upper right")
    lim = np.nanpercentile(np.abs(declared.residual[ho]), 99.5) * 1.2 if ho.any() else 1.0
    bins = np.linspace(-lim, lim, 80)
    axes[1].hist(declared.residual[ho], bins=bins, alpha=0.5, label="declared model")
    axes[1].hist(final.residual[ho], bins=bins, alpha=0.5, label="with effects: " + (", ".join(final.names) or "none"))
    axes[1].set(xlabel="held-out residual [A]", ylabel="samples")
    axes[1].legend()
    save(fig, "before_after.png", 1)

    # 1b. the transmission error, when the data has a gear encoder
    if declared.te is not None and final.te is not None:
        held = problem.te_held_out
        fig, ax = plt.subplots(figsize=(10, 4))
        ax.plot(sig.t[held], declared.te.residual[held] * 1e3, ".", ms=1, alpha=0.4,
                label=f"declared model: RMS {declared.te.rms_held_out * 1e3:.3f} mrad")
        ax.plot(sig.t[held], final.te.residual[held] * 1e3, ".", ms=1, alpha=0.4,
                label=f"with effects: RMS {final.te.rms_held_out * 1e3:.3f} mrad")
        ax.set(xlabel="t [s]", ylabel="residual [mrad at the gear]",
               title="held-out residual of the transmission error ratio theta_worm - theta_gear")
        ax.legend(markerscale=8, loc="upper right")
        save(fig, "transmission_error.png", None)  # not among the 2 + effects steps the caller counts

    # 2. angle-domain spectra (worm orders and gear orders), before and after
    rig = problem.rig0
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.5))
    worm_orders = np.arange(0.25, 40.0 + 1e-9, 0.05)
    gear_orders = np.arange(0.1, 4.0 + 1e-9, 0.02)
    for ax, angle, orders, label in ((axes[0], sig.theta_worm, worm_orders, "worm (= motor) orders [cycles/worm turn]"),
                                     (axes[1], sig.theta_gear, gear_orders, "gear orders [cycles/gear turn]")):
        for fitted, name in ((declared, "declared model"), (final, "with effects")):
            ax.plot(orders, order_spectrum(fitted.residual, angle, split.train, orders) * 1e3, lw=0.8, label=name)
        ax.set(xlabel=label, ylabel="amplitude [mA]")
        ax.legend(loc="upper right")
    axes[0].axvline(rig.gearbox.worm_starts, color="grey", ls=":", lw=0.8)
    axes[0].set_title(f"residual spectrum in the angle domain (training samples); dotted: tooth-pass order "
                      f"n = {rig.gearbox.worm_starts}", fontsize=9)
    save(fig, "spectrum.png", 2)

    # 2b. an unexplained residual: what it goes with (held-out samples)
    if result.unexplained is not None:
        written.append(unexplained_plot(out / "unexplained.png", problem, result, plt))

    # 3. per effect found: the residual it explains against its regressor
    for k, ef in enumerate(final.effects):
        others = [(e.effect, e.grid) for e in final.effects if e is not ef]
        without = fit(problem, others, final) if others else declared
        x_label, x = ef.effect.signature(final.rig, sig, ef.grid)
        on_te = ef.effect.fitted_signal == "transmission_error" and final.te is not None and without.te is not None
        if on_te:  # position effects: the transmission error's residual, in mrad
            r_without, r_final, unit = without.te.residual * 1e3, final.te.residual * 1e3, "mrad"
            use = problem.te_train | problem.te_held_out
        else:
            r_without, r_final, unit = without.residual, final.residual, "A"
            use = split.train | split.held_out
        contribution = r_without - r_final  # what adding this effect explains
        fig, ax = plt.subplots(figsize=(8, 5))
        ax.plot(x[use], r_without[use], ".", ms=1, alpha=0.25, label="residual without it")
        edges = np.unique(np.quantile(x[use], np.linspace(0, 1, 41)))
        if len(edges) < 10:  # a regressor with few distinct values (e.g. a flank): equal-width bins
            edges = np.linspace(x[use].min(), x[use].max(), 41)
        centre = 0.5 * (edges[1:] + edges[:-1])
        which = np.clip(np.digitize(x[use], edges) - 1, 0, len(centre) - 1)
        for values, style, name in ((r_without[use], "k-", "binned mean of the residual"),
                                    (contribution[use], "r--", "binned mean of the effect's fitted term")):
            means = np.array([values[which == b].mean() if np.any(which == b) else np.nan for b in range(len(centre))])
            ax.plot(centre, means, style, lw=1.5, label=name)
        ax.set(xlabel=x_label, ylabel=f"residual [{unit}]", title=f"{ef.name}: residual against its regressor")
        ax.legend(markerscale=8, loc="upper left")
        save(fig, f"effect_{ef.name}.png", 3 + k)
    return written


def unexplained_plot(path: Path, problem: Problem, result: Analysis, plt) -> str:
    """Binned means of the held-out final residual over speed, load, time and temperature, and its
    angle-domain spectra (worm and gear orders, each direction of rotation apart)."""
    sig, held, r = problem.signals, result.split.held_out, result.final.residual
    floor = result.noise.rms if result.noise is not None else math.nan
    t_run = time_in_run(sig)
    panels = [("omega_worm [rad/s]", sig.omega), ("tau_load [N m]", sig.tau_load), ("time within the run [s]", t_run)]
    if sig.temperature is not None:
        panels.append(("temperature [degC]", sig.temperature))
    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    flat = axes.ravel()
    for ax, (label, x) in zip(flat[:4], panels):
        xs, rs = x[held], r[held]
        edges = np.unique(np.quantile(xs, np.linspace(0, 1, 31)))
        which = np.clip(np.digitize(xs, edges) - 1, 0, len(edges) - 2)
        means = np.array([rs[which == b].mean() if np.any(which == b) else np.nan for b in range(len(edges) - 1)])
        ax.plot(xs, rs, ".", ms=1, alpha=0.15)
        ax.plot(0.5 * (edges[1:] + edges[:-1]), means, "k-", lw=1.5, label="binned mean")
        ax.set(xlabel=label, ylabel="held-out residual [A]")
        ax.legend(loc="upper right", fontsize=8)
    if len(panels) < 4:
        flat[3].axis("off")
    sigma = np.where(sig.omega < 0.0, -1.0, 1.0)
    for ax, angle, orders, label in ((flat[4], sig.theta_worm, np.arange(1, 61), "worm orders [per worm turn]"),
                                     (flat[5], sig.theta_gear, np.arange(1, 31), "gear orders [per gear turn]")):
        for direction, name in ((1.0, "forward"), (-1.0, "reverse")):
            mask = held & (sigma == direction)
            if mask.sum() > 100:
                ax.plot(orders, order_spectrum(r, angle, mask, orders.astype(float)) * 1e3, ".-", lw=0.8, label=name)
        ax.set(xlabel=label, ylabel="amplitude [mA]")
        ax.legend(loc="upper right", fontsize=8)
    u = result.unexplained
    fig.suptitle(f"unexplained residual {u.rms:.4f} A above the noise floor {floor:.4f} A; "
                 f"largest share: {u.correlations[0].quantity} ({100 * u.correlations[0].share:.0f} %)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path.name


def console_summary(problem: Problem, result: Analysis, tau_d: dict[str, float]) -> list[str]:
    """Human-readable lines (the last one is the machine-readable ``found:`` line)."""
    kt = problem.rig0.drive_motor.torque_constant
    d, f = result.declared, result.final
    lines = []
    lines += [correction_line(row) for row in corrections(problem, result)]
    mu = mu_line(problem, result)
    if mu:
        lines.append(mu)
    for k, rnd in enumerate(result.rounds):
        te_note = "" if not math.isfinite(rnd.baseline_te_rms_held_out) else \
            f", transmission error {rnd.baseline_te_rms_held_out * 1e3:.4f} mrad"
        lines.append(f"round {k + 1}: candidates ranked by the held-out improvement of their signal (model so far: "
                     f"{rnd.baseline_rms_held_out:.5f} A{te_note})")
        lines.append("    effect                 held-out RMS  improvement  dBIC(train)  grid")
        for c in rnd.candidates:
            grid = ", ".join(f"{k2}={v:.4g}" for k2, v in c.grid.items()
                             if k2 not in ("typical_load", "reference_temperature"))
            mark = "*" if c.name == rnd.accepted else " "
            note = f"  ({c.note})" if c.note else ""
            rms = f"{c.rms_held_out:9.5f} A   " if c.unit == "A" else f"{c.rms_held_out * 1e3:9.5f} mrad"
            lines.append(f"  {mark} {c.name:<20} {rms}  {100 * c.improvement:9.1f} %  "
                         f"{c.delta_bic:11.1f}  {grid}{note}")
        lines.append(f"    -> {'added ' + rnd.accepted if rnd.accepted else 'nothing significant left'}")
    if result.pruned:
        lines.append(f"dropped as redundant after later additions: {', '.join(result.pruned)}")
    if result.outside:
        lines.append(f"not named, as they only took a share of a residual no effect of the vocabulary describes "
                     f"(they do not earn their keep beside a generic description of it): {', '.join(result.outside)}")
    for ef in f.effects:
        parts = [f"{p.name} = {ef.values[p.name]:.4g} +- {ef.ci.get(p.name, math.nan):.2g}{_unit(p.unit)}"
                 for p in ef.effect.parameters]
        parts += [f"{g.name} = {ef.grid[g.name]:.4g}{_unit(g.unit)}" + (
            f" [{ef.grid_ci[g.name][0]:.3g}, {ef.grid_ci[g.name][1]:.3g}]" if g.name in ef.grid_ci else "")
                  for g in ef.effect.grid_parameters]
        lines.append(f"effect {ef.name}: " + "; ".join(parts))
    for a in result.aliases:
        parts = ", ".join(f"{k} = {v:.4g} +- {a.ci.get(k, math.nan):.2g}" for k, v in a.values.items() if v)
        lines.append(f"effect {a.effect} (named from {', '.join(a.parameters)} beyond the declared value's "
                     f"tolerance; its size counted from the declared value): {parts}")
    for c in result.contributions:
        scale, unit = (1e3, "mrad") if c.unit == "rad" else (1.0, c.unit)
        lines.append(f"unique contribution of {c.name}: held-out RMS {c.rms_without * scale:.5f} -> "
                     f"{c.rms_with * scale:.5f} {unit} without -> with it, {c.delta * scale:.5f} {unit} "
                     f"[{c.interval[0] * scale:.5f}, {c.interval[1] * scale:.5f}] (95 %, block bootstrap)")
    lines.append(f"held-out RMS error of the drive current: before {result.rms_before:.5f} A "
                 f"({result.rms_before * kt * 1e3:.3f} mN m; the rig file as declared), corrected "
                 f"{d.rms_held_out:.5f} A (refitted parameters), after {f.rms_held_out:.5f} A "
                 f"({f.rms_held_out * kt * 1e3:.3f} mN m)")
    if result.noise is not None:
        n = result.noise
        lines.append(f"noise floor {n.rms:.5f} A, estimated from the data: {n.method}, {n.samples} samples; "
                     f"after / floor = {f.rms_held_out / n.rms:.2f}")
    u = result.unexplained
    if u is not None:
        lines.append(f"UNEXPLAINED residual: {u.rms:.5f} A above the noise floor (held-out RMS {u.ratio:.2f} x "
                     f"the floor, more than {problem.settings.unexplained_factor:g} x); no effect of the "
                     f"vocabulary describes it. It goes with:")
        for c in u.correlations:
            lines.append(f"    {c.quantity:<18} {100 * c.share:5.1f} % of its variance  ({c.detail})")
    if d.te is not None and f.te is not None:
        lines.append(f"held-out RMS error of the transmission error (theta_gear fitted too): before "
                     f"{d.te.rms_held_out * 1e3:.4f} mrad, after {f.te.rms_held_out * 1e3:.4f} mrad")
    lines.append("held-out RMS error of tau_d estimated from the current: "
                 f"before {tau_d.get('before', math.nan):.5f} N m, "
                 f"after {tau_d.get('after', math.nan):.5f} N m per sample; averaged over 20 ms: before "
                 f"{tau_d.get('before_20ms', math.nan):.5f} N m, after {tau_d.get('after_20ms', math.nan):.5f} N m")
    lines.append(found_line(result))
    return lines


def _unit(unit: str) -> str:
    return "" if unit == "1" else f" {unit}"


def found_line(result: Analysis) -> str:
    """``found: <names|none> rms_before=<x> rms_after=<y> A[ unexplained=<z> A]``."""
    names = ",".join(result.found) or "none"
    line = f"found: {names} rms_before={result.rms_before:.6g} rms_after={result.final.rms_held_out:.6g} {UNIT}"
    if result.unexplained is not None:
        line += f" unexplained={result.unexplained.rms:.4g} {UNIT}"
    return line


def write_json(path: Path, report: dict[str, Any]) -> None:
    def clean(x: Any) -> Any:
        if isinstance(x, float):
            return x if math.isfinite(x) else None
        if isinstance(x, dict):
            return {str(k): clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        if isinstance(x, (np.floating, np.integer)):
            return clean(x.item())
        return x

    path.write_text(json.dumps(clean(report), indent=2), encoding="utf-8")

