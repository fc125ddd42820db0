"""The extended model: the declared model plus identified effects, as a parameter file and a function.

File: a ``worm_rig_parameters`` v1 file (worm_model.physics.parameters) with two optional
top-level sections that ``load_rig`` skips:

``free``     the parameters the residual analysis fitted (dotted names, see residuals.free);
``effects``  effect name -> {parameter: value} with the vocabulary's parameter names,
             units and signs (worm_model.effects: the ``effects:`` section of a
             ``worm_rig_effects`` file, read and checked by its ``file_format``), so
             ``SimulatedRig(rig, effects=doc["effects"])`` simulates the identified model.

Use from an estimator or model_node (plain numpy, no ROS)::

    model = ExtendedModel.load("extended_rig.yaml")
    sig = model.signals(omega_worm, alpha_worm, tau_load, theta_worm, theta_gear=None, t=t)
    i_expected = model.current(sig)                       # drive current [A] the model expects
    tau_d = model.estimate_load_torque(sig, current)       # load torque [N m] that explains `current`

Sign conventions as worm_model: omega/alpha + along + worm rotation, tau_load + opposes +
rotation, current + drives + rotation.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike

from worm_model.physics.parameters import Rig, default_rig_path, load_rig
from worm_model.effects import EffectsConfig, as_config, load_effects
from worm_model.errors import EffectsError, ParameterError
from worm_model.physics.units import UNITS, FloatArray, normalize_unit

from worm_model.residuals.effects import EFFECTS, Effect, channels_of
from worm_model.residuals.free import check_free, get_value
from worm_model.residuals.model import ALPHA_TIME_CONSTANT, Signals, evaluate


@dataclass
class ExtendedModel:
    """Rig parameters (free ones identified) plus effects [(effect, values, grid), ...]."""

    rig: Rig
    effects: list[tuple[Effect, dict[str, float], dict[str, float]]] = field(default_factory=list)
    alpha_time_constant: float = ALPHA_TIME_CONSTANT  # [s] of the acceleration filter the ripple terms assume

    @property
    def names(self) -> list[str]:
        return [e.name for e, _v, _g in self.effects]

    def without_effects(self) -> "ExtendedModel":
        return replace(self, effects=[])

    # ------------------------------------------------------------------ evaluation
    def signals(self, omega_worm: ArrayLike, alpha_worm: ArrayLike, tau_load: ArrayLike, theta_worm: ArrayLike,
                theta_gear: ArrayLike | None = None, t: ArrayLike | None = None, run: ArrayLike | None = None,
                temperature: ArrayLike | None = None) -> Signals:
        """Bundle per-sample inputs (arrays of one shape (n,)); t defaults to the rig's sample clock.

        alpha_worm is the worm acceleration [rad/s^2] as the caller filters it (periodic
        terms assume the filter of ALPHA_TIME_CONSTANT; a live causal filter makes them approximate).
        """
        w = np.atleast_1d(np.asarray(omega_worm, dtype=float))
        n = len(w)
        th = np.broadcast_to(np.asarray(theta_worm, dtype=float), (n,))
        return Signals(
            t=np.arange(n) / self.rig.sensors.sample_rate_hz if t is None
            else np.broadcast_to(np.asarray(t, float), (n,)),
            omega=w, alpha=np.broadcast_to(np.asarray(alpha_worm, dtype=float), (n,)),
            theta_worm=th,
            theta_gear=self.rig.gearbox.ratio * th if theta_gear is None
            else np.broadcast_to(np.asarray(theta_gear, dtype=float), (n,)),
            tau_load=np.broadcast_to(np.asarray(tau_load, dtype=float), (n,)),
            run=np.zeros(n, dtype=int) if run is None else np.asarray(run, dtype=int),
            temperature=None if temperature is None else np.asarray(temperature, dtype=float),
            alpha_time_constant=self.alpha_time_constant,
        )

    def current(self, signals: Signals) -> FloatArray:
        """Drive current [A] the extended model expects (what the current sensor would read)."""
        ch = channels_of(self.effects, self.rig, signals)
        return evaluate(self.rig, signals, ch).current

    def drive_torque(self, signals: Signals) -> FloatArray:
        """The same as a motor torque, K_t * current [N m]."""
        return self.rig.drive_motor.torque_constant * self.current(signals)

    def estimate_load_torque(self, signals: Signals, current: ArrayLike, limit: float | None = None,
                             iterations: int = 40, tolerance: float = 1e-9) -> FloatArray:
        """Load torque tau_d [N m] for which the model's current equals the measured one.

        The current is piecewise nearly affine in tau_d (slopes K_+ and K_- on the two flanks),
        so a bracketed secant (Illinois variant of regula falsi) converges in a few steps.

        Args:
            current: measured drive current [A] per sample.
            limit: search interval [-limit, limit] [N m]; default 3x the load motors' capacity.
            tolerance: stop when every bracketed sample's current matches within this [A].
        Returns:
            tau_d per sample; NaN where no load in the interval explains the current (the
            model's current does not bracket it) or the input is not finite.
        """
        i = np.asarray(current, dtype=float)
        lim = 3.0 * self.rig.max_load_torque if limit is None else float(limit)
        lo = np.full(len(signals), -lim)
        hi = np.full(len(signals), lim)

        def f(tau: FloatArray) -> FloatArray:
            return self.current(replace(signals, tau_load=tau)) - i

        f_lo, f_hi = f(lo), f(hi)
        ok = np.isfinite(f_lo) & np.isfinite(f_hi) & (np.sign(f_lo) != np.sign(f_hi))
        x = 0.5 * (lo + hi)
        side = np.zeros(len(signals))  # which end moved last (Illinois: halve the other's weight)
        for _ in range(iterations):
            with np.errstate(divide="ignore", invalid="ignore"):
                x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
            x = np.where(np.isfinite(x) & (x > np.minimum(lo, hi)) & (x < np.maximum(lo, hi)), x, 0.5 * (lo + hi))
            fx = f(x)
            if np.all(~ok | (np.abs(fx) <= tolerance)):
                break
            same_as_lo = np.sign(fx) == np.sign(f_lo)
            f_hi = np.where(same_as_lo & (side == 1), 0.5 * f_hi, f_hi)
            f_lo = np.where(~same_as_lo & (side == -1), 0.5 * f_lo, f_lo)
            lo, f_lo = np.where(same_as_lo, x, lo), np.where(same_as_lo, fx, f_lo)
            hi, f_hi = np.where(same_as_lo, hi, x), np.where(same_as_lo, f_hi, fx)
            side = np.where(same_as_lo, 1, -1)
        return np.where(ok, x, np.nan)

    # ------------------------------------------------------------------ file
    @classmethod
    def load(cls, path: str | Path, alpha_time_constant: float = ALPHA_TIME_CONSTANT) -> "ExtendedModel":
        """Read a parameter file with an optional ``effects:`` section.

        Raises:
            ParameterError: bad rig file; EffectsError (a ParameterError): a bad ``effects:`` section
                (worm_model.effects.file_format), or an effect the residual analysis has no regressor for.
        """
        rig = load_rig(path)
        config = load_effects(path)
        effects = []
        for name, entry in config.effects.items():
            if name not in EFFECTS:
                raise EffectsError(str(path), f"effects.{name}", "the residual analysis has no regressor for this "
                                   f"effect (it has: {', '.join(EFFECTS)})")
            effect = EFFECTS[name]
            values, grid = effect.from_simulator_entry(entry, rig)
            effects.append((effect, values, grid))
        return cls(rig, effects, alpha_time_constant)


def _si_to_unit(value: float, unit: str) -> float:
    factor, _dimension = UNITS[normalize_unit(unit)]
    return value / factor


def write_parameter_file(path: str | Path, base_file: str | Path, model: ExtendedModel, free: Sequence[str],
                         free_ci: Mapping[str, float], provenance: str,
                         effect_notes: Mapping[str, str] | None = None) -> None:
    """Write the extended model: the base rig file with identified free values, ``free:`` and ``effects:``.

    Every identified leaf gets ``source: "<provenance> (95 % CI +-x unit); declared <value> <unit>, <its
    source or assumption>"`` in place of its provenance, so the file stays a valid ``worm_rig_parameters``
    file and keeps what was declared beside what was identified.
    """
    document = yaml.safe_load(Path(base_file).read_text(encoding="utf-8"))
    document = json.loads(json.dumps(document))  # break YAML anchors: load_motor aliases drive_motor
    for name in check_free(free):
        section, leaf = name.split(".")
        node = document[section][leaf]
        unit = node["unit"]
        value = _si_to_unit(get_value(model.rig, name), unit)
        ci = _si_to_unit(free_ci.get(name, math.nan), unit)
        kind = "source" if "source" in node else "assumption"
        shown = f"{node['value']}" + ("" if unit == "1" else f" {unit}")
        before = f"declared {shown}, {kind}: {_shortened(str(node.get(kind, '')))}"
        node = {k: v for k, v in node.items() if k not in ("source", "assumption")}
        node["value"] = float(f"{value:.6g}")
        node["source"] = f"{provenance} (95 % CI +-{ci:.2g} {unit}); {before}"
        document[section][leaf] = node
    document["free"] = list(free)
    left_out: dict[str, str] = {}
    document["effects"] = effects_section(model, str(path), left_out)
    effect_notes = {**(effect_notes or {}), **{name: f"left out of this model, its fit is unphysical: {why}"
                                               for name, why in left_out.items()}}
    header = (f"# Extended model written by `residuals` ({provenance}).\n"
              "# Rig parameters as in the base file, free ones identified; `effects:` is a worm_rig_effects\n"
              "# section: the effects' parameter names and units (worm_effects --list).\n")
    notes = "".join(f"# {name}: {note}\n" for name, note in (effect_notes or {}).items())
    Path(path).write_text(header + notes + yaml.safe_dump(document, sort_keys=False), encoding="utf-8")


def effects_section(model: ExtendedModel, origin: str = "<fitted>",
                    left_out: dict[str, str] | None = None) -> dict[str, dict[str, float]]:
    """The ``effects:`` section a file of the extended model holds: each fitted effect as the vocabulary's parameters
    (its regressor's translation, 6 significant digits), checked and completed by worm_model.effects.file_format.

    A fitted effect with a value no effects file may hold (outside its declared range: no physical gearbox has it,
    so the fit took up something else) is left out of the section, and why goes into ``left_out`` (effect name ->
    the file format's reason), for the writer to say so.
    """
    fitted = {}
    for effect, values, grid in model.effects:
        entry = {k: float(f"{v:.6g}") for k, v in effect.simulator_entry(values, grid).items()}
        try:
            EffectsConfig.from_mapping({effect.name: entry}, origin)
        except EffectsError as err:
            if left_out is not None:
                left_out[effect.name] = str(err)
            continue
        fitted[effect.name] = entry
    return EffectsConfig.from_mapping(fitted, origin).section()


def _shortened(text: str, limit: int = 120) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks the cut)."""
    return text if len(text) <= limit else text[: limit - 3].rstrip() + "..."


def write_with_effects(path: str | Path, effects: Mapping[str, Any], base_file: str | Path | None = None) -> Path:
    """Write ``base_file`` (None: the bundled rig file) with ``effects`` (the vocabulary's names and units, as a
    ``worm_rig_effects`` file's ``effects:`` mapping, checked and every parameter written) as its ``effects:``
    section; loadable by ExtendedModel.load.

    Raises:
        ParameterError: the base file cannot be read; EffectsError: a bad ``effects`` mapping.
    """
    base = Path(base_file) if base_file else default_rig_path()
    try:
        document = yaml.safe_load(base.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as err:
        raise ParameterError(str(base), "", f"cannot read parameter file: {err}") from err
    document = json.loads(json.dumps(document))  # plain data: no YAML aliases shared between sections
    document["effects"] = as_config(dict(effects)).section()
    Path(path).write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return Path(path)
