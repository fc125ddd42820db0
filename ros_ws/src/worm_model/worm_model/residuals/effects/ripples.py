"""Regressors of torque ripples periodic in a shaft angle: worm and gear runout, the tooth pass, motor cogging
(family "periodic")."""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from worm_model.effects import VOCABULARY
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects.base import Coefficient, GridParameter, _Base, mesh_load, regresses
from worm_model.residuals.model import Signals, ripple_response


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
        Coefficient("amplitude_sin", "N m", "load-independent ripple, sine part"),
        Coefficient("amplitude_cos", "N m", "load-independent ripple, cosine part"),
        Coefficient("load_fraction_sin", "1", "ripple per unit of load, sine part"),
        Coefficient("load_fraction_cos", "1", "ripple per unit of load, cosine part"),
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


@regresses
class WormRunout(_Ripple):
    """Simulator: worm torque -(A + f i mesh_load) sin(theta_worm + phase)."""

    name = "worm_runout"
    description = "worm runout / eccentricity: torque ripple once per worm turn, (A + f i L) sin(theta_w + ph)"

    def load(self, rig, signals):
        return rig.gearbox.ratio * mesh_load(rig, signals)  # the mesh torque at the worm


@regresses
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


@regresses
class GearRunout(_Ripple):
    """Simulator: gear torque (A + f mesh_load) sin(theta_gear + phase)."""

    name = "gear_runout"
    description = "gear runout: torque ripple on the gear shaft once per gear turn"
    angle = "theta_gear"
    channel = "gear_torque"


@regresses
class MotorCogging(_Base):
    """Simulator: worm torque -amplitude sin(order theta_worm + phase), order an integer."""

    name = "motor_cogging"
    family = "periodic"
    description = "motor cogging / commutation: torque ripple at the motor's cogging order (per motor turn)"
    max_order: ClassVar[int] = 60
    parameters = (
        Coefficient("amplitude_sin", "N m", "cogging torque, sine part"),
        Coefficient("amplitude_cos", "N m", "cogging torque, cosine part"),
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
            {"order": float(entry.get("order", VOCABULARY[self.name].default("order")))}
