"""How well the health check watches a gearbox: detection and false alarms on simulated lives (``make evaluate``).

Simulated gearboxes of the paper's rig, with the effects a real one has and the model lacks
(:data:`GEARBOX_EFFECTS`: drags, mu's Stribeck rise and load dependence, ripples, backlash, sensor
gain and offset) and an oil whose temperature scales mu by -0.4 %/K (not the monitor's prior). Each
gearbox's life is a sequence of checks: ``baseline`` checks, then healthy checks, then (for the
detection study) checks after a change of mu's scale (the ``wear`` effect). Every check starts at
its own oil temperature, load scale, noise and gear angle, drawn from the seed:

* oil temperature: the hall's ambient (25 degC, sd 2 K, unknown to the monitor) plus the heating
  of the work before the check: power P ~ U(0, WORK_HEAT) W for t ~ U(0, 3 tau), through the gearbox's
  own R_th and tau (the declared 5 K/W and 900 s, each x U(0.8, 1.2) per gearbox): 23-60 degC, a
  +-15 K swing around 40;
* the reported temperature: measured (the true mean of the run + a 0.5 K sensor error) or
  estimated (worm_model.health.thermal from the assumed ambient and the work's heat, misjudged by
  a factor 1 + N(0, 0.15) per gearbox: the heat model's error);
* load scale U(0.8, 1.0): the check's loads as the rig makes them today.

Every check of every gearbox runs side by side in one vectorised simulation (health.simulated);
each is fitted and assessed in order against its gearbox's baseline and trend
(worm_model.health.assess), as ``health_check`` does. No ROS.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from worm_model.health.assess import Z95, assess_trend, baseline_of
from worm_model.health.bound import detection_probability, one_check_sigma
from worm_model.health.blocks import Blocks
from worm_model.health.fit import Temperature, fit_points
from worm_model.errors import FitError
from worm_model.health.model import HealthParameters
from worm_model.health.points import steady_points
from worm_model.health.record import CheckRecord
from worm_model.health.settings import HealthSettings, Limits
from worm_model.health.thermal import ThermalEstimate
from worm_model.physics.parameters import Rig

from torque_estimator.health.simulated import simulate_checks

#: the simulated gearbox's effects (the model lacks them); wear's rates other than mu's are 0 here, so a
#: change is mu's alone
TRUE_MU_PER_KELVIN = -0.004
GEARBOX_EFFECTS = {
    "bearing_coulomb": {}, "viscous_drag": {}, "speed_dependent_mu": {}, "load_dependent_mu": {},
    "oil_temperature": {"mu_per_kelvin": TRUE_MU_PER_KELVIN}, "worm_runout": {}, "tooth_pass": {},
    "gear_runout": {}, "motor_cogging": {}, "backlash": {}, "sensor_gain": {}, "sensor_offset": {},
    "wear": {"mu_rate": 0.1, "worm_drag_rate": 0.0, "gear_drag_rate": 0.0, "backlash_rate": 0.0},
}
#: [W] the most heat the work before a check makes: up to 36 K of rise through the declared 5 K/W (~15 W in at
#: ~50 % efficiency, a quarter of the bundled drive motor's ~60 W rating)
WORK_HEAT = 7.2
#: hours of the wear effect per unit rise of mu (mu_rate 0.1 per 1000 h)
HOURS_PER_RISE = 1000.0 / 0.1
MODES = ("measured", "estimated")


@dataclass
class Life:
    """One simulated gearbox: its checks' true conditions, in order."""

    temperature: np.ndarray  # [degC] true oil temperature at each check's start
    power: np.ndarray  # [W] heat of the work before each check
    duration: np.ndarray  # [s] of that work
    load_scale: np.ndarray
    rise: np.ndarray  # true relative rise of mu at each check
    heat_error: float  # the thermal estimate's misjudgement of the heat (factor - 1)
    records: dict[str, list[CheckRecord]] = field(default_factory=dict)  # mode -> fitted checks

    @property
    def first_changed(self) -> int:
        """Index of the first check after the change (0: mu never rises)."""
        return int(np.argmax(self.rise > 0))


def draw_lives(gearboxes: int, checks: int, seed: int, rises: np.ndarray | None = None,
               settings: HealthSettings = HealthSettings()) -> list[Life]:
    """``gearboxes`` lives of ``checks`` checks each (module docstring); ``rises``: mu's rise per check (default 0)."""
    rng = np.random.default_rng([seed, 2029])
    nominal = settings.thermal
    lives = []
    for _ in range(gearboxes):
        r_th = nominal.thermal_resistance * rng.uniform(0.8, 1.2)
        tau = nominal.time_constant * rng.uniform(0.8, 1.2)
        power = rng.uniform(0.0, WORK_HEAT, checks)
        duration = rng.uniform(0.0, 3.0 * tau, checks)
        ambient = nominal.ambient + rng.normal(0.0, 2.0, checks)
        temperature = ambient + r_th * power * (1.0 - np.exp(-duration / tau))
        lives.append(Life(temperature, power, duration, rng.uniform(0.8, 1.0, checks),
                          np.zeros(checks) if rises is None else np.asarray(rises, dtype=float),
                          float(rng.normal(0.0, 0.15))))
    return lives


def run_lives(rig: Rig, lives: list[Life], seed: int, settings: HealthSettings = HealthSettings(),
              progress: Callable[[int, int], None] | None = None) -> None:
    """Simulate and fit every check of every life (side by side); fills each life's ``records`` per mode."""
    temps = np.concatenate([life.temperature for life in lives])
    scales = np.concatenate([life.load_scale for life in lives])
    hours = np.concatenate([life.rise for life in lives]) * HOURS_PER_RISE
    blocks = simulate_checks(rig, len(temps), effects=GEARBOX_EFFECTS, seed=seed, temperature=temps,
                             hours=hours, load_scale=scales, progress=progress)
    rng = np.random.default_rng([seed, 4242])
    reference = HealthParameters.from_rig(rig)
    k = 0
    for life in lives:
        life.records = {mode: [] for mode in MODES}
        for j in range(len(life.temperature)):
            measured_oil = _run_temperature(blocks, k)
            points = steady_points(blocks.rig(k), rig, settings.points)
            try:
                fit = fit_points(points, rig, reference, settings.priors)
            except FitError:
                k += 1
                continue
            sensor = Temperature(measured_oil + rng.normal(0.0, settings.temperature.sensor_sigma),
                                 settings.temperature.sensor_sigma, "measured")
            estimate = ThermalEstimate.start(settings.thermal)
            estimate.settle(life.power[j] * (1.0 + life.heat_error), life.duration[j])
            guessed = Temperature(estimate.temperature, estimate.sigma, "estimated")
            cache: dict = {}  # the two records share their points, so their refits (assess.watched_fit)
            for mode, temperature in (("measured", sensor), ("estimated", guessed)):
                record = CheckRecord.from_fit(fit, temperature, f"check {j}", None, "simulator", points)
                record.cache = cache
                life.records[mode].append(record)
            k += 1


def _run_temperature(blocks: Blocks, k: int) -> float:
    return float(np.nanmean(blocks.temperature[:, k]))


def levels(life: Life, mode: str, rig: Rig, settings: HealthSettings) -> list[str]:
    """The level each check after the baseline raised, in order (as health_check assesses them)."""
    records = life.records[mode]
    return [a.level for a in assess_trend(records, settings, rig) if a is not None]


def first_check_bound(life: Life, mode: str, rig: Rig, settings: HealthSettings) -> float:
    """The least standard uncertainty any monitor could judge the first check after the change with
    (worm_model.health.bound's sigma_B, at the true temperature law; NaN: no changed check)."""
    first_changed = life.first_changed
    records = life.records[mode]
    if not first_changed or first_changed >= len(records):
        return math.nan
    earlier = records[:first_changed]
    baseline = baseline_of(earlier, settings, rig)
    return one_check_sigma(records[first_changed], earlier, baseline, TRUE_MU_PER_KELVIN, settings, rig)


def detection_checks(life: Life, mode: str, rig: Rig, settings: HealthSettings) -> int | None:
    """Checks after the change until the first WARN or ERROR (1 = the first check after it); None: never."""
    first_changed = life.first_changed
    result = levels(life, mode, rig, settings)
    n = settings.limits.baseline_checks
    for i, level in enumerate(result):
        if n + i >= first_changed and level != "OK":
            return n + i - first_changed + 1
    return None


@dataclass
class StudyResult:
    """What ``make evaluate`` prints (:meth:`lines`)."""

    detected: dict[tuple[float, str], list[int | None]]  # (rise, mode) -> checks to detection per gearbox
    false_alarms: dict[str, tuple[int, int]]  # mode -> (alarms, healthy checks assessed)
    sigma: dict[str, float] = field(default_factory=dict)  # mode -> median sigma of a healthy check's mu change
    #: (rise, mode) -> per gearbox, the least sigma any monitor could judge its first changed check with
    bound: dict[tuple[float, str], list[float]] = field(default_factory=dict)
    limits: Limits = field(default_factory=Limits)  # the alarm limits the checks were judged with
    example: list[CheckRecord] | None = None  # a gearbox with the largest rise, oil measured (for the plot)
    example_rise: float = 0.0
    example_first: int = 0  # index of its first changed check

    def lines(self) -> list[str]:
        out = []
        for (rise, mode), found in self.detected.items():
            missed = sum(1 for n in found if n is None)
            worst = max((n for n in found if n is not None), default=0)
            median = float(np.median([n if n is not None else math.inf for n in found]))
            out.append(f"health: change=mu+{rise:.0%} detected_in_checks={worst if not missed else 'never'} "
                       f"median={median:g} missed={missed} of {len(found)} temperature={mode}")
            if (rise, mode) in self.bound:
                sigmas = self.bound[rise, mode]
                chance = sum(detection_probability(rise, s, self.limits) for s in sigmas)
                out.append(f"health: change=mu+{rise:.0%} in_first_check={sum(n == 1 for n in found)} of {len(found)} "
                           f"bound={chance:.1f} worst_bound_sigma_pct={100 * max(sigmas):.2f} temperature={mode}")
        for mode, (alarms, total) in self.false_alarms.items():
            out.append(f"health: false_alarms={alarms} of {total} temperature={mode}")
        if self.sigma:
            cost = self.sigma.get("estimated", math.nan) / self.sigma.get("measured", math.nan)
            out.append(f"health: sigma_mu_change_pct measured={100 * self.sigma.get('measured', math.nan):.2f} "
                       f"estimated={100 * self.sigma.get('estimated', math.nan):.2f} cost_without_sensor={cost:.2f}x")
        return out


def run_study(rig: Rig, *, gearboxes: int = 50, baseline: int = 5, healthy: int = 20, detect_gearboxes: int = 20,
              before: int = 4, after: dict[float, int] | None = None, seed: int = 0,
              settings: HealthSettings = HealthSettings(),
              progress: Callable[[int, int], None] | None = None) -> StudyResult:
    """False alarms over ``gearboxes`` x ``healthy`` checks after their baselines; detection of each rise
    in ``after`` (rise -> checks simulated after it) on ``detect_gearboxes`` gearboxes, the change coming
    after ``before`` healthy checks."""
    after = {0.10: 3, 0.05: 8} if after is None else after
    settings = replace(settings, limits=replace(settings.limits, baseline_checks=baseline))
    healthy_lives = draw_lives(gearboxes, baseline + healthy, seed, settings=settings)
    changed: dict[float, list[Life]] = {}
    for j, (rise, count) in enumerate(after.items()):
        rises = np.concatenate([np.zeros(baseline + before), np.full(count, rise)])
        changed[rise] = draw_lives(detect_gearboxes, len(rises), seed + 1 + j, rises, settings)
    every = healthy_lives + [life for lives in changed.values() for life in lives]
    run_lives(rig, every, seed, settings, progress)
    false_alarms, sigma = {}, {}
    for mode in MODES:
        found = [assess_trend(life.records[mode], settings, rig) for life in healthy_lives]
        assessed = [a for f in found for a in f if a is not None]
        false_alarms[mode] = (sum(a.level != "OK" for a in assessed), len(assessed))
        sigma[mode] = float(np.median([a.mu_change.sigma for a in assessed])) if assessed else math.nan
    detected = {(rise, mode): [detection_checks(life, mode, rig, settings) for life in lives]
                for rise, lives in changed.items() for mode in MODES}
    # what one check can do is bounded (worm_model.health.bound); the rises one check is meant to find
    bound = {(rise, mode): [first_check_bound(life, mode, rig, settings) for life in lives]
             for rise, lives in changed.items() if rise > settings.limits.check_warn for mode in MODES}
    top = max(changed) if changed else None
    example = changed[top][0].records["measured"] if top is not None else None
    first = changed[top][0].first_changed if top is not None else 0
    return StudyResult(detected, false_alarms, sigma, bound, settings.limits, example, top or 0.0, first)


__all__ = ["GEARBOX_EFFECTS", "Life", "MODES", "StudyResult", "TRUE_MU_PER_KELVIN", "detection_checks",
           "draw_lives", "first_check_bound", "levels", "run_lives", "run_study"]


# --- live ------------------------------------------------------------------------------------------------

def operation(rig: Rig, duration: float, speeds=(120.0, 200.0, 280.0), loads=(0.6, -0.3, 0.9, 0.2),
              dwell: float = 5.0) -> tuple:
    """The paper's rig at work: speeds held in turn, the load motors stepping through ``loads`` (fractions of
    Rig.max_load_torque) every ``dwell`` s; a timeline of excitation.Ramp for ``duration`` s."""
    from torque_estimator.identification.excitation import Ramp

    out, t, k = [], 0.0, 0
    top = rig.max_load_torque
    while t < duration - 1e-9:
        speed = speeds[(k // len(loads)) % len(speeds)]
        load = loads[k % len(loads)] * top
        step = min(dwell, duration - t)
        out.append(Ramp(step, speed, speed, load, load, f"work {speed:g} rad/s, {load:+.3f} N m"))
        t += step
        k += 1
    return tuple(out)


@dataclass
class LiveTrace:
    """What the live monitor said, block by block."""

    time: np.ndarray  # [s]
    level: list[str]
    mu_change: np.ndarray
    mu_sigma: np.ndarray
    temperature: np.ndarray  # [degC] the monitor's oil temperature
    true_temperature: np.ndarray  # [degC]

    def first(self, level: str, after: float = 0.0) -> float:
        """Rig time [s] of the first block at ``level`` or above after ``after`` (NaN: never)."""
        order = {"OK": 0, "WARN": 1, "ERROR": 2}
        for t, lv in zip(self.time, self.level):
            if t > after and order[lv] >= order[level]:
                return float(t)
        return math.nan


def live_run(rig: Rig, reference, timeline, *, effects, seed: int = 0, settings: HealthSettings = HealthSettings(),
             thermal: HealthSettings | None = None,
             progress: Callable[[int, int], None] | None = None) -> dict[str, LiveTrace]:
    """The timeline on one simulated rig (scalar path, its own PI), every sample into two live monitors
    (worm_model.health.live.LiveHealth) side by side: "measured" is given the oil temperature with the samples,
    "estimated" is not (its thermal model, ``thermal``'s settings if given, estimates it from a cold start)."""
    from worm_model.health.live import LiveHealth
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiLoop
    from worm_rig_driver.sim.simulated_rig import SimulatedRig
    from torque_estimator.identification.excitation import sampled

    sim = SimulatedRig(rig, n=1, seed=seed, effects=effects)
    oil = next((e for e in sim.plant.fx.effects if e.name == "oil_temperature"), None)
    loop = PiLoop(rig, DEFAULT_GAINS, rig.supply_voltage)
    monitors = {"measured": LiveHealth(rig, reference, settings, sim.sample_period),
                "estimated": LiveHealth(rig, reference, thermal or settings, sim.sample_period)}
    _index, speeds, loads = sampled(timeline, sim.sample_period)
    batch = 5
    rows: dict[str, list[tuple]] = {name: [] for name in monitors}
    buf = {name: [] for name in ("w", "i", "d", "tw", "tg", "temp")}
    every = int(round(10.0 / sim.sample_period))
    for k in range(len(speeds)):
        sim.command(load_torque=float(loads[k]))
        m = sim.sample()
        w = float(m.omega_worm[0])
        buf["w"].append(w)
        buf["i"].append(float(m.current_drive[0]))
        buf["d"].append(float(m.tau_load[0]))
        buf["tw"].append(float(m.theta_worm[0]))
        buf["tg"].append(float(m.theta_gear[0]))
        buf["temp"].append(float(oil.temperature[0]) if oil is not None else math.nan)
        sim.command(voltage_drive=loop.update(sim.sample_period, float(speeds[k]), w))
        if len(buf["w"]) == batch:
            for name, monitor in monitors.items():
                given = buf["temp"] if name == "measured" else None
                if monitor.add(buf["w"], buf["i"], buf["d"], buf["tw"], buf["tg"], given):
                    st = monitor.status
                    rows[name].append((st.time, st.level, st.mu_change.value, st.mu_change.sigma,
                                       st.oil_temperature.value, buf["temp"][-1]))
            for v in buf.values():
                v.clear()
        if progress is not None and (k + 1) % every == 0:
            progress(k + 1, len(speeds))
    out = {}
    for name, table in rows.items():
        cols = list(zip(*table)) if table else [[]] * 6
        out[name] = LiveTrace(np.array(cols[0]), list(cols[1]), np.array(cols[2]), np.array(cols[3]),
                              np.array(cols[4]), np.array(cols[5]))
    return out


# --- the live scenarios and make evaluate's lines ---------------------------------------------------------

#: rig time of the lubricant loss in its scenario [s], and the scenario's length
LUBRICANT_AT, LUBRICANT_RUN = 30.0, 60.0
#: the cold start: oil from 15 degC, the housing's R_th that brings it to ~45 degC in 20 min of the work
#: (operation(); ~1.5 W of heat: a small box this warm is shielded from the air; the scenario's assumption)
COLD_START, COLD_RUN, COLD_R_TH = 15.0, 1200.0, 20.0


def live_reference(rig: Rig, seed: int, settings: HealthSettings):
    """A gearbox's trend of baseline checks (simulated side by side) and the live reference it gives."""
    from worm_model.health.assess import baseline_of
    from worm_model.health.live import LiveReference

    lives = draw_lives(1, settings.limits.baseline_checks + 1, seed, settings=settings)
    run_lives(rig, lives, seed, settings)
    records = lives[0].records["measured"]
    assess_trend(records, settings, rig)
    return LiveReference.from_check(records[-1], baseline_of(records, settings, rig))


def _with(effects: dict, **changes: dict) -> dict:
    out = {name: dict(values) for name, values in effects.items()}
    for name, values in changes.items():
        out[name] = {**out.get(name, {}), **values}
    return out


def live_scenarios(rig: Rig, seed: int = 0, settings: HealthSettings = HealthSettings(),
                   progress: Callable[[int, int], None] | None = None) -> dict[str, dict[str, LiveTrace]]:
    """The two live scenarios (module docstring of LiveHealth's targets): "lubricant" (mu +30 % at
    :data:`LUBRICANT_AT` s of the rig at work, oil at 40 degC) and "cold" (a cold start, oil 15 -> ~45 degC over
    20 min); each with the oil measured and estimated (the estimate's thermal model as identified once with a probe:
    R_th and tau within 10 % of the housing's)."""
    reference = live_reference(rig, seed + 7, settings)
    lubricant = _with(GEARBOX_EFFECTS, oil_temperature={"initial": 40.0},
                      lubricant_loss={"rise": 0.3, "at": LUBRICANT_AT})
    cold = _with(GEARBOX_EFFECTS, oil_temperature={"initial": COLD_START, "thermal_resistance": COLD_R_TH})
    thermal = replace(settings, thermal=replace(settings.thermal, thermal_resistance=0.9 * COLD_R_TH,
                                                time_constant=1.1 * 900.0))
    return {"lubricant": live_run(rig, reference, operation(rig, LUBRICANT_RUN), effects=lubricant, seed=seed,
                                  settings=settings, thermal=thermal),
            "cold": live_run(rig, reference, operation(rig, COLD_RUN), effects=cold, seed=seed + 1,
                             settings=settings, thermal=thermal, progress=progress)}


def live_lines(traces: dict[str, dict[str, LiveTrace]]) -> list[str]:
    out = []
    for mode, trace in traces["lubricant"].items():
        early = trace.first("WARN") < LUBRICANT_AT
        after = trace.first("WARN", LUBRICANT_AT) - LUBRICANT_AT
        out.append(f"health: live lubricant_loss=mu+30% warn_after_s={after:.2f} false_before={int(early)} "
                   f"temperature={mode}")
    for mode, trace in traces["cold"].items():
        raised = sum(1 for a, b in zip(["OK"] + trace.level[:-1], trace.level) if a == "OK" and b != "OK")
        sure = trace.mu_change - Z95 * trace.mu_sigma  # the reading's 95 % lower bound
        error = np.nanmax(np.abs(trace.temperature - trace.true_temperature))
        out.append(f"health: live cold_start oil={trace.true_temperature[0]:.0f}->{trace.true_temperature[-1]:.0f}degC "
                   f"over_s={trace.time[-1]:.0f} warnings={raised} largest_sure_rise_pct={100 * np.nanmax(sure):.1f} "
                   f"temperature_error_max_K={error:.1f} temperature={mode}")
    return out


def evaluate_lines(rig: Rig, seed: int = 0, settings: HealthSettings = HealthSettings(), out=None,
                   progress: Callable[[str, int, int], None] | None = None) -> list[str]:
    """``make evaluate``'s health lines: the study (:func:`run_study`), the live scenarios, the real drive's
    check; with ``out`` (a folder) also health_trend.png, a gearbox's life with a 10 % rise."""
    study = run_study(rig, seed=seed, settings=settings,
                      progress=None if progress is None else (lambda d, t: progress("health checks", d, t)))
    lines = study.lines()
    traces = live_scenarios(rig, seed, settings,
                            None if progress is None else (lambda d, t: progress("health live", d, t)))
    lines += live_lines(traces)
    from torque_estimator.health.real_drive import real_drive_line

    lines.append(real_drive_line(settings))
    if out is not None and study.example is not None:
        from worm_model.health.assess import baseline_of
        from worm_model.health.plots import trend_figure

        records = study.example
        assessments = assess_trend(records, settings, rig)
        n = settings.limits.baseline_checks
        trend_figure(out / "health_trend.png", records, assessments, settings, rig,
                     baseline_of(records[:n], settings, rig),
                     f"A simulated gearbox: mu +{max(study.example_rise, 0):.0%} from check "
                     f"{study.example_first + 1} (oil measured)")
    if out is not None:
        from worm_model.health.plots import live_figure

        live_figure(out / "health_live.png",
                    [(f"lubricant loss: mu +30 % at {LUBRICANT_AT:g} s", traces["lubricant"]),
                     (f"cold start: oil {COLD_START:g} -> 45 degC over {COLD_RUN / 60:g} min", traces["cold"])],
                    settings.limits, "The live monitor at the paper's rig (load known), oil measured and estimated")
    return lines
