"""The backlash regressor: the transmission error's jump across the clearance at each flank change."""
from __future__ import annotations

import math

import numpy as np

from worm_model.physics.parameters import Rig
from worm_model.physics.units import FloatArray

from worm_model.residuals.effects.base import Coefficient, GridParameter, _Base, regresses
from worm_model.residuals.model import ModelState, evaluate


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


@regresses
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
    parameters = (Coefficient.of("backlash", "angle"),)
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
