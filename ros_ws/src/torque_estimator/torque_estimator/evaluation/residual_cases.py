"""The residual tool's case matrix: `residuals` on the project's simulator, true effects against found ones.

Each case simulates a few seconds of n rigs side by side (worm_rig_driver's SimulatedRig, its
effect plug-ins switched on, the model not told) and gives the analysis a *rig file*, written
to disk as a user writes one: the rig's own file with its declared numbers off by realistic
amounts (:data:`PERTURBATIONS`: mu +-30 %, K_t +-5 %, drags x2 / x0.5, inertias +-20 %, the oil
reference temperature +-15 K; mu 25 % and K_t 3 % high as copied from a catalogue; drags declared
0), every changed number carrying a ``source:`` (a catalogue value) instead of its
``assumption:``.  The analysis reads that file as the ``residuals`` executable does
(``load_rig``, its ``free:`` list).

So that the matrix cannot be passed by one rig file's choices it spans the rig-file options
(:data:`RIGS`): two rigs (the bundled NMRV030 and a size-040 variant with another ratio, motor,
load motor count, current sensor: ``worm_model/data/nmrv040_rig.yaml``), each under every
friction model of worm_model.physics.friction.FRICTION_MODELS (the plant follows the rig file's
model; its mu is the file's).  A plant may differ from its file beyond the declared values
(``Case.plant``: e.g. no drag at all, where a fit that trades the drags against the rest goes
negative).

A case passes when ``effects_found`` is exactly its true set (parameter corrections are not
effects), every refitted drag and mu is physical (not below 0) and the held-out RMS after is
within ``Settings.unexplained_factor`` (1.3) of the noise floor estimated from the data; with an
effect outside the vocabulary (:data:`OUT_OF_VOCABULARY`) it passes when nothing is named (the
residual above 1.3x the floor is then reported as ``unexplained=``; what the corrections can take of
such an effect, as mu takes most of a load-proportional bearing drag, may leave it at the floor).

Effect sizes: each is large enough to move the held-out RMS by more than the 2 % the
selection asks for at the rig's current noise (NMRV030: 0.0215 A; NMRV040: 0.033 A, and a
current per worm torque twice the NMRV030's, :data:`SIZES`).  Effects that are the same
function of the data as a refitted parameter (sensor_gain ~ K_t, bearing_coulomb ~ the
Coulomb drags, viscous_drag ~ the viscous drag, inertia_error ~ the rotor inertia,
free.TOLERANCES) can only be told from a wrong declared value by size, so their cases
lie beyond the tolerance band *including* a declared value off by the amounts above
(e.g. bearing drag 30 mN m on the worm: 34 mN m against a declared 8 mN m is x4.25 > x2.5).

It lives here, with the studies, because it needs both the residual analysis
(worm_model) and the simulator (worm_rig_driver).

:func:`run_matrix` runs a list of cases; :func:`full_matrix` is what ``make evaluate``
prints (last line: :func:`summary_line`; ``--residual-cases small``: :func:`small_matrix`, a subset);
:func:`families` names the groups the matrix is built from (``python -m
torque_estimator.evaluation.residual_cases --family NAME`` runs one).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import multiprocessing
import os
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from worm_model.physics.parameters import Rig, default_rig_path, load_rig
from worm_model.rig_data.schema import MeasuredData

import worm_model.residuals.analysis as an
from worm_model.residuals.free import LOWER_BOUNDS, get_value, mu_parameter, read_free, set_values
from worm_model.residuals.model import prepare_signals

#: rig files the matrix uses: key -> (file in worm_model/data, friction model written into it, None: the file's)
RIGS: dict[str, tuple[str, str | None]] = {
    "nmrv030": ("nmrv030_rig.yaml", None),  # the bundled rig: AGMA friction
    "nmrv030_constant": ("nmrv030_rig.yaml", "constant"),  # the same rig, mu a constant (the file's 0.05)
    "nmrv040": ("nmrv040_rig.yaml", None),  # the variant rig: constant mu 0.06
    "nmrv040_agma": ("nmrv040_rig.yaml", "agma"),  # the variant rig under the AGMA curve
    "nmrv030_stribeck": ("nmrv030_rig.yaml", "stribeck"),  # the bundled rig, mu a Stribeck law (FRICTION_LEAVES)
}

#: friction leaves a RIGS key writes into its file beside the model: leaf -> (value [SI], assumption)
FRICTION_LEAVES: dict[str, dict[str, tuple[float, str]]] = {
    "nmrv030_stribeck": {
        "stribeck_rise": (0.03, "a Stribeck rise of 60 % of the file's kinetic 0.05, as a lubricated bronze mesh "
                                "shows at low sliding speed (the residual case matrix's choice)"),
        "stribeck_speed": (0.3, "V_st 0.3 m/s: the rise is felt over the lower third of the rig's 0.2-3.4 m/s "
                                "sliding speeds, so the profiles' speeds see it (the residual case matrix's choice)"),
    },
}

#: excitation profiles for the NMRV030 rig (24 V, 0.275 N m of load): drive voltage offsets [V], load offset
#: and swing [N m] (as tests/test_residuals_sim.py); "square": the load steps through zero; "reverse": every
#: third rig reverses its drive smoothly with almost no load.  Another rig scales the voltages by its supply
#: and the loads by its load motors' capacity (:func:`simulate`)
PROFILES: dict[str, dict[str, Any]] = {
    "standard": {"volts": (1.5, 20.0), "load": (-0.12, 0.2), "swing": (0.02, 0.15)},
    "low_speed": {"volts": (1.0, 4.0), "load": (0.1, 0.3), "swing": (0.02, 0.08)},
    "wide_load": {"volts": (3.0, 20.0), "load": (-0.05, 0.3), "swing": (0.1, 0.2)},
    "high_load": {"volts": (4.0, 20.0), "load": (0.1, 0.3), "swing": (0.02, 0.08)},
    "slow_high_load": {"volts": (2.0, 10.0), "load": (0.12, 0.3), "swing": (0.02, 0.08)},
    "slow_full_load": {"volts": (1.0, 3.0), "load": (0.2, 0.24), "swing": (0.02, 0.03)},
    "flank": {"volts": (3.0, 16.0), "load": (-0.03, 0.05), "swing": (0.08, 0.2), "square": True, "reverse": True},
}
#: the rig the profiles are written for: supply [V] and load motors' capacity [N m] (the bundled NMRV030)
PROFILE_SUPPLY = 24.0

#: oil sump sensor: resolution [K] and noise [K] (the climate-chamber case of tests/test_residuals_sim.py)
OIL_SENSOR = (0.25, 0.2)

#: declared-value errors: factor on the rig file's value (the simulated rig keeps the file's values);
#: "mu" is the friction model's mu parameter (free.MU_PARAMETERS); "reference_temperature" is an offset [K]
#: of the oil temperature at which the tool assumes the declared mu; a factor 0 declares the value 0
PERTURBATIONS: dict[str, dict[str, float]] = {
    "nominal": {},
    "high": {"mu": 1.3, "torque_constant": 1.05, "drags": 2.0, "inertia": 1.2, "reference_temperature": 15.0},
    "low": {"mu": 0.7, "torque_constant": 0.95, "drags": 0.5, "inertia": 0.8, "reference_temperature": -15.0},
    # mu and K_t copied from a catalogue: mu 25 % and K_t 3 % high, both with a source
    "catalogue": {"mu": 1.25, "torque_constant": 1.03},
    # no drag known, so none declared: every drag 0 (with a source: "none measured")
    "zero_drags": {"drags": 0.0},
}

_DRAGS = ("drive_motor.coulomb_drag", "drive_motor.viscous_drag", "load_motor.coulomb_drag", "load_motor.viscous_drag")
_INERTIAS = ("drive_motor.rotor_inertia", "gearbox.worm_inertia", "gearbox.gear_inertia")


def perturbed_parameters(rig: Rig, perturbation: Mapping[str, float]) -> dict[str, float]:
    """Dotted rig parameter -> factor on its value, for the groups of a perturbation (:data:`PERTURBATIONS`)."""
    out: dict[str, float] = {}
    for key, factor in perturbation.items():
        if key in ("mu", "friction.scale"):  # "friction.scale": the AGMA name of mu, as older callers wrote it
            out[mu_parameter(rig.friction.model)] = factor
        elif key == "torque_constant":  # K_e equals K_t in SI: a user who has one wrong has both
            out.update({"drive_motor.torque_constant": factor, "drive_motor.back_emf_constant": factor})
        elif key == "drags":
            out.update(dict.fromkeys(_DRAGS, factor))
        elif key == "inertia":
            out.update(dict.fromkeys(_INERTIAS, factor))
        elif key != "reference_temperature":
            raise KeyError(f"unknown perturbation group {key!r}")
    return out


def declared_rig(rig: Rig, perturbation: Mapping[str, float]) -> Rig:
    """``rig`` with its declared numbers off by ``perturbation`` (the groups of :data:`PERTURBATIONS`)."""
    factors = perturbed_parameters(rig, perturbation)
    return set_values(rig, list(factors), [get_value(rig, n) * f for n, f in factors.items()])


def rig_path(key: str) -> Path:
    """The file of a :data:`RIGS` key."""
    return default_rig_path().parent / RIGS[key][0]


def plant_rig(key: str, plant: Mapping[str, float] = {}) -> Rig:  # noqa: B006 (read only)
    """The simulated rig of a :data:`RIGS` key: its file's values under the key's friction model, then
    ``plant`` (perturbation groups, factors on the file's values) where the plant differs from its file."""
    rig = load_rig(rig_path(key))
    model = RIGS[key][1]
    if model is not None:
        leaves = {leaf: value for leaf, (value, _) in FRICTION_LEAVES.get(key, {}).items()}
        rig = dataclasses.replace(rig, friction=dataclasses.replace(rig.friction, model=model, **leaves))
    return declared_rig(rig, plant)


def write_rig_file(path: str | Path, key: str, perturbation: Mapping[str, float],
                   source: str = "catalogue value") -> Path:
    """The rig file a user writes: the key's file (its friction model set) with the numbers of ``perturbation``
    changed, each then carrying ``source:`` (``source``) instead of its ``assumption:``; loadable by load_rig."""
    base = rig_path(key)
    document = json.loads(json.dumps(yaml.safe_load(base.read_text(encoding="utf-8"))))  # no shared YAML anchors
    model = RIGS[key][1]
    if model is not None:
        document["friction"]["model"] = model
        for leaf, (value, why) in FRICTION_LEAVES.get(key, {}).items():
            document["friction"][leaf] = {"value": value, "unit": "m/s" if leaf == "stribeck_speed" else "1",
                                          "assumption": why}
    rig = plant_rig(key)
    for name, factor in perturbed_parameters(rig, perturbation).items():
        section, leaf = name.split(".")
        node = document[section][leaf]
        node["value"] = float(f"{float(node['value']) * factor:.6g}")
        node.pop("assumption", None)
        node["source"] = (f"{source} (the residual case matrix declares x{factor:g} the simulated rig's value)"
                          if factor else f"{source}: none measured, declared 0")
    Path(path).write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return Path(path)


@dataclass(frozen=True)
class Case:
    """One simulated data set and what the analysis should name.

    ``effects``: the simulator's ``effects:`` mapping; ``extra``: out-of-vocabulary effects
    (:data:`OUT_OF_VOCABULARY` keys) added to the simulator; ``truth``: the names a correct
    analysis gives (the vocabulary effects switched on).  ``rig``: a :data:`RIGS` key;
    ``plant``: perturbation groups where the simulated rig differs from its file (e.g.
    ``{"drags": 0.0}``: no drag at all); ``perturbation``: the rig file given to the analysis.
    """

    name: str
    effects: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    profile: str = "standard"
    perturbation: str = "nominal"
    extra: tuple[str, ...] = ()
    oil_start: tuple[float, ...] = ()
    runs: int = 10
    seconds: float = 4.0
    seed: int = 1
    rig: str = "nmrv030"
    plant: Mapping[str, float] = field(default_factory=dict)

    @property
    def truth(self) -> tuple[str, ...]:
        return tuple(sorted(self.effects))


# --------------------------------------------------------------------------- out-of-vocabulary effects
def _out_of_vocabulary() -> dict[str, Callable[[int, Rig], Any]]:
    """Simulator effects no vocabulary entry describes (factories: (n, rig) -> live effect), sized for the
    rig's file (:data:`OOV_SIZES`)."""
    from worm_rig_driver.sim.effects import EffectBase  # noqa: PLC0415

    class SteppedGearFriction(EffectBase):
        """Gear-shaft friction that depends on the gear angle in steps: +drag over one half of each gear
        turn, -drag over the other (an eccentric seal face: tight, then loose, about the declared drag).
        Odd in the direction of rotation and zero on average, so neither a drag correction nor a ripple
        of the vocabulary (gear_runout does not flip with the direction) takes it."""

        name = "stepped_gear_friction"

        def gear_torque(self, s):
            return self.size * np.sign(s.omega_gear) * np.sign(np.sin(s.theta_gear))

    class GearOrder3Ripple(EffectBase):
        """A torque ripple three times per gear turn on the gear shaft (a three-jaw coupling): no vocabulary
        effect has that order (gear_runout is once per gear turn, tooth_pass Z_g per gear turn)."""

        name = "gear_order3_ripple"

        def gear_torque(self, s):
            return self.size * np.sin(3.0 * s.theta_gear + 0.4)

    class LoadBearingFriction(EffectBase):
        """Friction of the output bearings under the mesh force: a gear-shaft drag proportional to the torque
        the mesh carries, size x mesh_load, against the gear's rotation.  On the driving flank it is the same
        function as a larger mu; on the coast flank it keeps opposing the motion where a mu change would
        help it, and at no load it vanishes where a Coulomb drag would not: the vocabulary has no such term
        (load_dependent_mu changes mu, i.e. acts with the flank)."""

        name = "load_bearing_friction"

        def gear_torque(self, s):
            return self.size * s.mesh_load * np.sign(s.omega_gear)

    class CurrentDrift(EffectBase):
        """A drive-current sensor whose zero drifts linearly while it warms: reading + size x t [A/s] (t from
        the start of every run).  A constant offset (sensor_offset) takes its mean and nothing in the
        vocabulary is linear in time (the oil's heating proxy scales mu, i.e. follows the load)."""

        name = "current_drift"

        def __init__(self, params, n, rig):
            super().__init__(params, n, rig)
            self.t0: float | None = None

        def sense(self, signals, context):
            t = context.channel_time["current_drive"]
            self.t0 = t if self.t0 is None else self.t0
            signals["current_drive"] = signals["current_drive"] + self.size * (t - self.t0)

    class WormHalfOrderRipple(EffectBase):
        """A torque ripple 1.5 times per worm turn (a coupling or belt stage at a 3:2 ratio on the motor shaft):
        the vocabulary's worm-angle ripples are whole orders (worm_runout 1, motor_cogging 2..60)."""

        name = "worm_order_1_5_ripple"

        def worm_torque(self, s):
            return -self.size * np.sin(1.5 * s.theta_worm + 0.7)

    classes = (SteppedGearFriction, GearOrder3Ripple, LoadBearingFriction, CurrentDrift, WormHalfOrderRipple)

    def factory(cls):
        def make(n: int, rig: Rig):
            effect = cls({}, n, rig)
            effect.size = OOV_SIZES[Path(rig.source).name if rig.source else RIGS["nmrv030"][0]][cls.name]
            return effect
        return make

    return {cls.name: factory(cls) for cls in classes}


#: the out-of-vocabulary effects' sizes per rig file: gear-shaft torques [N m] (stepped_gear_friction,
#: gear_order3_ripple), a fraction of the mesh load (load_bearing_friction), a drift [A/s] (current_drift),
#: a worm-shaft torque [N m] (worm_order_1_5_ripple).  Each leaves the true model's held-out RMS well above
#: 1.3x the floor; the NMRV040 carries a gear torque to the current ~3x more strongly (K_t 0.025 N m/A, ratio 20)
OOV_SIZES: dict[str, dict[str, float]] = {
    "nmrv030_rig.yaml": {"stepped_gear_friction": 0.04, "gear_order3_ripple": 0.05, "load_bearing_friction": 0.2,
                         "current_drift": 0.02, "worm_order_1_5_ripple": 0.005},
    "nmrv040_rig.yaml": {"stepped_gear_friction": 0.02, "gear_order3_ripple": 0.025, "load_bearing_friction": 0.15,
                         "current_drift": 0.025, "worm_order_1_5_ripple": 0.003},
}

OUT_OF_VOCABULARY = ("stepped_gear_friction", "gear_order3_ripple", "load_bearing_friction", "current_drift",
                     "worm_order_1_5_ripple")


# --------------------------------------------------------------------------- simulation
def simulate(case: Case, rig: Rig | None = None) -> MeasuredData:
    """``case.runs`` runs of ``case.seconds`` (1 s gaps in t), sampled at the rig's rate, open-loop voltage.

    The drive voltage is a slow sinusoid around a per-rig offset (both signs), the load a slow
    sinusoid or square wave of both signs; see :data:`PROFILES` (voltages scaled by the rig's supply,
    loads by its load motors' capacity, both against the NMRV030's).  With ``oil_start`` the rigs
    start at those oil temperatures and a sump sensor fills the ``temperature`` column.
    ``rig``: the simulated rig (default: the case's, :func:`plant_rig`).
    """
    from worm_rig_driver.sim.effects import EffectStack  # noqa: PLC0415
    from worm_rig_driver.sim.simulated_rig import SimulatedRig  # noqa: PLC0415

    rig = rig or plant_rig(case.rig, case.plant)
    p, n, seed = PROFILES[case.profile], case.runs, case.seed
    volt_scale = rig.supply_voltage / PROFILE_SUPPLY
    load_scale = rig.max_load_torque / load_rig().max_load_torque
    rng = np.random.default_rng(seed)
    sim = SimulatedRig(rig, n=n, seed=seed, effects={k: dict(v) for k, v in case.effects.items()}, scalar=False)
    if case.extra:  # switched on behind the registry's back: the point is that nothing knows them
        factories = _out_of_vocabulary()
        stack = EffectStack(list(sim.plant.fx.effects) + [factories[k](n, rig) for k in case.extra])
        sim.plant.fx = stack
        sim.plant._has_effects = True
        sim.sensors.effects = stack
    if case.oil_start:
        oil = next(e for e in sim.plant.fx.effects if e.name == "oil_temperature")
        oil.temperature = np.resize(np.asarray(case.oil_start, dtype=float), n)
    steps = int(round(case.seconds * rig.sensors.sample_rate_hz))
    dt = 1.0 / rig.sensors.sample_rate_hz
    v0 = rng.permutation(np.linspace(*p["volts"], n)) * np.where(np.arange(n) % 2, 1.0, -1.0) * volt_scale
    v1, f1 = rng.uniform(0.1, 0.3, n) * np.abs(v0), rng.uniform(0.5, 3.0, n)
    l0, l1, f2 = rng.uniform(*p["load"], n) * load_scale, rng.uniform(*p["swing"], n) * load_scale, \
        rng.uniform(0.2, 1.0, n)
    reverse = (np.arange(n) % 3 == 1) if p.get("reverse") else np.zeros(n, dtype=bool)
    if p.get("square"):
        v1, f2 = np.zeros(n), rng.uniform(0.7, 1.5, n)
    l0, l1 = np.where(reverse, rng.uniform(-0.005, 0.005, n) * load_scale, l0), np.where(reverse, 0.0, l1)
    f_rev = rng.uniform(0.25, 0.5, n)
    wave = np.sign if p.get("square") else (lambda x: x)
    keys = ("current_drive", "omega_worm", "theta_worm", "theta_gear", "tau_load", "voltage_drive")
    rec = {k: np.empty((steps, n)) for k in keys}
    oil = np.empty((steps, n))
    for k in range(steps):
        t = k * dt
        volts = v0 + v1 * np.sin(2 * np.pi * f1 * t)
        sim.command(voltage_drive=np.where(reverse, v0 * np.sin(2 * np.pi * f_rev * t + 0.3), volts),
                    load_torque=l0 + l1 * wave(np.sin(2 * np.pi * f2 * t)))
        m = sim.sample()
        for key in keys:
            rec[key][k] = getattr(m, key)
        if case.oil_start:
            oil[k] = sim.plant.fx.observe()["oil_temperature"]
    t = np.concatenate([np.arange(steps) * dt + j * (case.seconds + 1.0) for j in range(n)])
    extra = {}
    if case.oil_start:
        lsb, noise = OIL_SENSOR
        extra["temperature"] = (np.round((oil + rng.normal(0.0, noise, oil.shape)) / lsb) * lsb).T.ravel()
    return MeasuredData(t=t, **{k: v.T.ravel() for k, v in rec.items()}, **extra, source=f"sim:{case.name}")


# --------------------------------------------------------------------------- running and scoring
@dataclass
class CaseResult:
    case: Case
    found: tuple[str, ...]
    rms_before: float  # [A] held-out, rig file as declared
    rms_after: float  # [A] held-out, corrections and effects
    floor: float  # [A] noise floor estimated from the data
    unexplained: float | None  # [A] or None
    corrections: dict[str, float]  # refitted parameter -> identified / declared
    seconds: float  # wall time of simulation + analysis
    identified: dict[str, float] = field(default_factory=dict)  # refitted parameter -> identified value [SI]
    true: dict[str, float] = field(default_factory=dict)  # refitted parameter -> the simulated rig's value [SI]

    @property
    def truth(self) -> tuple[str, ...]:
        return self.case.truth

    @property
    def false_names(self) -> tuple[str, ...]:
        return tuple(sorted(set(self.found) - set(self.truth)))

    @property
    def missed(self) -> tuple[str, ...]:
        return tuple(sorted(set(self.truth) - set(self.found)))

    @property
    def exact(self) -> bool:
        return not self.false_names and not self.missed

    @property
    def within_floor(self) -> bool:
        return self.rms_after <= an.Settings().unexplained_factor * self.floor

    @property
    def unphysical(self) -> tuple[str, ...]:
        """Refitted parameters identified below their physical bound (drags, mu, inertias: free.LOWER_BOUNDS)."""
        return tuple(p for p, low in LOWER_BOUNDS.items() if self.identified.get(p, low) < low)

    @property
    def mu_ratio(self) -> float:
        """Identified / true value of the friction model's mu parameter (NaN when it was not refitted)."""
        name = mu_parameter(plant_rig(self.case.rig).friction.model)
        true = self.true.get(name, math.nan)
        return self.identified.get(name, math.nan) / true if true else math.nan

    @property
    def passed(self) -> bool:
        """Exact names and physical corrections, and at the floor; with an effect outside the vocabulary, nothing
        named (``unexplained=`` is then reported whenever the corrections leave more than 1.3x the floor: what
        they can take of it, e.g. of a load-proportional bearing drag through mu, is theirs)."""
        if self.unphysical:
            return False
        if self.case.extra:
            return self.exact and (self.unexplained is not None or self.within_floor)
        return self.exact and self.within_floor and self.unexplained is None


def run_case(case: Case, rig: Rig | None = None) -> CaseResult:
    """Simulate the case on ``rig`` (default: the case's) and analyse it with the rig file a user would write
    (:func:`write_rig_file`, read back as the ``residuals`` executable reads it)."""
    start = time.monotonic()
    plant = rig or plant_rig(case.rig, case.plant)
    data = simulate(case, plant)
    pert = PERTURBATIONS[case.perturbation]
    with tempfile.TemporaryDirectory(prefix="residual_case_") as folder:
        path = write_rig_file(Path(folder) / "rig.yaml", case.rig, pert)
        declared, free = load_rig(path), read_free(path)
    settings = an.Settings(reference_temperature=an.Settings().reference_temperature
                           + pert.get("reference_temperature", 0.0))
    signals = prepare_signals(declared, data, settings.alpha_time_constant, settings.reference_temperature)
    split = an.make_split(signals, settings, rig=declared)
    problem = an.Problem(declared, free, signals, data.current_drive, split, settings)
    result = an.analyse(problem)
    values = dict(result.final.free_values)
    return CaseResult(case, tuple(sorted(result.found)), result.rms_before, result.final.rms_held_out,
                      result.noise.rms, None if result.unexplained is None else result.unexplained.rms,
                      {p: v / get_value(declared, p) if get_value(declared, p) else math.nan
                       for p, v in values.items()},
                      time.monotonic() - start, values, {p: get_value(plant, p) for p in values})


def run_matrix(cases: Sequence[Case], rig: Rig | None = None,
               progress: Callable[[int, CaseResult], None] | None = None,
               workers: int | None = None) -> list[CaseResult]:
    """Every case's result, in the cases' order. The cases are independent and seeded, so they run in
    ``workers`` processes (default: one per CPU; 1: in this process) with the same results; ``progress``
    hears of each as it ends."""
    workers = min(len(cases), workers if workers is not None else (os.cpu_count() or 1))
    if workers <= 1:
        out = []
        for k, case in enumerate(cases):
            out.append(run_case(case, rig))
            if progress:
                progress(k + 1, out[-1])
        return out
    # spawn, not fork: the caller may hold threads (rclpy, pytest plug-ins) that a fork would copy mid-state
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(run_case, case, rig) for case in cases]
        for k, _done in enumerate(as_completed(futures)):
            if progress:
                progress(k + 1, _done.result())
        return [f.result() for f in futures]


# --------------------------------------------------------------------------- the matrices
#: one case per vocabulary effect, sized as argued in the module docstring (profile, simulator parameters),
#: per rig file
SIZES: dict[str, dict[str, tuple[str, dict[str, float]]]] = {
    "nmrv030_rig.yaml": {
        "bearing_coulomb": ("standard", {"worm_torque": 0.03, "gear_torque": 0.03}),
        "viscous_drag": ("standard", {"worm_torque": 0.05}),
        "speed_dependent_mu": ("low_speed", {"low_speed_gain": 2.0}),
        "load_dependent_mu": ("wide_load", {"sensitivity": 2.0}),
        "oil_temperature": ("slow_full_load", {"mu_per_kelvin": -0.012}),
        "worm_runout": ("standard", {"amplitude": 8e-3, "load_fraction": 0.05}),
        "tooth_pass": ("slow_high_load", {"amplitude": 0.0, "load_fraction": 0.8}),
        "gear_runout": ("standard", {"amplitude": 0.1}),
        # order 6 at up to 400 rad/s is a 380 Hz ripple: the fitted response leaves ~1/4 of it (the current's and
        # the encoder's sampling instants differ), so 0.02 N m, not more, keeps the residual near the floor
        "motor_cogging": ("standard", {"amplitude": 0.02, "order": 6}),
        "backlash": ("flank", {}),
        "sensor_gain": ("high_load", {"drive_current": 0.3}),
        "sensor_offset": ("standard", {}),
        "inertia_error": ("standard", {"worm": 1.0}),
        # the PWM ripple's sampling bias at the simulator's default 2 kHz sensor filter peaks at 7 mA: ranked first
        # but within 1.1 x the floor (not named, by design); a 10 kHz filter (amplitude 0.36 A, bias up to 33 mA)
        # is named
        "pwm": ("standard", {"filter_cutoff": 10000.0}),
    },
    # the variant: 1 mN m on the worm is 0.04 A (K_t 0.025), a gear torque reaches the worm x0.067, noise 0.033 A
    "nmrv040_rig.yaml": {
        "bearing_coulomb": ("standard", {"worm_torque": 0.015, "gear_torque": 0.04}),
        "viscous_drag": ("standard", {"worm_torque": 0.03}),
        "speed_dependent_mu": ("low_speed", {"low_speed_gain": 2.0}),
        "load_dependent_mu": ("wide_load", {"sensitivity": 2.0}),
        "worm_runout": ("standard", {"amplitude": 4e-3, "load_fraction": 0.05}),
        "gear_runout": ("standard", {"amplitude": 0.06}),
        "motor_cogging": ("standard", {"amplitude": 0.008, "order": 6}),
        "backlash": ("flank", {}),
        "sensor_gain": ("high_load", {"drive_current": 0.3}),
        "sensor_offset": ("standard", {}),
        "inertia_error": ("standard", {"worm": 1.0}),
        # the 12 V supply over a 0.3 mH winding: a 2 A ripple before the filter; at the simulator's default 2 kHz
        # filter its sampled bias stays within 1.1 x the floor (not named, as on the NMRV030), at 5 kHz it is named
        "pwm": ("standard", {"filter_cutoff": 5000.0}),
    },
}
#: the NMRV030's sizes (the first matrix's table)
ALONE = SIZES["nmrv030_rig.yaml"]

#: pairs: each effect of the vocabulary at least once (pwm alone only), on the profile the more demanding
#: one needs
PAIRS: tuple[tuple[str, str], ...] = (
    ("motor_cogging", "bearing_coulomb"),
    ("gear_runout", "load_dependent_mu"),
    ("speed_dependent_mu", "motor_cogging"),
    ("worm_runout", "viscous_drag"),
    ("tooth_pass", "sensor_gain"),
    ("oil_temperature", "worm_runout"),  # the oil case runs at low speed: too little acceleration for inertia
    ("inertia_error", "sensor_offset"),
    ("backlash", "gear_runout"),
)

# (Not paired: sensor_offset with an effect of a one-sided load profile (low_speed, slow_full_load): with the
# load of one sign in the fixed frame, each direction of rotation runs on its own flank, and a constant current
# offset equals a worm plus a gear-side Coulomb drag (K_s differs by flank) -- not identifiable there.)

_OIL_START = (-20.0, 25.0, 70.0)
_PROFILE_RANK = ("slow_full_load", "flank", "low_speed", "slow_high_load", "wide_load", "high_load", "standard")


def case_of(names: Sequence[str], perturbation: str = "nominal", seed: int = 1, extra: Sequence[str] = (),
            rig: str = "nmrv030", plant: Mapping[str, float] | None = None) -> Case:
    """A case on ``rig`` (a :data:`RIGS` key) with the named vocabulary effects at their :data:`SIZES` (and
    OOV ``extra``); ``plant``: where the simulated rig differs from its file (named in the case's name)."""
    sizes = SIZES[RIGS[rig][0]]
    effects = {n: sizes[n][1] for n in names}
    profiles = [sizes[n][0] for n in names] or ["standard"]
    profile = min(profiles, key=_PROFILE_RANK.index)
    oil = "oil_temperature" in names
    label = "+".join(list(names) + list(extra)) or "clean"
    prefix = "" if rig == "nmrv030" else f"{rig}:"
    suffix = "".join(f",plant {k} x{v:g}" for k, v in (plant or {}).items())
    return Case(f"{prefix}{label}/{perturbation}{suffix}", effects, profile, perturbation, tuple(extra),
                _OIL_START if oil else (), runs=12 if oil else 10, seed=seed, rig=rig, plant=dict(plant or {}))


def _cycle(values: Sequence[str], k: int) -> str:
    return values[k % len(values)]


def families() -> dict[str, list[Case]]:
    """The full matrix by family: what each group of cases checks.

    * ``nmrv030``: the bundled rig (AGMA): every effect alone and every pair, each with the declared
      values as they are and off both ways; clean data; the out-of-vocabulary effects (those of the
      first matrix with each perturbation, the others with one).
    * ``catalogue``: the bundled rig with mu and K_t copied high from a catalogue (with sources), or
      every drag declared 0: clean data, the effects a mu or drag error could pass for, OOV.
    * ``constant``: the bundled rig under the constant friction model: clean data with every
      perturbation, every effect alone and every pair with the perturbations in turn, OOV.
    * ``nmrv040``: the variant rig (constant mu, ratio 20, one load motor): clean data with every
      perturbation, every effect of its table alone, a few pairs, OOV.
    * ``nmrv040_agma``: the variant under the AGMA curve: clean data, a few effects, OOV.
    * ``stribeck``: the bundled rig under a Stribeck mu law (its low-speed rise, FRICTION_LEAVES): clean data
      with the declared values off, a few effects, OOV.
    * ``no_drag``: plants with no drag at all, declared as the file has it or as 0 (a fit that trades the
      drags against the rest goes negative there).
    """
    perts = list(PERTURBATIONS)
    off = ["high", "low", "catalogue", "zero_drags"]
    old_oov = ("stepped_gear_friction", "gear_order3_ripple")
    new_oov = tuple(x for x in OUT_OF_VOCABULARY if x not in old_oov)
    out: dict[str, list[Case]] = {}

    first = []
    for pert in ("nominal", "high", "low"):
        first.append(case_of([], pert, seed=11))
        first += [case_of([n], pert) for n in ALONE]
        first += [case_of(list(p), pert, seed=2) for p in PAIRS]
        first += [case_of([], pert, seed=3, extra=[x]) for x in old_oov]
    first += [case_of([], _cycle(("nominal", "high", "low"), k), seed=4, extra=[x]) for k, x in enumerate(new_oov)]
    out["nmrv030"] = first

    catalogue = [case_of([], "catalogue", seed=11), case_of([], "zero_drags", seed=12)]
    catalogue += [case_of([n], _cycle(("catalogue", "zero_drags"), k))
                  for k, n in enumerate(("load_dependent_mu", "speed_dependent_mu", "sensor_gain", "sensor_offset",
                                         "bearing_coulomb", "viscous_drag"))]
    catalogue += [case_of([], _cycle(("catalogue", "zero_drags"), k), seed=5, extra=[x])
                  for k, x in enumerate(OUT_OF_VOCABULARY)]
    out["catalogue"] = catalogue

    rig = "nmrv030_constant"
    constant = [case_of([], pert, seed=11 + k, rig=rig) for k, pert in enumerate(perts)]
    constant += [case_of([n], _cycle(off, k), rig=rig) for k, n in enumerate(ALONE)]
    constant += [case_of(list(p), _cycle(off, k + 1), seed=2, rig=rig) for k, p in enumerate(PAIRS)]
    constant += [case_of([], _cycle(off, k), seed=3, extra=[x], rig=rig) for k, x in enumerate(OUT_OF_VOCABULARY)]
    out["constant"] = constant

    rig = "nmrv040"
    variant = [case_of([], pert, seed=21 + k, rig=rig) for k, pert in enumerate(perts)]
    variant += [case_of([n], _cycle(off, k), rig=rig) for k, n in enumerate(SIZES["nmrv040_rig.yaml"])]
    variant += [case_of(list(p), _cycle(off, k + 2), seed=2, rig=rig)
                for k, p in enumerate((("motor_cogging", "bearing_coulomb"), ("gear_runout", "load_dependent_mu"),
                                       ("inertia_error", "sensor_offset")))]
    variant += [case_of([], _cycle(off, k), seed=3, extra=[x], rig=rig) for k, x in enumerate(OUT_OF_VOCABULARY)]
    out["nmrv040"] = variant

    rig = "nmrv040_agma"
    agma = [case_of([], pert, seed=31 + k, rig=rig) for k, pert in enumerate(("nominal", "high", "catalogue"))]
    agma += [case_of([n], _cycle(off, k), rig=rig)
             for k, n in enumerate(("load_dependent_mu", "speed_dependent_mu", "gear_runout", "sensor_gain"))]
    agma += [case_of([], _cycle(off, k), seed=3, extra=[x], rig=rig)
             for k, x in enumerate(("load_bearing_friction", "current_drift"))]
    out["nmrv040_agma"] = agma

    rig = "nmrv030_stribeck"
    stribeck = [case_of([], pert, seed=51 + k, rig=rig) for k, pert in enumerate(("nominal", "high", "catalogue",
                                                                                  "zero_drags"))]
    stribeck += [case_of([n], _cycle(off, k), rig=rig)
                 for k, n in enumerate(("load_dependent_mu", "sensor_gain", "gear_runout", "viscous_drag"))]
    stribeck += [case_of([], _cycle(off, k), seed=3, extra=[x], rig=rig)
                 for k, x in enumerate(("stepped_gear_friction", "current_drift"))]
    out["stribeck"] = stribeck

    no_drag = {"drags": 0.0}
    out["no_drag"] = [case_of([], pert, seed=41 + k, rig=rig, plant=no_drag)
                      for k, (rig, pert) in enumerate((("nmrv030", "nominal"), ("nmrv030", "zero_drags"),
                                                       ("nmrv030_constant", "zero_drags"),
                                                       ("nmrv030_constant", "catalogue"),
                                                       ("nmrv040", "zero_drags"), ("nmrv040", "nominal")))]
    return out


def full_matrix() -> list[Case]:
    """Every family of :func:`families`, in that order."""
    return [case for cases in families().values() for case in cases]


#: the small subset's cases, by name (each one of :func:`full_matrix`'s)
SMALL = (
    "clean/high", "clean/low", "bearing_coulomb/low", "sensor_gain/high", "inertia_error/low", "gear_runout/high",
    "load_dependent_mu/low", "oil_temperature/high", "sensor_offset/high", "motor_cogging+bearing_coulomb/high",
    "worm_runout+viscous_drag/low", "backlash+gear_runout/nominal", "gear_order3_ripple/high",
    "stepped_gear_friction/low",
    "nmrv030_constant:clean/catalogue", "nmrv030_constant:clean/zero_drags",
    "nmrv030_constant:load_dependent_mu/zero_drags", "nmrv030_constant:load_bearing_friction/catalogue",
    "nmrv040:clean/high", "nmrv040:sensor_offset/low", "nmrv040:current_drift/zero_drags",
    "clean/zero_drags,plant drags x0", "nmrv030_stribeck:clean/high",
)


def small_matrix() -> list[Case]:
    """A representative subset (``evaluate --residual-cases small``, about two minutes; :data:`SMALL`): clean data
    with the declared values off, every alias kind and a periodic, a mu and a sensor effect with them off, two pairs,
    out-of-vocabulary effects; the constant friction model with mu and K_t off (with sources) and with the drags
    declared 0; the variant rig; a plant without drag; the Stribeck mu law with mu off."""
    by_name = {c.name: c for c in full_matrix()}
    return [by_name[name] for name in SMALL]


def confusion(results: Sequence[CaseResult]) -> dict[str, dict[str, int]]:
    """true effect -> {column: count of cases}: the column of the effect itself when it was found, "missed"
    when not, and every false name found with it; a case without vocabulary effects has the row "none" (or
    its out-of-vocabulary effect) and the column "none" when nothing was named."""
    table: dict[str, dict[str, int]] = {}

    def count(row: str, column: str) -> None:
        table.setdefault(row, {})[column] = table.get(row, {}).get(column, 0) + 1

    for r in results:
        if r.truth:
            for t in r.truth:
                count(t, t if t in r.found else "missed")
                for f in r.false_names:
                    count(t, f)
        else:
            for f in r.false_names or ("none",):
                count("+".join(r.case.extra) or "none", f)
    return table


def summary_line(results: Sequence[CaseResult]) -> str:
    """``residuals: cases= exact= false_names= missed= at_floor= unexplained_oov= unphysical= passed=``."""
    oov = [r for r in results if r.case.extra]
    in_vocab = [r for r in results if not r.case.extra]
    return (f"residuals: cases={len(results)} exact={sum(r.exact for r in results)} "
            f"false_names={sum(len(r.false_names) for r in results)} missed={sum(len(r.missed) for r in results)} "
            f"at_floor={sum(r.within_floor for r in in_vocab)}/{len(in_vocab)} "
            f"unexplained_oov={sum(r.unexplained is not None for r in oov)}/{len(oov)} "
            f"unphysical={sum(bool(r.unphysical) for r in results)} "
            f"passed={sum(r.passed for r in results)}")


def format_results(results: Sequence[CaseResult]) -> list[str]:
    """One line per case (with the mu correction: identified / the simulated rig's), then the confusion table."""
    lines = ["  case                                                    found                          before   "
             "after    floor   after/floor  unexplained  mu/true"]
    for r in results:
        found = ",".join(r.found) or "none"
        unexpl = f"{r.unexplained:.4f}" if r.unexplained is not None else "-"
        mark = "" if r.passed else "  <- FAIL" + (f" (negative {', '.join(r.unphysical)})" if r.unphysical else "")
        lines.append(f"  {r.case.name:<55} {found:<30} {r.rms_before:.4f}  {r.rms_after:.4f}  {r.floor:.4f}  "
                     f"{r.rms_after / r.floor:5.2f}        {unexpl:<11}  {r.mu_ratio:5.3f}{mark}")
    lines += confusion_lines(results)
    return lines


def confusion_lines(results: Sequence[CaseResult], title: str = "") -> list[str]:
    """The confusion table (true rows, found columns) of ``results``."""
    table = confusion(results)
    columns = sorted({c for row in table.values() for c in row}, key=lambda c: (c in ("missed", "none"), c))
    width = max(len(t) for t in table) + 2
    lines = [f"  confusion{title} (rows: true effect, columns: effects found; counts of cases)",
             "  " + " " * width + " ".join(f"{c[:8]:>8}" for c in columns)]
    for t in sorted(table, key=lambda x: (x == "none", x)):
        lines.append("  " + f"{t:<{width}}" + " ".join(f"{table[t].get(c, 0) or '.':>8}" for c in columns))
    return lines


def family_lines(results: Sequence[CaseResult]) -> list[str]:
    """One summary line per family of :func:`families` that ``results`` covers."""
    by_name = {r.case.name: r for r in results}
    lines = []
    for family, cases in families().items():
        mine = [by_name[c.name] for c in cases if c.name in by_name]
        if mine:
            lines.append(f"  {family:<13} " + summary_line(mine).removeprefix("residuals: "))
    return lines


def evaluate_lines(cases: Sequence[Case] | None = None, progress: Callable[[int], None] | None = None) -> list[str]:
    """What ``make evaluate`` prints: a heading, one line per case, the confusion table, a line per family,
    and last the :func:`summary_line` (default: :func:`small_matrix`)."""
    cases = small_matrix() if cases is None else list(cases)
    start = time.monotonic()
    results = run_matrix(cases, progress=(lambda k, _r: progress(k)) if progress else None)
    return ([f"\nresiduals on the simulated rigs: {len(cases)} cases (true effects vs effects_found; rig files "
             f"{', '.join(sorted({c.rig for c in cases}))}; declared values off by mu +-30 %, K_t +-5 %, drags x2, "
             f"inertia +-20 %, oil reference +-15 K, or mu +25 % and K_t +3 % with sources, or drags declared 0), "
             f"{time.monotonic() - start:.0f} s"] + format_results(results) + ["  by family:"]
            + family_lines(results) + [summary_line(results)])


def main(argv: list[str] | None = None) -> int:
    """Run the matrix, a family of it, or the small subset, and print what ``make evaluate`` prints."""
    names = list(families())
    p = argparse.ArgumentParser(prog="python -m torque_estimator.evaluation.residual_cases",
                                description="The residual tool's case matrix on the simulated rigs: each case "
                                            "simulates a data set, gives `residuals` a rig file with its numbers off, "
                                            "and scores the names it finds against the true ones.")
    p.add_argument("--cases", choices=("full", "small"), default="small",
                   help="the full matrix (every family) or the small subset (default)")
    p.add_argument("--family", choices=names, action="append", default=None,
                   help="run only this family of the full matrix (repeatable); overrides --cases")
    p.add_argument("--match", default=None, help="run only the cases whose name contains this text")
    args = p.parse_args(argv)
    if args.family:
        groups = families()
        cases = [c for f in args.family for c in groups[f]]
    else:
        cases = full_matrix() if args.cases == "full" else small_matrix()
    if args.match:
        cases = [c for c in cases if args.match in c.name]
    print("\n".join(evaluate_lines(cases, progress=lambda k: print(f"  [{k}/{len(cases)}]", end="\r",
                                                                   flush=True))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
