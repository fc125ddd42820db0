"""model_node's per-sample processing as a plain class: one rig sample in, the mesh's forces out.

For every sample (ω_w [rad/s], i_drive [A], τ_load [N·m], physics.md §2 signs:
positive worm rotation is the reference, τ_load > 0 opposes it):

* the input torque at the worm is the drive motor's torque less its declared
  drags (motor.shaft_torque, Eq. 29), taken before the rotor's inertia, so the
  shafts' total inertias apply below;
* the gear shaft carries the measured load torque plus the load motors'
  declared drag (gear_side.gear_side_load);
* the worm acceleration α_w [rad/s²] is the filtered derivative of the
  tachogenerator speed (filters.FilteredDerivative; 0 if quasi-static);
* internal forces N, F_f, μ (internal_forces, Eqs 21-23), the switching
  torque τ_sw, the mode (section 3) and the engaged flank follow, with the
  flags of worm_msgs/GearboxForces.

A NaN/inf input gives NaN forces flagged INVALID_INPUT; a NaN/inf speed is
skipped by the acceleration filter (its state is kept for the next sample). Used by model_node and by the offline replay
(torque_estimator.offline.replay), so both run the same code. No ROS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from enum import IntFlag
from typing import Protocol

import numpy as np

from worm_model.live.filters import FilteredDerivative
from worm_model.physics.gear_side import gear_side_load, no_load_switching_torque
from worm_model.physics.internal_forces import internal_forces
from worm_model.physics.modes import classify_mode, motion_sign
from worm_model.physics.motor import shaft_torque
from worm_model.physics.parameters import Rig


class ForceFlags(IntFlag):
    """Quality bits of one sample's forces; the values of worm_msgs/GearboxForces FLAG_*."""

    NONE = 0
    #: ω_w, i_drive or τ_load was NaN/inf; the forces are NaN.
    INVALID_INPUT = 1
    #: No frame of motion (worm at rest): the forces are undefined.
    STANDSTILL = 2
    #: μ outside [0, μ_max]: an artefact of the inputs, not friction (physics.md §5).
    MU_OUT_OF_BOUND = 4


# plain ints on the per-sample path (IntFlag arithmetic costs microseconds per sample)
_INVALID_INPUT, _STANDSTILL = int(ForceFlags.INVALID_INPUT), int(ForceFlags.STANDSTILL)
_MU_OUT_OF_BOUND = int(ForceFlags.MU_OUT_OF_BOUND)


class RigSampleLike(Protocol):
    """What :meth:`LiveModel.update` reads of a sample (worm_msgs/RigSample has it)."""

    omega_worm: float
    current_drive: float
    tau_load: float


@dataclass(frozen=True)
class LiveForces:
    """One sample's forces: the fields of worm_msgs/GearboxForces but header and seq.

    Attributes:
        normal_force: N [N] (≥ 0); friction_force: F_f [N], against sliding;
        mu: F_f / N [1] (Eq. 23), may lie outside [0, mu_max] (see MU_OUT_OF_BOUND);
        mu_max: engagement bound cos φ_n cot λ [1]; switching_torque: τ_sw [N·m] at this speed;
        tau_load [N·m]: the measured load torque used; tau_in [N·m]: input torque at the worm used;
        mode: modes.Mode value; flank: +1 driving, -1 coast, 0 none; flags: ForceFlags bits.
    """

    normal_force: float
    friction_force: float
    mu: float
    mu_max: float
    switching_torque: float
    tau_load: float
    tau_in: float
    mode: int
    flank: int
    flags: int

    def as_dict(self) -> dict[str, float | int]:
        """The fields by name (in FIELDS order), e.g. as keyword arguments of GearboxForces."""
        return {name: getattr(self, name) for name in FIELDS}


#: LiveForces' field names, in the order of worm_msgs/GearboxForces.
FIELDS: tuple[str, ...] = tuple(f.name for f in fields(LiveForces))


class LiveModel:
    """Streaming internal forces for one rig (see module docstring).

    Args:
        rig: rig parameters (gearbox, motors' drags, inertias, sample rate).
        use_acceleration: use the worm acceleration (Eqs 19-20); False: quasi-static, α_w = 0.
        acceleration_filter: time constant [s] of the low-pass on speed and acceleration.
        sample_period: time between samples [s]; None: the rig's sensor sample rate.
    """

    def __init__(self, rig: Rig, use_acceleration: bool = True, acceleration_filter: float = 0.01,
                 sample_period: float | None = None) -> None:
        self.rig = rig
        self.use_acceleration = use_acceleration
        period = 1.0 / rig.sensors.sample_rate_hz if sample_period is None else sample_period
        self.derivative = FilteredDerivative(acceleration_filter, period)

    def update(self, sample: RigSampleLike) -> LiveForces:
        """Feed one sample (ω_w [rad/s], i_drive [A], τ_load [N·m]); returns its forces and flags."""
        return self.update_values(sample.omega_worm, sample.current_drive, sample.tau_load)

    def update_values(self, omega_worm: float, current_drive: float, tau_load: float) -> LiveForces:
        """:meth:`update` from the three values: ω_w [rad/s], i_drive [A], τ_load [N·m]."""
        rig = self.rig
        omega, current, tau_load = float(omega_worm), float(current_drive), float(tau_load)
        _omega_f, alpha = self.derivative.update(omega)
        alpha = alpha if self.use_acceleration else 0.0
        tau_in = float(shaft_torque(rig.drive_motor, current, omega))
        gear_load = float(gear_side_load(rig, tau_load, omega))
        tau_sw = float(no_load_switching_torque(rig, omega))
        # tau_in is taken before the rotor's inertia, so the shafts' total inertias apply.
        f = internal_forces(rig.gearbox, tau_in, gear_load, omega, alpha,
                            worm_inertia=rig.total_worm_inertia, gear_inertia=rig.total_gear_inertia)
        mode = classify_mode(motion_sign(omega) * tau_load, tau_sw)
        flags = 0
        if not (math.isfinite(omega) and math.isfinite(current) and math.isfinite(tau_load)):
            flags = _INVALID_INPUT
        elif not bool(np.all(f.valid)):
            flags = _STANDSTILL
        # a μ of undefined forces says nothing: only flagged on otherwise valid samples
        if not flags and not bool(np.all(f.mu_valid)):
            flags = _MU_OUT_OF_BOUND
        return LiveForces(float(f.normal_force), float(f.friction_force), float(f.mu),
                          float(rig.gearbox.mu_engagement_max), tau_sw, tau_load, tau_in, int(mode),
                          int(f.flank), flags)

    def update_batch(self, omega_worm, current_drive, tau_load) -> list[LiveForces]:
        """:meth:`update_values` for consecutive samples at once (sequences of equal length).

        The acceleration filter runs sample by sample; the forces are computed for all
        samples in one vectorised pass, which costs about what one sample does on its
        own. The results equal :meth:`update_values` called per sample (a test checks).
        """
        rig = self.rig
        omega = np.asarray(omega_worm, dtype=float)
        current = np.asarray(current_drive, dtype=float)
        load = np.asarray(tau_load, dtype=float)
        alpha = np.empty_like(omega)
        for k, w in enumerate(omega.tolist()):
            alpha[k] = self.derivative.update(w)[1]
        if not self.use_acceleration:
            alpha[:] = 0.0
        tau_in = shaft_torque(rig.drive_motor, current, omega)
        gear_load = gear_side_load(rig, load, omega)
        tau_sw = no_load_switching_torque(rig, omega)
        with np.errstate(invalid="ignore"):  # NaN inputs give NaN forces, flagged below
            f = internal_forces(rig.gearbox, tau_in, gear_load, omega, alpha,
                                worm_inertia=rig.total_worm_inertia, gear_inertia=rig.total_gear_inertia)
        mode = classify_mode(motion_sign(omega) * load, tau_sw)
        finite = np.isfinite(omega) & np.isfinite(current) & np.isfinite(load)
        valid = np.broadcast_to(f.valid, omega.shape)
        mu_valid = np.broadcast_to(f.mu_valid, omega.shape)
        flags = np.where(~finite, _INVALID_INPUT,
                         np.where(~valid, _STANDSTILL, np.where(~mu_valid, _MU_OUT_OF_BOUND, 0)))
        mu_max = float(rig.gearbox.mu_engagement_max)
        columns = (f.normal_force, f.friction_force, f.mu, tau_sw, load, tau_in, mode, f.flank, flags)
        rows = zip(*(np.broadcast_to(c, omega.shape).tolist() for c in columns))
        return [LiveForces(n, ff, mu, mu_max, sw, tl, ti, int(md), int(fl), int(fg))
                for n, ff, mu, sw, tl, ti, md, fl, fg in rows]


__all__ = ["FIELDS", "ForceFlags", "LiveForces", "LiveModel", "RigSampleLike"]
