"""Candidate effects beyond Eqs 19-30 (physics.md section 9), as plug-ins behind one protocol.

An effect adds to the model's channels (:data:`worm_model.residuals.model.CHANNELS`: mu,
mu_relative, worm_torque, gear_torque, worm_inertia, gear_inertia, current_gain,
current) a sum of *shapes*, one column per linear parameter:
``channel += shapes[channel] @ values``.  Its regressors (current per unit parameter
[A/unit]) are those shapes times the model's sensitivity of the current to each channel
(:func:`regressors`), so one declaration gives both the exact extended model and the
linear screening.  Parameters an effect is not linear in (a time constant, a harmonic
order, a Stribeck speed, a drag exponent, a PWM sampling phase) are *grid parameters*: the analysis tries
every grid value with linear least squares inside.

Most effects act on the drive current (``fitted_signal = "current_drive"``); one that shows
in position (backlash) gives instead the *transmission error* ratio theta_worm - theta_gear
[rad at the gear] per unit of its parameters (:meth:`Effect.te_columns`), fitted when the
data has a gear encoder.

Signs: fixed frame; the worm_torque and gear_torque channels are extra torques the drive
has to overcome (+ opposes + rotation, as tau_load).  Angles: theta_worm, and theta_gear
worm-referenced (+ with + worm rotation).

The effects and their parameters mirror the simulator's plug-ins (worm_rig_driver's
effects.py, file format ``worm_rig_effects``): same names, and :meth:`Effect.simulator_entry`
/ :meth:`Effect.from_simulator_entry` translate fitted values to and from an entry of an
``effects:`` section with the simulator's parameter names and meanings (there, a
worm-shaft torque is + when it *drives*; the sign is flipped in the translation).
Adding an effect is adding a class and a row in :data:`EFFECTS`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np
from scipy.signal import lfilter

from worm_model.physics.friction import sliding_velocity
from worm_model.physics.gear_side import gear_side_load
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.model import CHANNELS, Channels, ModelState, Signals, evaluate, ripple_response, sensitivities

#: Shapes: channel -> (n, number of parameters); a parameter's column is zero in the
#: channels it does not touch (channels an effect never touches are left out).
Shapes = dict[str, FloatArray]


@dataclass(frozen=True)
class Parameter:
    """A parameter the effect is linear in."""

    name: str
    unit: str
    description: str = ""


@dataclass(frozen=True)
class GridParameter:
    """A parameter searched on a grid (the effect is nonlinear in it)."""

    name: str
    unit: str
    description: str = ""


@runtime_checkable
class Effect(Protocol):
    """What every candidate effect provides."""

    name: str  # one of the vocabulary of the issue (EFFECTS keys)
    family: str  # "periodic" (angle spectrum), "regression", "thermal" (first-order drift)
    fitted_signal: str  # "current_drive" (channels, shapes) or "transmission_error" (te_columns)
    description: str
    parameters: tuple[Parameter, ...]
    grid_parameters: tuple[GridParameter, ...]

    def grid(self, rig: Rig, signals: Signals) -> list[dict[str, float]]:
        """Grid values to try ([{}] if the effect has no grid parameter)."""

    def unavailable(self, rig: Rig, signals: Signals) -> str | None:
        """Why the data cannot show this effect (None if it can)."""

    def shapes(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> Shapes:
        """channel -> (n, len(parameters)): channel contribution per unit of each parameter."""

    def te_columns(self, rig: Rig, signals: Signals, state: ModelState, grid: Mapping[str, float]) -> FloatArray:
        """(n, len(parameters)) transmission error [rad] per unit of each parameter (fitted_signal
        "transmission_error" only), at the model state ``state``."""

    def signature(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> tuple[str, FloatArray]:
        """(axis label, per-sample values) to plot the residual against."""

    def simulator_entry(self, values: Mapping[str, float], grid: Mapping[str, float]) -> dict[str, float]:
        """The effect's entry of an ``effects:`` section (simulator's names, units and signs)."""

    def from_simulator_entry(self, entry: Mapping[str, Any], rig: Rig) -> tuple[dict[str, float], dict[str, float]]:
        """Inverse of :meth:`simulator_entry`: (values, grid); ``rig`` gives geometry (Z_g)."""


def _column(n: int, p: int, j: int, x: FloatArray) -> FloatArray:
    out = np.zeros((n, p))
    out[:, j] = x
    return out


def _sigma(signals: Signals) -> FloatArray:
    return np.where(signals.omega < 0.0, -1.0, 1.0)


def mesh_load(rig: Rig, signals: Signals) -> FloatArray:
    """|tau_load + declared gear-side drag| [N m]: the torque the mesh carries on the gear side."""
    return np.abs(gear_side_load(rig, signals.tau_load, signals.omega))


class _Base:
    """Shared plumbing: no grid, always available."""

    name: ClassVar[str]
    family: ClassVar[str] = "regression"
    fitted_signal: ClassVar[str] = "current_drive"
    description: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    grid_parameters: ClassVar[tuple[GridParameter, ...]] = ()

    def grid(self, rig: Rig, signals: Signals) -> list[dict[str, float]]:
        return [{}]

    def unavailable(self, rig: Rig, signals: Signals) -> str | None:
        return None

    def te_columns(self, rig: Rig, signals: Signals, state: ModelState, grid: Mapping[str, float]) -> FloatArray:
        raise NotImplementedError(f"{self.name} acts on the current, not on the transmission error")

    def signature(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> tuple[str, FloatArray]:
        return "omega_worm [rad/s]", signals.omega

    def simulator_entry(self, values: Mapping[str, float], grid: Mapping[str, float]) -> dict[str, float]:
        return {p.name: float(values[p.name]) for p in self.parameters}

    def from_simulator_entry(self, entry: Mapping[str, Any], rig: Rig) -> tuple[dict[str, float], dict[str, float]]:
        return {p.name: float(entry.get(p.name, 0.0)) for p in self.parameters}, {}


# --------------------------------------------------------------------------- regression effects
class BearingCoulomb(_Base):
    """Simulator: worm -worm_torque sign(omega_worm), gear +gear_torque sign(omega_gear)."""

    name = "bearing_coulomb"
    description = "bearing/seal Coulomb drag on the worm and gear shafts: a step with sign(omega)"
    parameters = (
        Parameter("worm_torque", "N m", "Coulomb drag on the worm shaft"),
        Parameter("gear_torque", "N m", "Coulomb drag on the gear shaft"),
    )

    def shapes(self, rig, signals, grid):
        s, n = _sigma(signals), len(signals)
        return {"worm_torque": _column(n, 2, 0, s), "gear_torque": _column(n, 2, 1, s)}

    def simulator_entry(self, values, grid):
        # the simulator's drags are magnitudes (>= 0)
        return {p.name: max(0.0, float(values[p.name])) for p in self.parameters}


class ViscousDrag(_Base):
    """Simulator: T_ref (|omega| / omega_ref)^exponent on each shaft, gear term at the worm speed."""

    name = "viscous_drag"
    description = "viscous and oil-churning drag, T_ref (|omega_worm| / omega_ref)^p on the worm and gear shafts"
    reference_speed: ClassVar[float] = 300.0  # [rad/s], the simulator's default omega_ref
    parameters = (
        Parameter("worm_torque", "N m", "worm-shaft drag at the reference speed (300 rad/s)"),
        Parameter("gear_torque", "N m", "gear-shaft drag at the reference worm speed"),
    )
    grid_parameters = (GridParameter("exponent", "1", "speed exponent: 1 viscous, 0.5..1 churning"),)

    def grid(self, rig, signals):
        return [{"exponent": p} for p in (0.5, 0.75, 1.0, 1.25, 1.5)]

    def shapes(self, rig, signals, grid):
        x = _sigma(signals) * (np.abs(signals.omega) / self.reference_speed) ** grid["exponent"]
        n = len(signals)
        return {"worm_torque": _column(n, 2, 0, x), "gear_torque": _column(n, 2, 1, x)}

    def simulator_entry(self, values, grid):
        return {"worm_torque": max(0.0, values["worm_torque"]), "gear_torque": max(0.0, values["gear_torque"]),
                "reference_speed": self.reference_speed, "exponent": float(grid["exponent"])}

    def from_simulator_entry(self, entry, rig):
        scale = (self.reference_speed / float(entry.get("reference_speed", self.reference_speed))) \
            ** float(entry.get("exponent", 1.0))
        return ({"worm_torque": float(entry.get("worm_torque", 0.0)) * scale,
                 "gear_torque": float(entry.get("gear_torque", 0.0)) * scale},
                {"exponent": float(entry.get("exponent", 1.0))})


class SpeedDependentMu(_Base):
    """Simulator: mu = mu_rig(V_s) (1 + low_speed_gain exp(-V_s / stribeck_speed))."""

    name = "speed_dependent_mu"
    description = "Stribeck rise of mu at low sliding speed: mu *= 1 + gain exp(-V_s / v_stribeck)"
    parameters = (Parameter("low_speed_gain", "1", "relative increase of mu as the sliding speed goes to 0"),)
    grid_parameters = (GridParameter("stribeck_speed", "m/s", "sliding speed over which the increase decays"),)

    def grid(self, rig, signals):
        return [{"stribeck_speed": float(v)} for v in np.geomspace(0.03, 1.5, 13)]

    def shapes(self, rig, signals, grid):
        vs = sliding_velocity(rig.gearbox, signals.omega)
        return {"mu_relative": np.exp(-vs / grid["stribeck_speed"])[:, None]}

    def signature(self, rig, signals, grid):
        return "sliding speed [m/s]", sliding_velocity(rig.gearbox, signals.omega)

    def simulator_entry(self, values, grid):
        return {"low_speed_gain": float(values["low_speed_gain"]), "stribeck_speed": float(grid["stribeck_speed"])}

    def from_simulator_entry(self, entry, rig):
        return ({"low_speed_gain": float(entry.get("low_speed_gain", 0.0))},
                {"stribeck_speed": float(entry.get("stribeck_speed", 0.3))})


class LoadDependentMu(_Base):
    """Simulator: mu = mu_rig (1 + sensitivity mesh_load / reference_torque)."""

    name = "load_dependent_mu"
    description = "mu changing with the transmitted torque: mu *= 1 + sensitivity |mesh load| / 0.25 N m"
    reference_torque: ClassVar[float] = 0.25  # [N m], the simulator's default
    parameters = (Parameter("sensitivity", "1", "relative change of mu at a mesh load of 0.25 N m"),)

    def shapes(self, rig, signals, grid):
        return {"mu_relative": (mesh_load(rig, signals) / self.reference_torque)[:, None]}

    def signature(self, rig, signals, grid):
        return "tau_load [N m]", signals.tau_load

    def simulator_entry(self, values, grid):
        return {"sensitivity": float(values["sensitivity"]), "reference_torque": self.reference_torque}

    def from_simulator_entry(self, entry, rig):
        ref = float(entry.get("reference_torque", self.reference_torque))
        return {"sensitivity": float(entry.get("sensitivity", 0.0)) * self.reference_torque / ref}, {}


class _SensorError(_Base):
    """Current-sensor errors: the drive sensor's (parameter 0) and the load sensors' (parameter 1).

    The drive term enters the channel :attr:`drive_channel`.  The load term makes the measured
    tau_load wrong by :meth:`load_torque_error` per unit of the parameter; the true load is the
    measured one minus that, so the gear shaft's channel gets -error (to first order).
    """

    drive_channel: ClassVar[str]

    def load_torque_error(self, rig: Rig, signals: Signals) -> FloatArray:
        """Error of the measured tau_load [N m] per unit of the load-current parameter."""
        raise NotImplementedError

    def shapes(self, rig, signals, grid):
        n = len(signals)
        return {self.drive_channel: _column(n, 2, 0, np.ones(n)),
                "gear_torque": _column(n, 2, 1, -self.load_torque_error(rig, signals))}

    def simulator_entry(self, values, grid):
        # tacho gains/offsets scale alpha like an inertia error: not separable from the drive current, written as 0
        return {"drive_current": float(values["drive_current"]), "load_current": float(values["load_current"]),
                "drive_tacho": 0.0, "load_tacho": 0.0}


class SensorGain(_SensorError):
    """Simulator: reading = (1 + gain) x true, per sensor (drive current, load currents, tachos)."""

    name = "sensor_gain"
    description = "current-sensor gain errors: drive current x (1 + g_d); measured tau_load x (1 + g_l)"
    drive_channel = "current_gain"
    parameters = (
        Parameter("drive_current", "1", "relative gain error of the drive current sensor"),
        Parameter("load_current", "1", "relative gain error of the load current sensors (tau_load)"),
    )

    def load_torque_error(self, rig, signals):
        return signals.tau_load  # measured = (1 + g_l) true: error g_l tau_load to first order

    def signature(self, rig, signals, grid):
        return "tau_load [N m]", signals.tau_load


class SensorOffset(_SensorError):
    """Simulator: reading = true + offset, per sensor."""

    name = "sensor_offset"
    description = "current-sensor offsets: drive current + o_d; each load current + o_l (tau_load)"
    drive_channel = "current"
    parameters = (
        Parameter("drive_current", "A", "offset of the drive current sensor"),
        Parameter("load_current", "A", "offset of each load current sensor"),
    )

    def load_torque_error(self, rig, signals):
        # tau_load per A of offset on each sensor
        return np.full(len(signals), rig.load_motor.torque_constant * rig.load_motor_count)

    def signature(self, rig, signals, grid):
        return "t [s]", signals.t


class InertiaError(_Base):
    """Simulator: J_true = (1 + worm) J_worm,file and (1 + gear) J_gear,file."""

    name = "inertia_error"
    description = "error of the declared worm-shaft inertia (worm + rotor): residual proportional to alpha"
    # The gear shaft's inertia reaches the drive current through i (r_w/r_g) K_s ~ 0.2 % of the
    # worm side's: not identifiable from the current, so only the worm part is fitted.
    parameters = (Parameter("worm", "1", "relative error of the worm-shaft inertia"),)

    def shapes(self, rig, signals, grid):
        return {"worm_inertia": np.full((len(signals), 1), rig.total_worm_inertia)}

    def signature(self, rig, signals, grid):
        return "alpha_worm [rad/s^2]", signals.alpha

    def simulator_entry(self, values, grid):
        return {"worm": float(values["worm"]), "gear": 0.0}


# --------------------------------------------------------------------------- thermal
def first_order_lag(t: FloatArray, x: FloatArray, run: np.ndarray, time_constant: float) -> FloatArray:
    """y' = (x - y) / time_constant with y = 0 at the start of every run (first-order thermal model).

    Discretised exactly for x held over each (median) sample period of the run.
    """
    y = np.zeros(len(x))
    for r in np.unique(run):
        idx = np.flatnonzero(run == r)
        period = float(np.median(np.diff(t[idx]))) if len(idx) > 1 else 0.0
        decay = math.exp(-period / time_constant) if time_constant > 0 else 0.0
        y[idx] = lfilter([1.0 - decay], [1.0, -decay], x[idx])
    return y


def mesh_heat(rig: Rig, signals: Signals, state: ModelState | None = None) -> FloatArray:
    """Friction power in the mesh [W] by the declared model: |omega| G ((r_w/r_g) K_s - i) >= 0.

    Power in from the worm, (r_w/r_g) K_s G |omega|, minus power out to the gear, G i |omega|
    (frame of motion, inertia included in G).
    """
    st = state if state is not None else evaluate(rig, signals)
    gb = rig.gearbox
    return np.maximum(np.abs(signals.omega) * st.mesh_demand * (gb.radius_ratio * st.flank_factor - gb.ratio), 0.0)


class OilTemperature(_Base):
    """Simulator: C dT/dt = P - (T - T_amb)/R_th, mu *= 1 + mu_per_kelvin (T - T_amb), T(0) = T_amb.

    Two ways to the oil temperature rise dT over the reference (the temperature at which
    the declared mu holds, Signals.reference_temperature):

    * measured (a ``temperature`` column, e.g. a sump sensor): dT = T - T_ref, gaps in the
      column interpolated in time; grid {time_constant: 0};
    * not measured: the first-order model of the simulator, driven by the mesh friction
      power the declared model computes, R_th P lagged by the time constant (searched on
      a grid), starting at T_ref at every run.  Only the product mu_per_kelvin R_th is
      identifiable: R_th is fixed at the simulator's default.
    """

    name = "oil_temperature"
    family = "thermal"
    description = ("oil temperature (measured, or a first-order thermal model of the mesh's friction power) "
                   "scaling mu: mu *= 1 + mu_per_kelvin (T - T_ref)")
    thermal_resistance: ClassVar[float] = 5.0  # [K/W] the simulator's default; only the product is identifiable
    default_time_constant: ClassVar[float] = 900.0  # [s] the simulator's default, written when T was measured
    parameters = (Parameter("mu_per_kelvin", "1/K", "relative change of mu per kelvin of oil warming"),)
    grid_parameters = (GridParameter("time_constant", "s", "thermal time constant (0: measured temperature)"),)

    def grid(self, rig, signals):
        ref = {"reference_temperature": float(signals.reference_temperature)}
        if signals.temperature is not None:
            return [{"time_constant": 0.0, **ref}]
        span = float(np.max(np.bincount(signals.run, weights=np.gradient(signals.t)))) \
            if len(signals) > 1 else 1.0  # the longest run [s]
        return [{"time_constant": float(tc), **ref}
                for tc in np.geomspace(max(span / 30.0, 0.5), 10.0 * span, 12)]

    def unavailable(self, rig, signals):
        if signals.temperature is not None and not np.any(np.isfinite(signals.temperature)):
            return "the temperature column holds no value"
        return None

    def warming(self, rig: Rig, signals: Signals, grid: Mapping[str, float]) -> FloatArray:
        """Oil temperature rise over the reference [K]: measured, or the first-order model of the mesh heat."""
        if signals.temperature is not None:
            temp = signals.temperature
            finite = np.isfinite(temp)
            if not finite.any():
                return np.zeros(len(temp))
            if not finite.all():  # a slow quantity: interpolate the holes in time
                temp = np.interp(signals.t, signals.t[finite], temp[finite])
            return temp - float(grid.get("reference_temperature", signals.reference_temperature))
        heat = mesh_heat(rig, signals)
        return self.thermal_resistance * first_order_lag(signals.t, heat, signals.run, grid["time_constant"])

    def shapes(self, rig, signals, grid):
        return {"mu_relative": self.warming(rig, signals, grid)[:, None]}

    def signature(self, rig, signals, grid):
        label = "measured oil temperature - reference [K]" if signals.temperature is not None \
            else "modelled oil warming [K]"
        return label, self.warming(rig, signals, grid)

    def simulator_entry(self, values, grid):
        ref = float(grid.get("reference_temperature", 25.0))
        tc = float(grid["time_constant"])
        return {"mu_per_kelvin": float(values["mu_per_kelvin"]),
                "time_constant": tc if tc > 0 else self.default_time_constant,
                "thermal_resistance": self.thermal_resistance, "ambient": ref, "initial": ref}

    def from_simulator_entry(self, entry, rig):
        r_th = float(entry.get("thermal_resistance", self.thermal_resistance))
        return ({"mu_per_kelvin": float(entry.get("mu_per_kelvin", 0.0)) * r_th / self.thermal_resistance},
                {"time_constant": float(entry.get("time_constant", self.default_time_constant)),
                 "reference_temperature": float(entry.get("ambient", 25.0))})


# --------------------------------------------------------------------------- periodic effects
def seen_ripple(rig: Rig, signals: Signals, phase: FloatArray, frequency: FloatArray) -> tuple[FloatArray, FloatArray]:
    """What the quasi-static model sees of sin(phase) and cos(phase) torque ripples [N m per N m].

    A ripple at frequency Omega (order x shaft speed, signed) reaches the residual scaled
    and shifted by D = model.ripple_response (the rotor inertia absorbs fast ripple):
    sin(p) -> Re D sin(p) + Im D cos(p), cos(p) -> Re D cos(p) - Im D sin(p), evaluated at
    the instantaneous frequency (speed changes slowly against the ~10 ms response).
    """
    d = ripple_response(rig, frequency, signals.sample_period, signals.alpha_time_constant)
    s, c = np.sin(phase), np.cos(phase)
    return d.real * s + d.imag * c, d.real * c - d.imag * s


def _angle_in_period(name: str, angle: FloatArray, order: float) -> tuple[str, FloatArray]:
    """(axis label, angle [rad] modulo one period of the order): where in its cycle a ripple is."""
    return f"{name} modulo 2 pi / {order:g} [rad]", np.mod(angle, 2.0 * math.pi / order)


def _phase(sin_part: float, cos_part: float) -> tuple[float, float]:
    """(amplitude, phase) of s sin(x) + c cos(x) = A sin(x + phase)."""
    return math.hypot(sin_part, cos_part), math.atan2(cos_part, sin_part)


class _Ripple(_Base):
    """(A + f L) sin(order angle + phase) on one shaft, L a load; linear as four parameters.

    A sin(x + ph) = A cos(ph) sin(x) + A sin(ph) cos(x): the parameters are the sine and
    cosine parts of the constant amplitude and of the load fraction.
    """

    family = "periodic"
    angle: ClassVar[str] = "theta_worm"
    channel: ClassVar[str] = "worm_torque"
    parameters = (
        Parameter("amplitude_sin", "N m", "load-independent ripple, sine part"),
        Parameter("amplitude_cos", "N m", "load-independent ripple, cosine part"),
        Parameter("load_fraction_sin", "1", "ripple per unit of load, sine part"),
        Parameter("load_fraction_cos", "1", "ripple per unit of load, cosine part"),
    )
    grid_parameters = (GridParameter("order", "1", "cycles per turn of the shaft"),)

    def orders(self, rig: Rig) -> list[float]:
        return [1.0]

    def load(self, rig: Rig, signals: Signals) -> FloatArray:
        return mesh_load(rig, signals)

    def angle_of(self, rig: Rig, signals: Signals) -> FloatArray:
        return getattr(signals, self.angle)

    def grid(self, rig, signals):
        # typical_load: the load at which simulator_entry picks the phase of the larger part
        typical = float(np.median(self.load(rig, signals)))
        return [{"order": float(k), "typical_load": typical} for k in self.orders(rig)]

    def unavailable(self, rig, signals):
        theta = self.angle_of(rig, signals)
        turns = np.sum([np.ptp(theta[signals.run == r]) for r in np.unique(signals.run)]) / (2 * math.pi)
        if turns < 2.0:
            return f"the data cover {turns:.1f} turns of {self.angle}; need at least 2"
        return None

    def rate(self, rig: Rig, signals: Signals) -> FloatArray:
        """Speed of the angle [rad/s] (worm-referenced gear angle: ratio * omega_worm)."""
        return signals.omega * (rig.gearbox.ratio if self.angle == "theta_gear" else 1.0)

    def shapes(self, rig, signals, grid):
        L = self.load(rig, signals)
        sin_col, cos_col = seen_ripple(rig, signals, grid["order"] * self.angle_of(rig, signals),
                                       grid["order"] * self.rate(rig, signals))
        return {self.channel: np.column_stack([sin_col, cos_col, L * sin_col, L * cos_col])}

    def signature(self, rig, signals, grid):
        return _angle_in_period(self.angle, self.angle_of(rig, signals), grid["order"])

    def simulator_entry(self, values, grid):
        # one phase in the simulator: that of the larger part; the other part is projected on it
        a, pa = _phase(values["amplitude_sin"], values["amplitude_cos"])
        f, pf = _phase(values["load_fraction_sin"], values["load_fraction_cos"])
        typical = grid.get("typical_load", 0.0)
        phase = pa if a >= f * typical else pf
        amp = values["amplitude_sin"] * math.cos(phase) + values["amplitude_cos"] * math.sin(phase)
        frac = values["load_fraction_sin"] * math.cos(phase) + values["load_fraction_cos"] * math.sin(phase)
        return {"amplitude": max(0.0, amp), "load_fraction": max(0.0, frac), "phase": phase}

    def from_simulator_entry(self, entry, rig):
        a, f, ph = (float(entry.get(k, 0.0)) for k in ("amplitude", "load_fraction", "phase"))
        values = {"amplitude_sin": a * math.cos(ph), "amplitude_cos": a * math.sin(ph),
                  "load_fraction_sin": f * math.cos(ph), "load_fraction_cos": f * math.sin(ph)}
        return values, {"order": self.orders(rig)[0]}


class WormRunout(_Ripple):
    """Simulator: worm torque -(A + f i mesh_load) sin(theta_worm + phase)."""

    name = "worm_runout"
    description = "worm runout / eccentricity: torque ripple once per worm turn, (A + f i L) sin(theta_w + ph)"

    def load(self, rig, signals):
        return rig.gearbox.ratio * mesh_load(rig, signals)  # the mesh torque at the worm


class ToothPass(_Ripple):
    """Simulator: gear torque (A + f mesh_load) sin(Z_g theta_gear + phase)."""

    name = "tooth_pass"
    description = "mesh (tooth-pass) ripple on the gear shaft: Z_g per gear turn = n (starts) per worm turn"
    angle = "theta_gear"
    channel = "gear_torque"

    def orders(self, rig):
        return [float(rig.gearbox.gear_teeth)]

    def angle_of(self, rig, signals):
        # the gear angle from the worm encoder (ratio * theta_worm, rigid kinematics): at the tooth-pass
        # order the gear encoder's steps (Z_g x 2 pi / counts per turn) would blur the phase 30-fold more
        return rig.gearbox.ratio * signals.theta_worm


class GearRunout(_Ripple):
    """Simulator: gear torque (A + f mesh_load) sin(theta_gear + phase)."""

    name = "gear_runout"
    description = "gear runout: torque ripple on the gear shaft once per gear turn"
    angle = "theta_gear"
    channel = "gear_torque"


class MotorCogging(_Base):
    """Simulator: worm torque -amplitude sin(order theta_worm + phase), order an integer."""

    name = "motor_cogging"
    family = "periodic"
    description = "motor cogging / commutation: torque ripple at the motor's cogging order (per motor turn)"
    max_order: ClassVar[int] = 60
    parameters = (
        Parameter("amplitude_sin", "N m", "cogging torque, sine part"),
        Parameter("amplitude_cos", "N m", "cogging torque, cosine part"),
    )
    grid_parameters = (GridParameter("order", "1", "cogging cycles per motor turn"),)

    def grid(self, rig, signals):
        # orders 1 and n (and the tooth-pass order n) belong to worm_runout / tooth_pass
        skip = {1, rig.gearbox.worm_starts}
        return [{"order": float(k)} for k in range(2, self.max_order + 1) if k not in skip]

    def shapes(self, rig, signals, grid):
        sin_col, cos_col = seen_ripple(rig, signals, grid["order"] * signals.theta_worm,
                                       grid["order"] * signals.omega)
        return {"worm_torque": np.column_stack([sin_col, cos_col])}

    def signature(self, rig, signals, grid):
        return _angle_in_period("theta_worm", signals.theta_worm, grid["order"])

    def simulator_entry(self, values, grid):
        amplitude, phase = _phase(values["amplitude_sin"], values["amplitude_cos"])
        return {"amplitude": amplitude, "order": float(grid["order"]), "phase": phase}

    def from_simulator_entry(self, entry, rig):
        a, ph = float(entry.get("amplitude", 0.0)), float(entry.get("phase", 0.0))
        return {"amplitude_sin": a * math.cos(ph), "amplitude_cos": a * math.sin(ph)}, \
            {"order": float(entry.get("order", 14))}


def gap_crossing(t: FloatArray, drive: FloatArray, run: np.ndarray, gap: float) -> FloatArray:
    """Mesh position p [rad at the gear] inside a clearance of width ``gap`` [rad], per sample.

    p = ratio theta_worm - theta_gear lies in [-gap/2, +gap/2]; it rests on the flank the
    mesh force presses (+gap/2 when the worm pushes the gear forward, drive > 0) and, once
    the force pulls away from that flank, moves freely with p'' = drive [rad/s^2] until it
    reaches a flank, where it stops (an inelastic impact, as in the simulator's plant).
    ``drive`` is taken as samples of a continuous signal, linear between samples: the
    flight starts where it crosses zero, and is integrated exactly for that ramp.  A force
    that turns back before the gap is crossed brings p back to the flank it left: noise on
    the measured load near the switching torque does not flip the flank.  Every run
    starts resting on the flank its first sample presses.
    """
    half = 0.5 * gap
    out = np.empty(len(t))
    drive = np.where(np.isfinite(drive), drive, 0.0)
    for r in np.unique(run):
        idx = np.flatnonzero(run == r)
        tr, a = t[idx], drive[idx]
        n = len(idx)
        p = np.empty(n)
        pulls = {1.0: np.flatnonzero(a < 0.0), -1.0: np.flatnonzero(a > 0.0)}  # samples pulling off each flank
        side = 1.0 if a[0] >= 0.0 else -1.0
        pos, vel, k = side * half, 0.0, 0
        while k < n:
            # resting on `side` up to the first sample j > k that pulls off it
            leave = pulls[side]
            i = np.searchsorted(leave, k + 1)
            if i == len(leave):
                p[k:] = pos
                break
            j = int(leave[i])
            p[k:j] = pos
            # the force crosses zero inside (t[j-1], t[j]) (or at t[j-1]): fly from there to t[j]
            a0, a1 = a[j - 1], a[j]
            frac = a0 / (a0 - a1) if side * a0 > 0.0 else 0.0
            tau = (tr[j] - tr[j - 1]) * (1.0 - frac)
            pos, vel, k = pos + a1 * tau * tau / 6.0, a1 * tau / 2.0, j
            while True:  # free flight, acceleration linear between samples
                if abs(pos) >= half:  # reached a flank (the other, or back on the one it left)
                    side = 1.0 if pos > 0.0 else -1.0
                    pos, vel = side * half, 0.0
                    break
                p[k] = pos
                if k + 1 >= n:
                    k += 1
                    break
                dt = tr[k + 1] - tr[k]
                pos += vel * dt + dt * dt * (2.0 * a[k] + a[k + 1]) / 6.0
                vel += dt * (a[k] + a[k + 1]) / 2.0
                k += 1
        out[idx] = p
    return out


class Backlash(_Base):
    """Simulator: a dead zone of ``angle`` [rad at the gear] crossed at every flank change.

    Evidence is in position, not in the current: with a gear encoder the transmission
    error ratio theta_worm - theta_gear sits on one flank of the clearance while the
    mesh force G (gear side, fixed frame: + when the worm pushes the gear forward)
    presses it, and moves to the other when G changes sign (the load crossing the
    switching torque, or a reversal).  Its regressor is the mesh position
    :func:`gap_crossing` computes from the model's G (driven by p'' = G / J_eff,
    1/J_eff = 1/J_g + i (r_w/r_g) K_s / J_w: the gear's own inertia and the small part
    the freed worm adds) per unit of gap, so the coefficient *is* the gap; the gap that
    times the crossing is searched on a grid.  The fitted signal is the transmission
    error (fitting.fit_te: per-run encoder offsets plus this term).  In the drive current
    backlash leaves only a few-ms transient at each flank change, of the size of the
    declared model's own transient error there, so no current term is fitted for it.
    """

    name = "backlash"
    fitted_signal = "transmission_error"
    description = "backlash: the transmission error jumps by the gap when the mesh force changes flank"
    parameters = (Parameter("angle", "rad", "circumferential clearance at the gear shaft"),)
    grid_parameters = (GridParameter("crossing_angle", "rad", "gap that times the crossing (grid)"),)

    def grid(self, rig, signals):
        return [{"crossing_angle": float(a)} for a in np.geomspace(math.radians(1.0 / 60.0), math.radians(2.0), 10)]

    def unavailable(self, rig, signals):
        if signals.transmission_error is None:
            return "needs theta_gear (a gear encoder): without it backlash shows only as ms transients in the current"
        state = evaluate(rig, signals)
        side = state.sigma * state.flank
        if not np.any((np.diff(side) != 0) & (np.diff(signals.run) == 0)):
            return "the mesh force never changes sign (no flank change in the data)"
        return None

    def shapes(self, rig, signals, grid):
        return {}  # nothing on the current channels

    def mesh_drive(self, rig: Rig, state: ModelState) -> FloatArray:
        """p'' [rad/s^2] while the teeth are apart: G (fixed frame) / J_eff."""
        gb = rig.gearbox
        inverse = 1.0 / rig.total_gear_inertia + gb.ratio * gb.radius_ratio * np.abs(state.flank_factor) \
            / rig.total_worm_inertia
        return state.sigma * state.mesh_demand * inverse

    def te_columns(self, rig, signals, state, grid):
        gap = grid["crossing_angle"]
        return (gap_crossing(signals.t, self.mesh_drive(rig, state), signals.run, gap) / gap)[:, None]

    def signature(self, rig, signals, grid):
        state = evaluate(rig, signals)
        return "modelled mesh position / gap", self.te_columns(rig, signals, state, grid)[:, 0]

    def simulator_entry(self, values, grid):
        return {"angle": max(0.0, float(values["angle"]))}

    def from_simulator_entry(self, entry, rig):
        angle = float(entry.get("angle", 0.0))
        return {"angle": angle}, {"crossing_angle": angle}


# --------------------------------------------------------------------------- sampling of the PWM ripple
#: PWM frequency [Hz] of the firmware's H-bridges: timers 4/5 in fast PWM with TOP = PWM_TOP = 799 at
#: 16 MHz, 16e6 / 800 = 20 kHz (firmware/motors.c; worm_rig_driver protocol/table.py PWM_TOP, the
#: simulator's pwm default).  A constant here: worm_model does not import the driver package.
PWM_FREQUENCY = 20_000.0
#: [s] from the firmware's sample tick to the instant the ADC holds the drive current: the drive current is
#: the first conversion of the tick's sequence (firmware/adc_mux.c: step 0 = current of motor 0), held 1.5
#: ADC clocks after its start, ADC clock 16 MHz / 128 (adc_mux_init's prescaler): 1.5 x 8 us = 12 us
#: (worm_rig_driver sim/sensors.py AdcChain.sample_times()["current_drive"], the instant the simulator
#: samples the current at and hands to its pwm effect as channel_time).
CURRENT_HOLD_DELAY = 1.5 * 128 / 16e6


def firmware_sampling_phase(frequency: float = PWM_FREQUENCY, sample_rate: float = 1000.0) -> float | None:
    """PWM phase [periods, 0..1) at which the firmware's ADC samples the drive current; None if it walks.

    The 1 kHz tick (timer 0: 16 MHz / 64 / 250) and the PWM (timers 4/5: 16 MHz / 800) run from the same
    crystal, so a tick is exactly ``frequency / sample_rate`` = 20 PWM periods and every sample falls at the
    same phase, ``CURRENT_HOLD_DELAY x frequency`` = 12 us / 50 us = 0.24 in the simulator (its PWM and its
    ticks both start at t = 0, no interrupt latency).  On the real board the offset between timer 0 and
    timers 4/5 (started one after the other at boot) and the tick ISR's latency move it: hence a grid
    parameter of :class:`Pwm`, fitted from the data.  A frequency that is not a whole multiple of the sample
    rate makes the phase walk from sample to sample (None): the ripple then averages out and is noise.
    """
    periods = frequency / sample_rate
    if abs(periods - round(periods)) > 1e-9 * max(periods, 1.0):
        return None
    return (CURRENT_HOLD_DELAY * frequency) % 1.0


def sampled_ripple(duty: FloatArray, phase: float) -> FloatArray:
    """The PWM ripple the ADC samples at ``phase`` [periods], per unit of V_s / (L f) [1], as a function of duty d.

    Sign-magnitude PWM: the armature current rises for d / f and falls for (1 - d) / f, a triangle of
    peak to peak V_s d (1 - d) / (L f) about its mean (L f >> R).  Sampled at phase p of the period
    (switch-on at p = 0) the deviation from the mean is d (1 - d) x shape, shape = -1/2 + p/d while p < d
    (rising), 1/2 - (p - d)/(1 - d) after (falling) -- the simulator's pwm effect.  Multiplied out, without
    a division at d = 0 or 1 (where the ripple vanishes):

        d (1 - d) shape = p (1 - d) - d (1 - d) / 2 - max(p - d, 0)

    (for the current in the direction of the voltage; the caller applies sign(V)).  ``duty`` is clipped to [0, 1].
    """
    d = np.clip(duty, 0.0, 1.0)
    return phase * (1.0 - d) - 0.5 * d * (1.0 - d) - np.maximum(phase - d, 0.0)


class Pwm(_Base):
    """Simulator ``pwm``: the PWM current ripple, sampled by the ADC at a phase fixed by the firmware's timing.

    The plant (and the declared model) carry the mean armature current; the ADC samples the
    triangular PWM ripple on top of it (:func:`sampled_ripple`), attenuated by the Hall sensor's
    first-order filter.  Because a sample period is a whole number of PWM periods the sampling phase
    p is the same on every sample, so what is left in the current is not noise but a *bias* that
    depends on the operating point through the duty d = |V| / V_s:

        current += sign(V) x amplitude x sampled_ripple(d, p)                       [A]
        amplitude = V_s / (L f) / sqrt(1 + (f / f_c)^2)                             [A]

    f the PWM frequency (:data:`PWM_FREQUENCY`), L the drive motor's inductance, V_s the supply,
    f_c the current sensor filter's cut-off.  V [V] is the drive voltage the model implies at steady
    state, V = R i_true + K_e omega_worm (Eq. 29 without L di/dt, which the 1 kHz means do not
    resolve): i_true from the declared model (model.evaluate), i.e. without the other effects'
    channels (their few tens of mA move d by ~R x 0.03 / 24 ~ 0.2 %), and the measured current is
    not used, so the regressor is free of the current noise.  The analysis caches the shapes with
    the first rig it screens them on (its refit of the declared model): later corrections of a few
    % move d by less than the phase grid's step.  Signs: V and the current + drive
    + rotation (model.py); the bias has the sign of V (the ripple triangle is the same in either
    direction of the bridge).

    Parameters: ``amplitude`` [A], linear; ``phase`` [periods, 0..1) on a grid of ``phases`` steps
    (1/50 = 1 us: the simulator's 0.24 lies on it).  The grid values also carry ``frequency`` [Hz]
    and ``full_ripple`` = V_s / (L f) [A], the rig's unfiltered ripple scale, so that
    :meth:`simulator_entry` (which gets no rig) can turn the amplitude into a filter cut-off.

    Translation: the simulator's entry has ``frequency``, ``duty_levels`` and ``filter_cutoff``, and
    no phase: its phase is fixed by the (simulated) firmware's timing (:func:`firmware_sampling_phase`).
    So :meth:`from_simulator_entry` takes the phase from that timing, and :meth:`simulator_entry`
    writes the fitted amplitude as a filter cut-off and loses the fitted phase (on the real board it
    may differ from the simulator's).  ``duty_levels`` (the duty resolution) is left to the
    simulator's default: a duty step of V_s / 800 moves the speed, not the steady current.  Much of
    the bias's constant and linear part, p (1 - d) sign(V) = p sign(V) - p V / V_s, is the same
    function of the data as the refitted Coulomb drag, viscous drag and K_t; its d (1 - d) and hinge
    max(p - d, 0) terms are what the analysis sees.
    """

    name = "pwm"
    description = ("PWM current ripple sampled at a fixed phase of the PWM period: a bias "
                   "sign(V) A [p (1 - d) - d (1 - d)/2 - max(p - d, 0)] at duty d = |R i + K_e omega| / V_s")
    frequency: ClassVar[float] = PWM_FREQUENCY
    phases: ClassVar[int] = 50
    #: the simulator's default filter cut-off [Hz] (an ACS712 with C_F = 47 nF, an assumption there)
    filter_cutoff: ClassVar[float] = 2000.0
    #: cut-off [Hz] written for an amplitude at or beyond the unfiltered ripple (the simulator's largest plausible Hz)
    max_filter_cutoff: ClassVar[float] = 1e5
    #: cut-off [Hz] written for an amplitude <= 0, which the simulator cannot make: no ripple to speak of
    min_filter_cutoff: ClassVar[float] = 1e-3
    parameters = (Parameter("amplitude", "A", "V_s / (L f) x the current sensor filter's attenuation"),)
    grid_parameters = (GridParameter("phase", "1", "PWM phase of the drive current's ADC sampling instant "
                                                  "[periods, 0 = switch-on]"),)

    def full_ripple(self, rig: Rig, frequency: float | None = None) -> float:
        """V_s / (L f) [A]: four times the largest peak-to-peak ripple (at d = 1/2), before the sensor's filter."""
        return rig.supply_voltage / (rig.drive_motor.inductance * (frequency or self.frequency))

    def drive_voltage(self, rig: Rig, signals: Signals) -> FloatArray:
        """V = R i_true + K_e omega_worm [V] by the declared model at steady state (class docstring)."""
        m = rig.drive_motor
        v = m.resistance * evaluate(rig, signals).current_true + m.back_emf_constant * signals.omega
        return np.where(np.isfinite(v), v, 0.0)  # a sample the model cannot evaluate gets no ripple

    def duty(self, rig: Rig, signals: Signals) -> FloatArray:
        """|V| / V_s [1], clipped to [0, 1] (beyond it the bridge is saturated: no ripple)."""
        return np.clip(np.abs(self.drive_voltage(rig, signals)) / rig.supply_voltage, 0.0, 1.0)

    def grid(self, rig, signals):
        full = self.full_ripple(rig)
        return [{"phase": k / self.phases, "frequency": self.frequency, "full_ripple": full}
                for k in range(self.phases)]

    def unavailable(self, rig, signals):
        if firmware_sampling_phase(self.frequency, rig.sensors.sample_rate_hz) is None:
            return (f"the PWM ({self.frequency:g} Hz) is not a whole multiple of the sample rate "
                    f"({rig.sensors.sample_rate_hz:g} Hz): the sampling phase walks and the ripple averages out")
        return None

    def shapes(self, rig, signals, grid):
        v = self.drive_voltage(rig, signals)
        d = np.clip(np.abs(v) / rig.supply_voltage, 0.0, 1.0)
        return {"current": (np.sign(v) * sampled_ripple(d, grid["phase"]))[:, None]}

    def signature(self, rig, signals, grid):
        return "modelled duty |R i + K_e omega| / V_s [1]", self.duty(rig, signals)

    def simulator_entry(self, values, grid):
        # amplitude = full / sqrt(1 + (f / f_c)^2)  ->  f_c = f a / sqrt(1 - a^2), a = amplitude / full
        f = float(grid.get("frequency", self.frequency))
        a = float(values["amplitude"]) / float(grid["full_ripple"])
        if a <= 0.0:
            cutoff = self.min_filter_cutoff
        elif a >= 1.0:
            cutoff = self.max_filter_cutoff
        else:
            cutoff = min(max(f * a / math.sqrt(1.0 - a * a), self.min_filter_cutoff), self.max_filter_cutoff)
        return {"frequency": f, "filter_cutoff": cutoff}

    def from_simulator_entry(self, entry, rig):
        f = float(entry.get("frequency", self.frequency))
        cutoff = float(entry.get("filter_cutoff", self.filter_cutoff))
        full = self.full_ripple(rig, f)
        phase = firmware_sampling_phase(f, rig.sensors.sample_rate_hz)
        # a walking sampling phase (f not a multiple of the sample rate) leaves no bias: amplitude 0
        amplitude = 0.0 if phase is None else full / math.sqrt(1.0 + (f / cutoff) ** 2)
        return {"amplitude": amplitude}, {"phase": 0.0 if phase is None else phase, "frequency": f,
                                          "full_ripple": full}


#: effect name -> plug-in instance (the vocabulary of physics.md section 9)
EFFECTS: dict[str, Effect] = {e.name: e for e in (
    BearingCoulomb(), ViscousDrag(), SpeedDependentMu(), LoadDependentMu(), OilTemperature(),
    WormRunout(), ToothPass(), GearRunout(), MotorCogging(), Backlash(),
    SensorGain(), SensorOffset(), InertiaError(), Pwm(),
)}


# --------------------------------------------------------------------------- helpers used by the analysis
def channels_of(effects: Sequence[tuple[Effect, Mapping[str, float], Mapping[str, float]]],
                rig: Rig, signals: Signals, shapes: Sequence[Shapes] | None = None) -> Channels:
    """Channel contributions of fitted effects: [(effect, values, grid), ...]."""
    ch = Channels()
    for k, (effect, values, grid) in enumerate(effects):
        sh = shapes[k] if shapes is not None else effect.shapes(rig, signals, grid)
        v = np.array([values[p.name] for p in effect.parameters])
        for channel, cols in sh.items():
            ch.add(channel, cols @ v)
    return ch


def regressors(effect: Effect, rig: Rig, signals: Signals, state: ModelState, shapes: Shapes,
               sens: Mapping[str, FloatArray] | None = None) -> FloatArray:
    """(n, p) d current / d parameter [A per parameter unit] at the model state (sens: precomputed sensitivities)."""
    sens = sens if sens is not None else sensitivities(rig, signals, state)
    total = np.zeros((len(signals), len(effect.parameters)))
    for channel, cols in shapes.items():
        total += sens[channel][:, None] * cols
    return total


def mask_shapes(shapes: Shapes, mask: np.ndarray) -> Shapes:
    return {k: v[mask] for k, v in shapes.items()}


assert all(c in CHANNELS for c in ("mu_relative", "worm_torque", "gear_torque", "current_gain", "current"))
