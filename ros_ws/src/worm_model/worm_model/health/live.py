"""Watching between checks: a sliding-window estimate of the gearbox's friction from the live stream.

Where the load is known (the paper's rig commands it; tau_load is measured), every block of samples
(blocks.Blocks, 50 ms) in steady motion within the range the reference check covered (its speeds
and loads, widened by settings.Live.margin) gives a residual

    r_b = K_t i_b + J alpha_b - T_model(omega_b, tau_b; reference, f_T(T_b)) - ripple(theta_g)

against the health model with the reference parameters (the latest check's, mu at the oil's
temperature T_b through the learned law: model.TemperatureLaw). As the check's points, a block counts
once it is steady (one direction, small acceleration, the speed and the load those of the block
before) and the first settings.Live.settle seconds after a change are left out (the speed loop's
current still settles when the speed already holds). Over the window
(settings.Live.window of rig time) the residuals say how much the friction rose, read two ways:

* as mu: delta_s = sum(phi r) / sum(phi^2), phi_b = dT_model/ds at the block, reported relative
  to the reference (what a lubricant loss or a worn mesh moves);
* as torque: the mean of r [N m] at the worm (what a dragging seal moves).

At one operating point the two cannot be told apart (both only raise the torque); the level is
raised by mu's reading (settings.Limits.live_warn / live_error, and z >= z_min) or by a torque excess
beyond the drive drag's limits. Each reading's sigma: the scatter of the blocks' residuals about it
(their mean's variance with the lag-1 autocorrelation's effective count: ripples and the speed loop
make neighbouring blocks alike), the model's own error at a point (the reference check's RMS
residual: it does not average out over a window), the oil
temperature's uncertainty (k sigma_T) and the law's (sigma_k |T - T_check|). A level must hold
settings.Limits.live_hold of rig time before it is raised or lowered; a raised level stands until a window
shows, surely (95 %), that mu's reading is back below the warning limit (at a light load the window
cannot tell: the alarm holds).

The wheel runout's once-per-gear-turn ripple (fit's nuisance) is learned here too, slowly (a
recursive least squares on sin, cos of the gear angle, with and without |D_mesh|, forgetting over
:data:`RIPPLE_MEMORY` s): a window shorter than a gear turn would otherwise read part of it as a change.

The oil temperature: measured where given with the samples, else the first-order thermal model
(thermal.ThermalEstimate) fed by the heat the model says the drive makes.
Plain Python on floats per sample; numpy once per block. No ROS.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from worm_model.health.assess import ORDER, Baseline, Estimate, Z95
from worm_model.health.model import HealthParameters, TemperatureLaw, drag_power, input_torque, mesh_loss
from worm_model.health.record import CheckRecord
from worm_model.health.settings import HealthSettings
from worm_model.health.thermal import ThermalEstimate
from worm_model.physics.parameters import Rig

#: [s] memory of the ripple's estimate
RIPPLE_MEMORY = 30.0
#: [N m] the model's own error at a point when the rig file is the reference (assumption: an identified rig
#: file's, ~0.1 mN m; a rig file as declared is far worse: run a check first)
RIG_FILE_FLOOR = 1e-4
#: relative step of mu's scale for the sensitivity phi
_STEP = 1e-3


@dataclass(frozen=True)
class LiveReference:
    """What the live monitor compares with: a check's parameters at the reference temperature, and where it holds.

    Attributes:
        parameters: health parameters, mu_scale at law.reference.
        law: mu's temperature law (learned by the trend, or the prior).
        floor: [N m] the model's own error at a point (the check's RMS residual).
        speeds: "forward"/"backward" -> [min, max] |omega| the check covered [rad/s].
        loads: [min, max] tau_load the check covered [N m].
        check_temperature: [degC] the check's oil temperature (k's uncertainty grows away from it).
        source: what it is ("check of <date>", "rig file").
    """

    parameters: HealthParameters
    law: TemperatureLaw
    floor: float
    speeds: dict
    loads: list
    check_temperature: float
    source: str

    @classmethod
    def from_check(cls, record: CheckRecord, baseline: Baseline) -> "LiveReference":
        """The latest check's own fit, its mu brought to the reference temperature by the baseline's law."""
        law = baseline.law
        f = float(law.factor(record.temperature.value))
        params = replace(record.parameters, mu_scale=record.parameters.mu_scale / f)
        return cls(params, law, record.rms, record.speeds, record.loads, record.temperature.value,
                   f"check of {record.date}")

    @classmethod
    def from_rig(cls, rig: Rig, settings: HealthSettings) -> "LiveReference":
        """The rig file's values over the load motors' whole range (no check yet: a coarse reference)."""
        prior = settings.temperature
        top = rig.max_load_torque
        return cls(HealthParameters.from_rig(rig), TemperatureLaw(prior.reference, prior.mu_per_kelvin, prior.sigma),
                   RIG_FILE_FLOOR, {"forward": [0.0, math.inf], "backward": [0.0, math.inf]}, [-top, top],
                   prior.reference, "rig file")


@dataclass
class LiveStatus:
    """The window's estimate (module docstring); NaN where the window holds nothing to say it from."""

    level: str = "OK"
    message: str = "waiting for steady operation within the checked range"
    time: float = 0.0  # [s] rig time of the newest block
    mu_change: Estimate = field(default_factory=lambda: Estimate(math.nan, math.nan))  # relative, as mu
    friction_excess: Estimate = field(default_factory=lambda: Estimate(math.nan, math.nan))  # [N m] at the worm
    oil_temperature: Estimate = field(default_factory=lambda: Estimate(math.nan, math.nan))  # [degC]
    temperature_source: str = "estimated"
    backlash: Estimate = field(default_factory=lambda: Estimate(math.nan, math.nan))  # [rad]
    blocks: int = 0  # in the window
    window: float = 0.0  # [s] of rig time the window's blocks cover
    speed: float = math.nan  # [rad/s] mean of the window
    load: float = math.nan  # [N m] mean of the window
    outside: int = 0  # blocks of steady motion outside the checked range, since the start

    def values(self) -> dict[str, str]:
        """The figures for /diagnostics (SI units in the keys)."""
        m, e, t, b = self.mu_change, self.friction_excess, self.oil_temperature, self.backlash
        return {"mu_change": f"{m.value:+.4f}", "mu_change_ci95": f"{Z95 * m.sigma:.4f}",
                "friction_excess_Nm": f"{e.value:+.3e}", "friction_excess_ci95_Nm": f"{Z95 * e.sigma:.1e}",
                "oil_temperature_degC": f"{t.value:.1f}", "oil_temperature_ci95_K": f"{Z95 * t.sigma:.1f}",
                "temperature_source": self.temperature_source, "backlash_rad": f"{b.value:.5f}",
                "window_blocks": str(self.blocks), "window_s": f"{self.window:.2f}", "speed_rad_s": f"{self.speed:.1f}",
                "load_Nm": f"{self.load:.3f}", "rig_time_s": f"{self.time:.2f}"}


class LiveHealth:
    """The live monitor's core (module docstring): samples in (:meth:`add`), a :class:`LiveStatus` out.

    Args:
        rig: the rig file (geometry, motor constant, inertias).
        reference: what to compare with.
        settings: live window, limits, thermal model.
        sample_period: the rig's [s].
        thermal: the oil's estimate when no temperature comes with the samples (default: a cold start).
    """

    def __init__(self, rig: Rig, reference: LiveReference, settings: HealthSettings, sample_period: float,
                 thermal: ThermalEstimate | None = None) -> None:
        self.rig = rig
        self.reference = reference
        self.settings = settings
        self.period = sample_period
        self.size = max(2, int(round(settings.live.block_time / sample_period)))
        self.thermal = thermal or ThermalEstimate.start(settings.thermal)
        self.status = LiveStatus()
        self._window: deque = deque()
        self._sums = [0.0] * 9
        self._count = 0
        self._time = 0.0
        self._candidate = ("OK", 0.0)  # (level, rig time it was first seen)
        self._ripple = _Ripple(math.exp(-settings.live.block_time / RIPPLE_MEMORY))
        self._prev_current = math.nan
        self._last: tuple[float, float] | None = None
        self._settled = 0
        self.blocks_seen = 0
        ratio = rig.gearbox.ratio
        self._ratio = ratio
        top = reference.loads
        span = max(top[1] - top[0], 1e-9) if top else 1.0
        margin = settings.live.margin
        self._load_range = (top[0] - margin * span, top[1] + margin * span) if top else (-math.inf, math.inf)
        self._speed_range = {name: (lo * (1.0 - margin), hi * (1.0 + margin))
                             for name, (lo, hi) in reference.speeds.items()}

    # --- samples in -------------------------------------------------------------------------------------
    def add(self, omega, current, tau_load, theta_worm, theta_gear=None, temperature=None) -> bool:
        """Samples of one message (sequences of floats, consecutive); True when a block finished."""
        finished = False
        s = self._sums
        for k in range(len(omega)):
            w, i = float(omega[k]), float(current[k])
            j = self._count
            s[0] += w
            s[1] += j * w
            s[2] += i
            di = i - self._prev_current if j else 0.0
            s[3] += di * di
            self._prev_current = i
            s[4] += float(tau_load[k])
            g = self._ratio * float(theta_worm[k])
            s[5] += math.sin(g)
            s[6] += math.cos(g)
            if theta_gear is not None:
                s[7] += float(theta_gear[k]) - g
            if temperature is not None:
                s[8] += float(temperature[k])
            if j == 0:
                self._w_min = self._w_max = w
            else:
                self._w_min, self._w_max = min(self._w_min, w), max(self._w_max, w)
            self._count += 1
            if self._count == self.size:
                self._block(theta_gear is not None, temperature is not None)
                finished = True
        return finished

    # --- one block ---------------------------------------------------------------------------------------
    def _block(self, has_te: bool, has_temperature: bool) -> None:
        n = float(self.size)
        s = self._sums
        omega = s[0] / n
        alpha = (s[1] - 0.5 * (n - 1.0) * s[0]) / (n * (n * n - 1.0) / 12.0) / self.period
        current = s[2] / n
        noise = s[3] / (2.0 * (n - 1.0))
        load = s[4] / n
        gs, gc = s[5] / n, s[6] / n
        te = s[7] / n if has_te else math.nan
        measured = s[8] / n if has_temperature else math.nan
        one_way = self._w_min * self._w_max > 0.0
        self._sums = [0.0] * 9
        self._count = 0
        duration = n * self.period
        self._time += duration
        self.blocks_seen += 1
        ref, rig, live = self.reference, self.rig, self.settings.live
        law = ref.law
        # the oil: measured, else the thermal estimate fed by the heat at this block
        if math.isfinite(measured):
            temperature = Estimate(measured, self.settings.temperature.sensor_sigma)
            source = "measured"
        else:
            factor = float(law.factor(self.thermal.temperature))
            heat = 0.0
            if math.isfinite(omega) and math.isfinite(load) and abs(omega) > 1e-3:
                worm, gear = drag_power(rig, ref.parameters, omega)
                shares = self.settings.thermal
                heat = float(mesh_loss(rig, ref.parameters, omega, load, factor)) \
                    + shares.drive_drag_heat * float(worm) + shares.gear_drag_heat * float(gear)
            self.thermal.step(duration, heat)
            temperature = Estimate(self.thermal.temperature, self.thermal.sigma)
            source = "estimated"
        self.status.oil_temperature, self.status.temperature_source = temperature, source
        self.status.time = self._time
        points = self.settings.points
        steady = one_way and abs(alpha) < points.alpha_max and abs(omega) >= points.slowest(rig) \
            and math.isfinite(current) and math.isfinite(load)
        if steady and self._last is not None:  # a new operating point is a transient too
            w0, d0 = self._last
            steady = abs(omega - w0) <= max(points.speed_floor, points.speed_tolerance * abs(w0)) \
                and abs(load - d0) <= max(points.load_floor, points.load_tolerance * abs(d0))
        self._last = (omega, load)
        self._settled = self._settled + 1 if steady else 0
        if self._settled * duration <= live.settle + 1e-9:  # the tail of a change: left out
            self._expire()
            return
        lo, hi = self._speed_range.get("forward" if omega > 0 else "backward", (math.inf, -math.inf))
        if not (lo <= abs(omega) <= hi and self._load_range[0] <= load <= self._load_range[1]):
            self.status.outside += 1
            self._expire()
            return
        factor = float(law.factor(temperature.value))
        p = ref.parameters
        model = float(input_torque(rig, p, omega, load, factor))
        bumped = float(input_torque(rig, replace(p, mu_scale=p.mu_scale * (1.0 + _STEP)), omega, load, factor))
        phi = (bumped - model) / (_STEP * p.mu_scale)  # dT/ds [N m per unit of mu's scale]
        k_t = rig.drive_motor.torque_constant
        measured_torque = k_t * current + rig.total_worm_inertia * alpha
        mesh = abs(load + p.gear_coulomb * math.copysign(1.0, omega) + p.gear_viscous * self._ratio * omega)
        residual = measured_torque - model
        ripple = self._ripple.predict(gs, gc, mesh)
        self._ripple.update(gs, gc, mesh, residual)
        contact = math.copysign(1.0, load + p.gear_coulomb * math.copysign(1.0, omega)
                                + p.gear_viscous * self._ratio * omega)
        self._window.append((self._time, residual - ripple, phi, noise, omega, load, temperature, te, contact, mesh))
        self._expire()
        self._estimate()

    def _expire(self) -> None:
        horizon = self._time - self.settings.live.window
        while self._window and self._window[0][0] <= horizon:
            self._window.popleft()
        if len(self._window) < self.settings.live.min_blocks:
            self.status.blocks = len(self._window)
            self._decide("OK", "waiting for steady operation within the checked range" if not self._window else
                         f"{len(self._window)} steady blocks in the window, {self.settings.live.min_blocks} needed")

    def _estimate(self) -> None:
        rows = self._window
        if len(rows) < self.settings.live.min_blocks:
            return
        ref = self.reference
        r = np.array([row[1] for row in rows])
        phi = np.array([row[2] for row in rows])
        n = len(r)
        floor2 = ref.floor ** 2
        s_ref = ref.parameters.mu_scale
        info = float(phi @ phi)
        delta = float(phi @ r) / info if info > 0 else math.nan
        scatter = r - phi * delta if info > 0 else r - r.mean()
        # the blocks' residuals are correlated (ripples slower than a block, the speed loop): the variance of a
        # mean over n of them is s^2 / n_eff, n_eff = n (1 - rho) / (1 + rho) with rho the lag-1 autocorrelation
        var = float(scatter @ scatter) / max(n - 1, 1)
        rho = float(np.corrcoef(scatter[:-1], scatter[1:])[0, 1]) if n > 3 and var > 0 else 0.0
        rho = min(max(rho if math.isfinite(rho) else 0.0, 0.0), 0.9)
        inflate = (1.0 + rho) / (1.0 - rho)
        excess = float(r.mean())
        excess_sigma = math.sqrt(var * inflate / n + floor2)
        temperature = rows[-1][6]
        law = ref.law
        f = float(law.factor(temperature.value))
        if info > 0:
            phi_mean = float(phi.mean())
            noise = var * inflate / info + floor2 / max(phi_mean * phi_mean, 1e-30)
            thermal = (law.mu_per_kelvin * temperature.sigma / f) ** 2 \
                + (law.sigma * (temperature.value - ref.check_temperature)) ** 2
            mu = Estimate(delta / s_ref, math.sqrt(noise / s_ref ** 2 + thermal))
        else:
            mu = Estimate(math.nan, math.nan)
        st = self.status
        st.mu_change, st.friction_excess = mu, Estimate(excess, excess_sigma)
        st.blocks = n
        st.window = rows[-1][0] - rows[0][0] + self.size * self.period
        st.speed = float(np.mean([row[4] for row in rows]))
        st.load = float(np.mean([row[5] for row in rows]))
        st.backlash = _backlash(rows)
        limits = self.settings.limits
        level, why = "OK", "friction as the reference"
        sure = math.isfinite(mu.value) and mu.sigma > 0 and mu.value / mu.sigma >= limits.z_min
        if sure and mu.value > limits.live_error:
            level, why = "ERROR", "friction far above the reference"
        elif sure and mu.value > limits.live_warn:
            level, why = "WARN", "friction above the reference"
        elif self.status.level != "OK" and not (mu.value + Z95 * mu.sigma < limits.live_warn):
            # an alarm stands until the window shows, surely, that the friction is back below the limit
            level, why = self.status.level, "cannot tell at this load"
        drive = ref.parameters.drive_coulomb + ref.parameters.drive_viscous * abs(st.speed)
        if level == "OK" and excess > max(limits.drag_floor, limits.drag_warn * drive) \
                and excess / excess_sigma >= limits.z_min:
            level, why = "WARN", "drive torque above the reference (a drag?)"
        text = (f"{why}: as mu {mu.value:+.1%} +- {Z95 * mu.sigma:.1%}, as torque {1e3 * excess:+.2f} +- "
                f"{1e3 * Z95 * excess_sigma:.2f} mN m at {st.speed:.0f} rad/s, {st.load:+.3f} N m; oil "
                f"{temperature.value:.1f} +- {Z95 * temperature.sigma:.1f} degC ({st.temperature_source})")
        self._decide(level, text)

    def _decide(self, level: str, text: str) -> None:
        """Raise or lower the level once the candidate has held limits.live_hold of rig time."""
        st = self.status
        candidate, since = self._candidate
        if level != candidate:
            self._candidate = (level, self._time)
            since = self._time
        if level != st.level and self._time - since >= self.settings.limits.live_hold - 1e-9:
            st.level = level
        if ORDER[level] >= ORDER[st.level] or level == st.level:
            st.message = text
        else:
            st.message = f"{text} (holding {st.level})"


class _Ripple:
    """The once-per-gear-turn ripple of the residual: exponentially weighted least squares on (sin, cos) x
    (1, |D_mesh|) of the gear angle, forgetting factor ``lam`` per block (memory 1 / (1 - lam) blocks), with a
    ridge of one block's weight (where the regressors are not excited the estimate stays at 0 instead of
    wandering). A level step of the residual is, over whole gear turns, orthogonal to these regressors:
    within a memory of many turns the estimate takes almost none of it."""

    def __init__(self, lam: float) -> None:
        self.lam = lam
        self.a = np.zeros((4, 4))
        self.b = np.zeros(4)
        self.theta = np.zeros(4)

    @staticmethod
    def _x(gs: float, gc: float, mesh: float) -> np.ndarray:
        return np.array([gs, gc, mesh * gs, mesh * gc])

    def predict(self, gs: float, gc: float, mesh: float) -> float:
        return float(self._x(gs, gc, mesh) @ self.theta)

    def update(self, gs: float, gc: float, mesh: float, residual: float) -> None:
        x = self._x(gs, gc, mesh)
        self.a = self.lam * self.a + np.outer(x, x)
        self.b = self.lam * self.b + x * residual
        self.theta = np.linalg.solve(self.a + np.eye(4), self.b)


def _backlash(rows) -> Estimate:
    """The gap from the window's transmission errors on both flanks (fit._backlash's way); NaN if one is missing."""
    te = np.array([row[7] for row in rows])
    contact = np.array([row[8] for row in rows])
    mesh = np.array([row[9] for row in rows])
    use = np.isfinite(te) & (mesh > 0.02)
    plus, minus = te[use & (contact > 0)], te[use & (contact < 0)]
    if plus.size < 2 or minus.size < 2:
        return Estimate(math.nan, math.nan)
    return Estimate(float(minus.mean() - plus.mean()),
                    math.sqrt(plus.var(ddof=1) / plus.size + minus.var(ddof=1) / minus.size))


__all__ = ["LiveHealth", "LiveReference", "LiveStatus", "RIPPLE_MEMORY"]
