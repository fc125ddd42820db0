"""Fit the rig's uncertain parameters and the effects the model lacks to an identification record.

The fit is the residual analysis of worm_model.residuals (its model, split, selection and
file format); what differs is its purpose.  ``residuals`` *names* effects, so it is careful
not to name one too many; ``identify`` builds the model an estimator inverts, so it keeps
what makes the model's static map right:

Which parameters (:func:`default_refit`)
    What varies from gearbox to gearbox and motor to motor is unknown on *this* rig whatever the rig
    file says about where its number came from: the standard set of worm_model.residuals.free (mu,
    i.e. the friction model's mu parameter: ``friction.scale`` under the AGMA curve,
    ``friction.mu_constant`` under the constant model; K_t, within its tolerance band; the drive
    motor's Coulomb and viscous drags, the load motors' Coulomb drag, the rotor inertia) is refitted
    whether a leaf carries a ``source:`` (a catalogue or datasheet value, copied as users copy it)
    or an ``assumption:``, plus the rig file's ``free:`` list.  The geometry (lead and pressure
    angles, radii) stays as declared: the lead and pressure angles trade off against mu, the radii
    against K_t, with nothing in the drive current to tell them apart (free.py's docstring argues
    the set).  ``--free`` replaces the whole list.  The corrections are reported as ``residuals``
    reports them (declared -> identified +- interval, the tolerance band, what became of it), and
    written into the extended rig file with the declared value and its provenance kept beside them.
Which effects (:data:`IDENTIFY_SETTINGS`)
    Every effect ``residuals`` accepts, with four settings changed: an effect must lower the
    held-out RMS of the current by 0.1 % (residuals: 2 %), it may raise the transmission
    error's by up to 5 % (residuals: as much as the first; no estimator reads the transmission
    error, and a Stribeck law moves it by ~3 % through mu), no effect is refused because the
    current is already near its noise floor (residuals: within 1.1 x), and none is dropped for
    taking only a share of a residual outside the vocabulary (residuals' step 5: that share is
    still a share of the static map the estimator inverts).  An estimator
    averages the current over hundreds of samples: a systematic 0.01 A, half the per-sample
    noise, is ~5 % of the load range on the coast flank, where the current moves little with
    the load; a Stribeck rise, a load-dependent mu or the PWM ripple's sampled bias each buy
    0.1-0.5 % of the RMS and 0.5-2 % of the range at the estimate.  The BIC test and the
    consistency over the held-out blocks (the block bootstrap) still guard against fitting noise.
Which samples (:data:`QUASI_STATIC_ACCELERATION`)
    Those an estimator reads as steady: |alpha| <= 200 rad/s^2, LiveEstimator's default
    TRANSIENT threshold.  Above it the residual is the dynamics a quasi-static map leaves out
    (the current sensor's filter, the inductance, backlash impacts at reversals: 0.08 A RMS at
    200-1000 rad/s^2 and 0.35 A above, against the 0.03 A noise of steady samples, with the
    true model and every true effect): 2 % of the samples made half the residual's variance and
    hid every effect smaller than it from the held-out blocks.
Figures (simulated rig with every default effect on, the rig file off by mu x1.3, K_t x1.05, drags
    x2, 85 s record, 17 held-out points, % of the load range; evaluation.identified): 0.5 % / no
    guard took the identified model to 2.97 / 6.96 % (mean / max); these settings to 0.71 / 1.52,
    0.58 / 1.91 and 0.92 / 2.15 % (seeds 1-3).
Ranges
    The speed and load range the record covered (99.9 percentile of |omega_worm|, 0.5 / 99.5
    percentiles of tau_load) go into the written file's ``identification:`` section: the estimators take
    their table and OUT_OF_CALIBRATION limits from there instead of a calibration database.
No ROS.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from worm_model.physics.parameters import Rig, default_rig_path, load_rig
from worm_model.residuals import analysis as an
from worm_model.residuals.extended import ExtendedModel, write_parameter_file
from worm_model.residuals.free import STANDARD_REFIT, check_free, get_value, read_free, resolve_parameters
from worm_model.residuals.report import correction_line, corrections, mu_line
from worm_model.residuals.model import prepare_signals
from worm_model.rig_data.schema import MeasuredData

#: the residual analysis' settings for identification (module docstring: what differs and why)
IDENTIFY_SETTINGS = an.Settings(min_improvement=0.001, other_signal_tolerance=0.05, at_floor=0.0, max_effects=10,
                                check_outside_vocabulary=False)
#: [rad/s^2] samples accelerating faster are left out of the fit (module docstring: LiveEstimator's TRANSIENT)
QUASI_STATIC_ACCELERATION = 200.0
#: fewer samples than this in either set of the split cannot rank the candidates
MIN_SAMPLES = 200


class IdentificationError(ValueError):
    """The record cannot be fitted (too short, too slow); the message says what to change."""


def default_refit(rig_file: str | Path | None, free: Sequence[str] | None = None) -> tuple[list[str], str]:
    """(parameters to fit, where the choice came from): ``free`` if given, else the standard set (whatever the
    provenance of the declared numbers) plus the rig file's ``free:`` list (module docstring).  The friction
    model's mu appears as ``friction.mu`` (worm_model.residuals.free.resolve_parameters names it for the rig).

    Raises:
        ParameterError: an unreadable rig file or an unknown parameter name.
    """
    if free is not None:
        return check_free(free, "--free"), "--free"
    listed = read_free(rig_file)
    names = list(STANDARD_REFIT) + [name for name in listed if name not in STANDARD_REFIT]
    why = "the standard set of worm_model.residuals.free, whatever the provenance of the declared numbers"
    return names, why + (" + the rig file's free: list" if listed else "")


@dataclass
class Identification:
    """The identified model and how it was found."""

    model: ExtendedModel
    analysis: an.Analysis
    problem: an.Problem
    declared: Rig
    fitted: list[str]
    choice: str  # where the fitted list came from
    speed_max: float  # [rad/s] covered by the record
    torque_range: tuple[float, float]  # [N m] covered by the record
    rig_time: float  # [s] of samples in the record
    samples: int

    @property
    def corrections(self) -> dict[str, tuple[float, float, float]]:
        """parameter -> (declared, identified, 95 % half-width), SI."""
        final = self.analysis.final
        return {p: (get_value(self.declared, p), get_value(self.model.rig, p), float(final.free_ci.get(p, math.nan)))
                for p in self.fitted if p not in self.analysis.aliased_parameters}

    def correction_lines(self) -> list[str]:
        """The corrections as ``residuals`` prints them (and mu as a friction coefficient)."""
        lines = [correction_line(row) for row in corrections(self.problem, self.analysis)]
        mu = mu_line(self.problem, self.analysis)
        return lines + ([mu] if mu else [])

    def section(self, source: str) -> dict:
        """The ``identification:`` section of the written file."""
        return {
            "source": source,
            "samples": int(self.samples), "rig_time_s": round(self.rig_time, 3),
            "speed_max": {"value": round(self.speed_max, 3), "unit": "rad/s"},
            "torque_min": {"value": round(self.torque_range[0], 6), "unit": "N m"},
            "torque_max": {"value": round(self.torque_range[1], 6), "unit": "N m"},
            "fitted": list(self.fitted), "fitted_choice": self.choice,
            "effects_found": list(self.model.names),
            "rms_before_A": float(f"{self.analysis.rms_before:.6g}"),
            "rms_after_A": float(f"{self.analysis.final.rms_held_out:.6g}"),
        }


def identify(data: MeasuredData, rig_file: str | Path | None, free: Sequence[str] | None = None,
             settings: an.Settings = IDENTIFY_SETTINGS,
             progress: Callable[[str, int, int], None] | None = None) -> Identification:
    """Fit the rig file's uncertain parameters and the effects to ``data`` (module docstring).

    Raises:
        ParameterError: a bad rig file or parameter name.
        IdentificationError: too few usable samples.
    """
    declared = load_rig(rig_file or None)
    fitted, choice = default_refit(rig_file, free)
    fitted = resolve_parameters(declared, fitted, "--free" if free is not None else str(rig_file or default_rig_path()))
    settings = replace(settings, refit=tuple(fitted))
    finite = np.isfinite(data.current_drive)
    signals = prepare_signals(declared, data, settings.alpha_time_constant, settings.reference_temperature)
    quasi_static = np.abs(signals.alpha) <= QUASI_STATIC_ACCELERATION
    split = an.make_split(signals, settings, finite & quasi_static)
    for name, mask in (("training", split.train), ("held-out", split.held_out)):
        if mask.sum() < MIN_SAMPLES:
            raise IdentificationError(f"{data.source}: only {int(mask.sum())} {name} samples with |omega_worm| >= "
                                      f"{settings.min_speed:g} rad/s and |alpha| <= {QUASI_STATIC_ACCELERATION:g} "
                                      f"rad/s^2 (need {MIN_SAMPLES}): record longer")
    problem = an.Problem(declared, [], signals, data.current_drive, split, settings)
    result = an.analyse(problem, progress)
    model = ExtendedModel(*an.extended_effects(result), settings.alpha_time_constant)
    speed = np.abs(data.omega_worm[finite])
    tau = data.tau_load[np.isfinite(data.tau_load)]
    runs = np.unique(data.run)
    rig_time = float(sum(np.ptp(data.t[data.run == r]) + data.sample_period for r in runs))
    return Identification(model, result, problem, declared, list(problem.free), choice,
                          float(np.percentile(speed, 99.9)),
                          (float(np.percentile(tau, 0.5)), float(np.percentile(tau, 99.5))),
                          rig_time, len(data))


def write_identified(path: str | Path, rig_file: str | Path | None, ident: Identification, source: str) -> None:
    """Write the extended rig file: residuals' format (identified values, ``free:``, ``effects:``) plus the
    ``identification:`` section (ranges, what was fitted). Loadable by load_rig and ExtendedModel.load."""
    result = ident.analysis
    provenance = f"identified by identify from {source}"
    write_parameter_file(path, rig_file or default_rig_path(), ident.model,
                         [p for p in ident.fitted if p not in result.aliased_parameters], result.final.free_ci,
                         provenance)
    text = Path(path).read_text(encoding="utf-8")
    Path(path).write_text(text + yaml.safe_dump({"identification": ident.section(source)}, sort_keys=False),
                          encoding="utf-8")


__all__ = ["IDENTIFY_SETTINGS", "QUASI_STATIC_ACCELERATION", "Identification", "IdentificationError",
           "default_refit", "identify", "write_identified"]
