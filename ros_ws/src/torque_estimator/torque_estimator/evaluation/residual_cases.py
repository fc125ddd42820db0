"""The case matrix of issue 15: `residuals` on the project's simulator, true effects against found ones.

Each case simulates a few seconds of n rigs side by side (worm_rig_driver's SimulatedRig,
its effect plug-ins switched on, the model not told) and gives the analysis a rig file
whose declared numbers may be off by realistic amounts (:data:`PERTURBATIONS`: mu +-30 %,
K_t +-5 %, drags x2 / x0.5, inertias +-20 %, the oil reference temperature +-15 K; the
simulated rig itself stays the bundled one).  A case passes when ``effects_found`` is
exactly its true set (parameter corrections are not effects), the held-out RMS after is
within ``Settings.unexplained_factor`` (1.3) of the noise floor estimated from the data,
and, for an effect outside the vocabulary (:data:`OUT_OF_VOCABULARY`), when nothing is
named and ``unexplained=`` is reported.

Effect sizes: each is large enough to move the held-out RMS by more than the 2 % the
selection asks for at this rig's 0.0215 A current noise.  Effects that are the same
function of the data as a refitted parameter (sensor_gain ~ K_t, bearing_coulomb ~ the
Coulomb drags, viscous_drag ~ the viscous drag, inertia_error ~ the rotor inertia,
free.TOLERANCES) can only be told from a wrong declared value by size, so their cases
lie beyond the tolerance band *including* a declared value off by the amounts above
(e.g. bearing drag 30 mN m on the worm: 34 mN m against a declared 8 mN m is x4.25 > x2.5).

It lives here, with the experiments, because it needs both the residual analysis
(worm_model) and the simulator (worm_rig_driver).

:func:`run_matrix` runs a list of cases; :func:`full_matrix` is what ``make evaluate``
prints (last line: :func:`summary_line`; ``--residual-cases small``: :func:`small_matrix`, a subset).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from worm_model.physics.parameters import Rig, load_rig
from worm_model.rig_data.schema import MeasuredData

import worm_model.residuals.analysis as an
from worm_model.residuals.free import get_value, set_values
from worm_model.residuals.model import prepare_signals

#: excitation profiles: drive voltage offsets [V], load offset and swing [N m] (as tests/test_residuals_sim.py);
#: "square": the load steps through zero; "reverse": every third rig reverses its drive smoothly with almost no load
PROFILES: dict[str, dict[str, Any]] = {
    "standard": {"volts": (1.5, 20.0), "load": (-0.12, 0.2), "swing": (0.02, 0.15)},
    "low_speed": {"volts": (1.0, 4.0), "load": (0.1, 0.3), "swing": (0.02, 0.08)},
    "wide_load": {"volts": (3.0, 20.0), "load": (-0.05, 0.3), "swing": (0.1, 0.2)},
    "high_load": {"volts": (4.0, 20.0), "load": (0.1, 0.3), "swing": (0.02, 0.08)},
    "slow_high_load": {"volts": (2.0, 10.0), "load": (0.12, 0.3), "swing": (0.02, 0.08)},
    "slow_full_load": {"volts": (1.0, 3.0), "load": (0.2, 0.24), "swing": (0.02, 0.03)},
    "flank": {"volts": (3.0, 16.0), "load": (-0.03, 0.05), "swing": (0.08, 0.2), "square": True, "reverse": True},
}

#: oil sump sensor: resolution [K] and noise [K] (the climate-chamber case of tests/test_residuals_sim.py)
OIL_SENSOR = (0.25, 0.2)

#: declared-value errors: factor on the rig file's value (the simulated rig keeps the bundled values);
#: "reference_temperature" is an offset [K] of the oil temperature at which the tool assumes the declared mu
PERTURBATIONS: dict[str, dict[str, float]] = {
    "nominal": {},
    "high": {"friction.scale": 1.3, "torque_constant": 1.05, "drags": 2.0, "inertia": 1.2,
             "reference_temperature": 15.0},
    "low": {"friction.scale": 0.7, "torque_constant": 0.95, "drags": 0.5, "inertia": 0.8,
            "reference_temperature": -15.0},
}

_DRAGS = ("drive_motor.coulomb_drag", "drive_motor.viscous_drag", "load_motor.coulomb_drag", "load_motor.viscous_drag")
_INERTIAS = ("drive_motor.rotor_inertia", "gearbox.worm_inertia", "gearbox.gear_inertia")


def declared_rig(rig: Rig, perturbation: Mapping[str, float]) -> Rig:
    """The rig file a user would write: ``rig`` with its declared numbers off by ``perturbation``."""
    names: list[str] = []
    factors: list[float] = []
    for key, factor in perturbation.items():
        if key == "friction.scale":
            names.append(key)
            factors.append(factor)
        elif key == "torque_constant":  # K_e equals K_t in SI: a user who has one wrong has both
            names += ["drive_motor.torque_constant", "drive_motor.back_emf_constant"]
            factors += [factor, factor]
        elif key == "drags":
            names += list(_DRAGS)
            factors += [factor] * len(_DRAGS)
        elif key == "inertia":
            names += list(_INERTIAS)
            factors += [factor] * len(_INERTIAS)
    return set_values(rig, names, [get_value(rig, n) * f for n, f in zip(names, factors)])


@dataclass(frozen=True)
class Case:
    """One simulated data set and what the analysis should name.

    ``effects``: the simulator's ``effects:`` mapping; ``extra``: out-of-vocabulary effects
    (:data:`OUT_OF_VOCABULARY` keys) added to the simulator; ``truth``: the names a correct
    analysis gives (the vocabulary effects switched on).
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

    @property
    def truth(self) -> tuple[str, ...]:
        return tuple(sorted(self.effects))


# --------------------------------------------------------------------------- out-of-vocabulary effects
def _out_of_vocabulary() -> dict[str, Callable[[int, Rig], Any]]:
    """Simulator effects no vocabulary entry describes (factories: (n, rig) -> live effect)."""
    from worm_rig_driver.sim.effects import EffectBase  # noqa: PLC0415

    class SteppedGearFriction(EffectBase):
        """Gear-shaft friction that depends on the gear angle in steps: +drag over one half of each gear
        turn, -drag over the other (an eccentric seal face: tight, then loose, about the declared drag).
        Odd in the direction of rotation and zero on average, so neither a drag correction nor a ripple
        of the vocabulary (gear_runout does not flip with the direction) takes it."""

        name = "stepped_gear_friction"
        drag = 0.04  # [N m]

        def gear_torque(self, s):
            return self.drag * np.sign(s.omega_gear) * np.sign(np.sin(s.theta_gear))

    class GearOrder3Ripple(EffectBase):
        """A torque ripple three times per gear turn on the gear shaft (a three-jaw coupling): no vocabulary
        effect has that order (gear_runout is once per gear turn, tooth_pass Z_g per gear turn)."""

        name = "gear_order3_ripple"
        amplitude = 0.05  # [N m]

        def gear_torque(self, s):
            return self.amplitude * np.sin(3.0 * s.theta_gear + 0.4)

    return {"stepped_gear_friction": lambda n, rig: SteppedGearFriction({}, n, rig),
            "gear_order3_ripple": lambda n, rig: GearOrder3Ripple({}, n, rig)}


OUT_OF_VOCABULARY = ("stepped_gear_friction", "gear_order3_ripple")


# --------------------------------------------------------------------------- simulation
def simulate(case: Case, rig: Rig | None = None) -> MeasuredData:
    """``case.runs`` runs of ``case.seconds`` (1 s gaps in t), sampled at the rig's rate, open-loop voltage.

    The drive voltage is a slow sinusoid around a per-rig offset (both signs), the load a slow
    sinusoid or square wave of both signs; see :data:`PROFILES`.  With ``oil_start`` the rigs
    start at those oil temperatures and a sump sensor fills the ``temperature`` column.
    """
    from worm_rig_driver.sim.effects import EffectStack  # noqa: PLC0415
    from worm_rig_driver.sim.simulated_rig import SimulatedRig  # noqa: PLC0415

    rig = rig or load_rig()
    p, n, seed = PROFILES[case.profile], case.runs, case.seed
    rng = np.random.default_rng(seed)
    sim = SimulatedRig(rig, n=n, seed=seed, effects={k: dict(v) for k, v in case.effects.items()}, scalar=False)
    if case.extra:  # switched on behind the registry's back: the point is that nothing knows them
        factories = _out_of_vocabulary()
        stack = EffectStack(list(sim.plant.fx.effects) + [factories[k](n, rig) for k in case.extra])
        sim.plant.fx = stack
        sim.plant._has_effects = True
    if case.oil_start:
        oil = next(e for e in sim.plant.fx.effects if e.name == "oil_temperature")
        oil.temperature = np.resize(np.asarray(case.oil_start, dtype=float), n)
    steps = int(round(case.seconds * rig.sensors.sample_rate_hz))
    dt = 1.0 / rig.sensors.sample_rate_hz
    v0 = rng.permutation(np.linspace(*p["volts"], n)) * np.where(np.arange(n) % 2, 1.0, -1.0)
    v1, f1 = rng.uniform(0.1, 0.3, n) * np.abs(v0), rng.uniform(0.5, 3.0, n)
    l0, l1, f2 = rng.uniform(*p["load"], n), rng.uniform(*p["swing"], n), rng.uniform(0.2, 1.0, n)
    reverse = (np.arange(n) % 3 == 1) if p.get("reverse") else np.zeros(n, dtype=bool)
    if p.get("square"):
        v1, f2 = np.zeros(n), rng.uniform(0.7, 1.5, n)
    l0, l1 = np.where(reverse, rng.uniform(-0.005, 0.005, n), l0), np.where(reverse, 0.0, l1)
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
    def passed(self) -> bool:
        """Exact names; at the floor, or (an effect outside the vocabulary) ``unexplained=`` reported."""
        if self.case.extra:
            return self.exact and self.unexplained is not None
        return self.exact and self.within_floor and self.unexplained is None


def run_case(case: Case, rig: Rig | None = None) -> CaseResult:
    """Simulate the case on ``rig`` (default: the bundled one) and analyse it with the perturbed rig file."""
    start = time.monotonic()
    rig = rig or load_rig()
    data = simulate(case, rig)
    pert = PERTURBATIONS[case.perturbation]
    declared = declared_rig(rig, pert)
    settings = an.Settings(reference_temperature=an.Settings().reference_temperature
                           + pert.get("reference_temperature", 0.0))
    signals = prepare_signals(declared, data, settings.alpha_time_constant, settings.reference_temperature)
    problem = an.Problem(declared, [], signals, data.current_drive, an.make_split(signals, settings), settings)
    result = an.analyse(problem)
    return CaseResult(case, tuple(sorted(result.found)), result.rms_before, result.final.rms_held_out,
                      result.noise.rms, None if result.unexplained is None else result.unexplained.rms,
                      {p: v / get_value(declared, p) for p, v in result.final.free_values.items()},
                      time.monotonic() - start)


def run_matrix(cases: Sequence[Case], rig: Rig | None = None,
               progress: Callable[[int, CaseResult], None] | None = None) -> list[CaseResult]:
    out = []
    for k, case in enumerate(cases):
        out.append(run_case(case, rig))
        if progress:
            progress(k + 1, out[-1])
    return out


# --------------------------------------------------------------------------- the matrices
#: one case per vocabulary effect, sized as argued in the module docstring (profile, simulator parameters)
ALONE: dict[str, tuple[str, dict[str, float]]] = {
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
    # the PWM ripple's sampling bias at the simulator's default 2 kHz sensor filter peaks at 7 mA: ranked first but
    # within 1.1 x the floor (not named, by design); a 10 kHz filter (amplitude 0.36 A, bias up to 33 mA) is named
    "pwm": ("standard", {"filter_cutoff": 10000.0}),
}

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


def case_of(names: Sequence[str], perturbation: str = "nominal", seed: int = 1, extra: Sequence[str] = ()) -> Case:
    """A case with the named vocabulary effects at their :data:`ALONE` sizes (and OOV ``extra``)."""
    effects = {n: ALONE[n][1] for n in names}
    profiles = [ALONE[n][0] for n in names] or ["standard"]
    profile = min(profiles, key=_PROFILE_RANK.index)
    oil = "oil_temperature" in names
    label = "+".join(list(names) + list(extra)) or "clean"
    return Case(f"{label}/{perturbation}", effects, profile, perturbation, tuple(extra),
                _OIL_START if oil else (), runs=12 if oil else 10, seed=seed)


def full_matrix() -> list[Case]:
    """Every effect alone and every pair, each with the declared values as they are and off both ways;
    clean data; the out-of-vocabulary effects."""
    cases = []
    for pert in PERTURBATIONS:
        cases.append(case_of([], pert, seed=11))
        cases += [case_of([n], pert) for n in ALONE]
        cases += [case_of(list(p), pert, seed=2) for p in PAIRS]
        cases += [case_of([], pert, seed=3, extra=[x]) for x in OUT_OF_VOCABULARY]
    return cases


def small_matrix() -> list[Case]:
    """A representative subset (about a minute; ``evaluate --residual-cases small``): clean data with the declared values
    off, every alias kind and a periodic, a mu and a sensor effect with them off, two pairs, both
    out-of-vocabulary effects."""
    return [
        case_of([], "high", seed=11), case_of([], "low", seed=12),
        case_of(["bearing_coulomb"], "low"), case_of(["sensor_gain"], "high"),
        case_of(["inertia_error"], "low"), case_of(["gear_runout"], "high"),
        case_of(["load_dependent_mu"], "low"), case_of(["oil_temperature"], "high"),
        case_of(["sensor_offset"], "high"),
        case_of(["motor_cogging", "bearing_coulomb"], "high", seed=2),
        case_of(["worm_runout", "viscous_drag"], "low", seed=2),
        case_of(["backlash", "gear_runout"], "nominal", seed=2),
        case_of([], "high", seed=3, extra=["gear_order3_ripple"]),
        case_of([], "low", seed=3, extra=["stepped_gear_friction"]),
    ]


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
    """``residuals: cases= exact= false_names= missed= at_floor= unexplained_oov= passed=``."""
    oov = [r for r in results if r.case.extra]
    in_vocab = [r for r in results if not r.case.extra]
    return (f"residuals: cases={len(results)} exact={sum(r.exact for r in results)} "
            f"false_names={sum(len(r.false_names) for r in results)} missed={sum(len(r.missed) for r in results)} "
            f"at_floor={sum(r.within_floor for r in in_vocab)}/{len(in_vocab)} "
            f"unexplained_oov={sum(r.unexplained is not None for r in oov)}/{len(oov)} "
            f"passed={sum(r.passed for r in results)}")


def format_results(results: Sequence[CaseResult]) -> list[str]:
    """One line per case, then the confusion table (true rows, found columns)."""
    lines = ["  case                                         found                          before   after    "
             "floor   after/floor  unexplained"]
    for r in results:
        found = ",".join(r.found) or "none"
        unexpl = f"{r.unexplained:.4f}" if r.unexplained is not None else "-"
        mark = "" if r.passed else "  <- FAIL"
        lines.append(f"  {r.case.name:<44} {found:<30} {r.rms_before:.4f}  {r.rms_after:.4f}  {r.floor:.4f}  "
                     f"{r.rms_after / r.floor:5.2f}        {unexpl}{mark}")
    table = confusion(results)
    columns = sorted({c for row in table.values() for c in row}, key=lambda c: (c in ("missed", "none"), c))
    width = max(len(t) for t in table) + 2
    lines.append("  confusion (rows: true effect, columns: effects found; counts of cases)")
    lines.append("  " + " " * width + " ".join(f"{c[:8]:>8}" for c in columns))
    for t in sorted(table, key=lambda x: (x == "none", x)):
        lines.append("  " + f"{t:<{width}}" + " ".join(f"{table[t].get(c, 0) or '.':>8}" for c in columns))
    return lines


def evaluate_lines(cases: Sequence[Case] | None = None, progress: Callable[[int], None] | None = None) -> list[str]:
    """What ``make evaluate`` prints: a heading, one line per case, the confusion table, and last the
    :func:`summary_line` (default: :func:`small_matrix`)."""
    cases = small_matrix() if cases is None else list(cases)
    start = time.monotonic()
    results = run_matrix(cases, progress=(lambda k, _r: progress(k)) if progress else None)
    return ([f"\nresiduals on the simulated rig: {len(cases)} cases (true effects vs effects_found; declared values "
             f"off by mu +-30 %, K_t +-5 %, drags x2, inertia +-20 %, oil reference +-15 K), "
             f"{time.monotonic() - start:.0f} s"] + format_results(results) + [summary_line(results)])
