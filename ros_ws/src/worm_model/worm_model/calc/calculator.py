"""Core of the ``worm_calc`` command: one worm-gear operating point through the model.

Two questions, each a plain function returning a flat dict of SI numbers (the CLI prints
it, or dumps it as JSON):

* :func:`forces` -- internal forces from torques (paper Eqs 21-23): given tau_in on the
  worm, tau_d on the gear and optionally the worm speed and acceleration, the contact's
  normal and friction forces, mu, mode and flank, the force components and the powers.
* :func:`efficiencies` -- from a friction coefficient: forward and back-driving
  efficiency and whether the drive self-locks (reference section 6).

Conventions are those of :mod:`worm_model.physics.internal_forces` (fixed frame, tau_d + opposes
+ worm rotation).  Geometry: :func:`make_gearbox` builds a gearbox from pitch radii, lead
angle and normal pressure angle alone, with the speed ratio i = r_w tan(lambda) / r_g that
this geometry implies (Eq. 26; the numbers of starts and teeth are not needed).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from worm_model.physics.efficiency import backward_efficiency, forward_efficiency, friction_angle, is_self_locking
from worm_model.physics.friction import sliding_velocity
from worm_model.physics.internal_forces import internal_forces, mesh_force_components
from worm_model.physics.modes import Flank, Mode
from worm_model.physics.parameters import Gearbox
from worm_model.errors import CalculatorError


#: JSON names of the modes and flanks
MODE_NAMES = {Mode.STANDSTILL: "standstill", Mode.RESISTIVE: "resistive",
              Mode.PSEUDO_RESISTIVE: "pseudo_resistive", Mode.ASSISTIVE: "assistive"}
FLANK_NAMES = {Flank.DRIVING: "driving", Flank.COAST: "coast", Flank.NONE: "none"}


def _finite(name: str, value: float) -> float:
    if not math.isfinite(value):
        raise CalculatorError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def make_gearbox(base: Gearbox, worm_radius: float, gear_radius: float, lead_angle: float,
                 pressure_angle: float, worm_inertia: float | None = None,
                 gear_inertia: float | None = None) -> Gearbox:
    """``base`` with new geometry (SI, angles in rad) and, if given, new shaft inertias.

    The ratio n/Z of ``base`` is not used by this module (the speed ratio is
    ``geometric_ratio``), so it is left as it is.

    Raises:
        CalculatorError: radius <= 0, lead angle outside (0, 90 deg), pressure angle
            outside [0, 90 deg), inertia < 0, or a non-finite value.
    """
    checks = {
        "worm pitch radius": (worm_radius, lambda x: x > 0, "must be > 0 m"),
        "gear pitch radius": (gear_radius, lambda x: x > 0, "must be > 0 m"),
        "lead angle": (lead_angle, lambda x: 0 < x < math.pi / 2, "must lie in (0, 90) deg"),
        "normal pressure angle": (pressure_angle, lambda x: 0 <= x < math.pi / 2, "must lie in [0, 90) deg"),
    }
    if worm_inertia is not None:
        checks["worm inertia"] = (worm_inertia, lambda x: x >= 0, "must be >= 0 kg m^2")
    if gear_inertia is not None:
        checks["gear inertia"] = (gear_inertia, lambda x: x >= 0, "must be >= 0 kg m^2")
    for name, (value, ok, message) in checks.items():
        if not ok(_finite(name, value)):
            shown = f"{math.degrees(value):g} deg" if "angle" in name else f"{value:g}"
            raise CalculatorError(f"{name} {shown}: {message}")
    return dataclasses.replace(
        base,
        worm_pitch_radius=float(worm_radius),
        gear_pitch_radius=float(gear_radius),
        lead_angle=float(lead_angle),
        normal_pressure_angle=float(pressure_angle),
        worm_inertia=base.worm_inertia if worm_inertia is None else float(worm_inertia),
        gear_inertia=base.gear_inertia if gear_inertia is None else float(gear_inertia),
    )


def geometry(gearbox: Gearbox) -> dict[str, float]:
    """The geometry echoed in every answer (SI, angles also in deg)."""
    return {
        "worm_pitch_radius": gearbox.worm_pitch_radius,
        "gear_pitch_radius": gearbox.gear_pitch_radius,
        "lead_angle": gearbox.lead_angle,
        "lead_angle_deg": math.degrees(gearbox.lead_angle),
        "normal_pressure_angle": gearbox.normal_pressure_angle,
        "normal_pressure_angle_deg": math.degrees(gearbox.normal_pressure_angle),
        "speed_ratio": gearbox.geometric_ratio,
        "mu_max": gearbox.mu_engagement_max,
        "self_locking_mu": gearbox.self_locking_mu,
    }


def forces(gearbox: Gearbox, tau_in: float, tau_d: float, omega_worm: float | None = None,
           alpha_worm: float = 0.0, switching_torque: float = 0.0) -> dict[str, Any]:
    """Internal forces of one operating point (Eqs 21-23) with components and powers.

    Args:
        gearbox: geometry and shaft inertias (worm_inertia, gear_inertia [kg m^2]).
        tau_in: torque on the worm shaft [N m], + drives + worm rotation.
        tau_d: load torque on the gear shaft [N m], + opposes + worm rotation.
        omega_worm: worm speed [rad/s]; its sign sets the direction of motion.  None: the
            direction is that of tau_in, and the speed-dependent outputs (sliding
            velocity, powers) are None.  0 is standstill (mode "standstill", forces are
            the statics).
        alpha_worm: worm acceleration [rad/s^2]; the gear's is i * alpha_worm (Eq. 27).
        switching_torque: tau_sw >= 0 [N m] for the mode classification (0: pure model).
    Returns:
        dict (JSON-able, NaN as float nan): the geometry of :func:`geometry`, the inputs,
        and normal_force, friction_force [N], mu, mu_valid, mode (name), flank (name),
        flank_sign, valid, worm_tangential_force = gear_axial_force,
        gear_tangential_force = worm_axial_force, radial_force [N], sliding_velocity [m/s],
        input_power, output_power, friction_power [W] (input = output + friction).
    Raises:
        CalculatorError: a non-finite input, a negative switching torque, or torques that would make the
            mesh a source of energy (mu < 0: more power out than in).
    """
    for name, value in (("tau_in", tau_in), ("tau_d", tau_d), ("alpha_worm", alpha_worm),
                        ("switching_torque", switching_torque)):
        _finite(name, value)
    if omega_worm is not None:
        _finite("omega_worm", omega_worm)
    if switching_torque < 0:
        raise CalculatorError(f"switching_torque {switching_torque:g} N m: must be >= 0")
    # without a speed, a nominal speed in the direction of tau_in fixes the frame of motion
    omega = (1.0 if tau_in >= 0 else -1.0) if omega_worm is None else omega_worm
    ratio = gearbox.geometric_ratio
    f = internal_forces(gearbox, tau_in, tau_d, omega, alpha_worm, ratio * alpha_worm, switching_torque)
    c = mesh_force_components(gearbox, f.normal_force, f.friction_force, f.flank)
    out: dict[str, Any] = geometry(gearbox)
    out.update({
        "worm_inertia": gearbox.worm_inertia,
        "gear_inertia": gearbox.gear_inertia,
        "tau_in": float(tau_in),
        "tau_d": float(tau_d),
        "omega_worm": None if omega_worm is None else float(omega_worm),
        "alpha_worm": float(alpha_worm),
        "switching_torque": float(switching_torque),
        "normal_force": float(f.normal_force),
        "friction_force": float(f.friction_force),
        "mu": float(f.mu),
        "mu_valid": bool(f.mu_valid),
        "mode": MODE_NAMES[Mode(int(f.mode))],
        "flank": FLANK_NAMES[Flank(int(f.flank))],
        "flank_sign": int(f.flank),
        "valid": bool(f.valid),
        "worm_tangential_force": float(c.worm_tangential),
        "gear_axial_force": float(c.worm_tangential),
        "gear_tangential_force": float(c.gear_tangential),
        "worm_axial_force": float(c.gear_tangential),
        "radial_force": float(c.radial),
        "sliding_velocity": None,
        "input_power": None,
        "output_power": None,
        "friction_power": None,
    })
    _conserves_energy(gearbox, tau_in, tau_d, omega_worm, float(f.mu))
    overflowed = [k for k, v in out.items() if isinstance(v, float) and math.isinf(v)]
    if overflowed:
        raise CalculatorError(f"{overflowed[0]} overflows (inf) for these inputs: they are far outside any gear set")
    if omega_worm is not None:
        v_s = float(sliding_velocity(gearbox, omega_worm))
        omega_gear = ratio * omega_worm
        out.update({
            "sliding_velocity": v_s,
            # powers at the mesh: what the worm shaft puts in (less its inertia's share)
            "input_power": float((tau_in - gearbox.worm_inertia * alpha_worm) * omega_worm),
            "output_power": float((tau_d + gearbox.gear_inertia * ratio * alpha_worm) * omega_gear),
            "friction_power": float(f.friction_force) * v_s,
        })
    return out


def _conserves_energy(gearbox: Gearbox, tau_in: float, tau_d: float, omega_worm: float | None, mu: float) -> None:
    """Refuse torques that make the mesh a source of energy: friction can only take power out, so mu >= 0.

    A negative mu means more power leaves the mesh than enters it (in resistive mode: more at the gear than
    the worm puts in), which no gear set does; the likely cause is a torque in the wrong unit or sign.
    """
    if not (math.isfinite(mu) and mu < 0.0):
        return
    if omega_worm is not None and omega_worm != 0.0:
        p_in = tau_in * omega_worm
        p_out = tau_d * gearbox.geometric_ratio * omega_worm
        flow = (f"the worm puts {p_in:.4g} W in and the gear takes {p_out:.4g} W out" if p_in >= 0 else
                f"the gear puts {-p_out:.4g} W in and the worm takes {-p_in:.4g} W out")
        raise CalculatorError(f"--tau-in {tau_in:g} N m with --tau-load {tau_d:g} N m at --omega {omega_worm:g} "
                              f"rad/s: {flow}, more out than in (mu = {mu:.3g} < 0): no gear set makes energy; "
                              "check the torques' units and signs (tau_d + opposes + worm rotation)")
    raise CalculatorError(f"--tau-in {tau_in:g} N m with --tau-load {tau_d:g} N m: mu = {mu:.3g} < 0, friction "
                          "that would feed energy into the mesh: no gear set does; check the torques' units and "
                          "signs (tau_d + opposes + worm rotation)")


def efficiencies(gearbox: Gearbox, mu: float) -> dict[str, Any]:
    """Forward and back-driving efficiency at friction coefficient mu (reference section 6).

    Args:
        mu: tooth-thread friction coefficient, >= 0.
    Returns:
        dict: the geometry of :func:`geometry`, mu, friction_angle [rad] and _deg,
        efficiency_forward (worm drives gear, tan(lambda)/tan(lambda + rho')),
        efficiency_backward (gear drives worm, tan(lambda - rho')/tan(lambda); <= 0 when
        self-locking), self_locking (mu > cos(phi_n) tan(lambda)), and
        forward_drive_possible (mu < mu_max, Remark 4; always true, as larger mu are refused).
    Raises:
        CalculatorError: mu negative, not finite, or at or beyond mu_max (Remark 4).
    """
    if not _finite("mu", mu) >= 0:
        raise CalculatorError(f"mu {mu:g}: must be >= 0")
    if mu >= gearbox.mu_engagement_max:
        raise CalculatorError(f"mu {mu:g} is at or beyond the Remark-4 bound mu_max = cos(phi_n) cot(lambda) = "
                              f"{gearbox.mu_engagement_max:.4g} of this geometry: the driving flank does not "
                              "engage, there is no efficiency to compute")
    rho = float(friction_angle(gearbox, mu))
    out: dict[str, Any] = geometry(gearbox)
    out.update({
        "mu": float(mu),
        "friction_angle": rho,
        "friction_angle_deg": math.degrees(rho),
        "efficiency_forward": float(forward_efficiency(gearbox, mu)),
        "efficiency_backward": float(backward_efficiency(gearbox, mu)),
        "self_locking": bool(is_self_locking(gearbox, mu)),
        "forward_drive_possible": bool(mu < gearbox.mu_engagement_max),
    })
    return out


def to_json_ready(result: dict[str, Any]) -> dict[str, Any]:
    """NaN/inf -> None so the dict dumps as strict JSON."""
    def clean(v: Any) -> Any:
        if isinstance(v, (float, np.floating)) and not math.isfinite(v):
            return None
        return v
    return {k: clean(v) for k, v in result.items()}
