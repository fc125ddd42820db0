"""Regressors of effects that change the friction and the readings: drags, mu's speed and load laws, sensor
gain and offset errors, the worm shaft's inertia (family "regression")."""
from __future__ import annotations

from typing import ClassVar

import numpy as np

from worm_model.effects import VOCABULARY
from worm_model.physics.friction import sliding_velocity
from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects.base import (Coefficient, GridParameter, Signals, _Base, _column, _sigma, mesh_load,
                                               regresses)


@regresses
class BearingCoulomb(_Base):
    """Simulator: worm -worm_torque sign(omega_worm), gear +gear_torque sign(omega_gear)."""

    name = "bearing_coulomb"
    description = "bearing/seal Coulomb drag on the worm and gear shafts: a step with sign(omega)"
    parameters = (
        Coefficient.of("bearing_coulomb", "worm_torque"),
        Coefficient.of("bearing_coulomb", "gear_torque"),
    )

    def shapes(self, rig, signals, grid):
        s, n = _sigma(signals), len(signals)
        return {"worm_torque": _column(n, 2, 0, s), "gear_torque": _column(n, 2, 1, s)}

    def simulator_entry(self, values, grid):
        # the simulator's drags are magnitudes (>= 0)
        return {p.name: max(0.0, float(values[p.name])) for p in self.parameters}


@regresses
class ViscousDrag(_Base):
    """Simulator: T_ref (|omega| / omega_ref)^exponent on each shaft, gear term at the worm speed."""

    name = "viscous_drag"
    description = "viscous and oil-churning drag, T_ref (|omega_worm| / omega_ref)^p on the worm and gear shafts"
    #: [rad/s] the worm speed the fitted torques are at: the declared default omega_ref
    reference_speed: ClassVar[float] = VOCABULARY["viscous_drag"].default("reference_speed")
    parameters = (
        Coefficient.of("viscous_drag", "worm_torque"),
        Coefficient.of("viscous_drag", "gear_torque"),
    )
    grid_parameters = (GridParameter.of("viscous_drag", "exponent"),)

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


@regresses
class SpeedDependentMu(_Base):
    """Simulator: mu = mu_rig(V_s) (1 + low_speed_gain exp(-V_s / stribeck_speed))."""

    name = "speed_dependent_mu"
    description = "Stribeck rise of mu at low sliding speed: mu *= 1 + gain exp(-V_s / v_stribeck)"
    parameters = (Coefficient.of("speed_dependent_mu", "low_speed_gain"),)
    grid_parameters = (GridParameter.of("speed_dependent_mu", "stribeck_speed"),)

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
                {"stribeck_speed": float(entry.get("stribeck_speed", VOCABULARY[self.name].default("stribeck_speed")))})


@regresses
class LoadDependentMu(_Base):
    """Simulator: mu = mu_rig (1 + sensitivity mesh_load / reference_torque)."""

    name = "load_dependent_mu"
    description = "mu changing with the transmitted torque: mu *= 1 + sensitivity |mesh load| / 0.25 N m"
    #: [N m] the mesh load the fitted sensitivity is at: the declared default
    reference_torque: ClassVar[float] = VOCABULARY["load_dependent_mu"].default("reference_torque")
    parameters = (Coefficient.of("load_dependent_mu", "sensitivity"),)

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


@regresses
class SensorGain(_SensorError):
    """Simulator: reading = (1 + gain) x true, per sensor (drive current, load currents, tachos)."""

    name = "sensor_gain"
    description = "current-sensor gain errors: drive current x (1 + g_d); measured tau_load x (1 + g_l)"
    drive_channel = "current_gain"
    parameters = (
        Coefficient.of("sensor_gain", "drive_current"),
        Coefficient.of("sensor_gain", "load_current"),
    )

    def load_torque_error(self, rig, signals):
        return signals.tau_load  # measured = (1 + g_l) true: error g_l tau_load to first order

    def signature(self, rig, signals, grid):
        return "tau_load [N m]", signals.tau_load


@regresses
class SensorOffset(_SensorError):
    """Simulator: reading = true + offset, per sensor."""

    name = "sensor_offset"
    description = "current-sensor offsets: drive current + o_d; each load current + o_l (tau_load)"
    drive_channel = "current"
    parameters = (
        Coefficient.of("sensor_offset", "drive_current"),
        Coefficient.of("sensor_offset", "load_current"),
    )

    def load_torque_error(self, rig, signals):
        # tau_load per A of offset on each sensor
        return np.full(len(signals), rig.load_motor.torque_constant * rig.load_motor_count)

    def signature(self, rig, signals, grid):
        return "t [s]", signals.t


@regresses
class InertiaError(_Base):
    """Simulator: J_true = (1 + worm) J_worm,file and (1 + gear) J_gear,file."""

    name = "inertia_error"
    description = "error of the declared worm-shaft inertia (worm + rotor): residual proportional to alpha"
    # The gear shaft's inertia reaches the drive current through i (r_w/r_g) K_s ~ 0.2 % of the
    # worm side's: not identifiable from the current, so only the worm part is fitted.
    parameters = (Coefficient.of("inertia_error", "worm"),)

    def shapes(self, rig, signals, grid):
        return {"worm_inertia": np.full((len(signals), 1), rig.total_worm_inertia)}

    def signature(self, rig, signals, grid):
        return "alpha_worm [rad/s^2]", signals.alpha

    def simulator_entry(self, values, grid):
        return {"worm": float(values["worm"]), "gear": 0.0}
