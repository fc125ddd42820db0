"""Steady constant-speed points: consecutive blocks held at one worm speed and one load, averaged.

The Bittencourt & Axelsson way of watching a joint's friction: at a constant speed the drive's
torque is the friction torque (plus the known load reflected), free of inertia. A run of blocks
becomes a point when every block kept one direction, its acceleration stayed below
``alpha_max`` and its speed and load stayed within tolerance of the run's mean; the first
``settle`` blocks of each run are left out (the tail of the change before it) and a point needs
``min_blocks`` blocks after them. What is found does not depend on who made the run: the
health check's reference run, a recorded bag, or a machine's own repeated motion.

A point's torque is K_t x the mean current plus the total worm-side inertia x the mean
acceleration (small: a steady point). Its standard error is the current's white noise
(blocks.Blocks.current_noise) over sqrt(samples), times ``loop_noise``: the speed loop turns the
tacho's noise into slower current fluctuations the white estimate does not see (1.15 on the
simulated rig; assumption 1.25). Not the block means' spread: the torque ripples of a turning
gearbox (runout, tooth pass, cogging) make the blocks differ and average out over a point.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from worm_model.health.blocks import Blocks
from worm_model.physics.parameters import Rig
from worm_model.physics.resolution import kinetic_speed
from worm_model.physics.units import FloatArray


@dataclass(frozen=True)
class PointRules:
    """When blocks count as one steady point (module docstring). Speeds [rad/s], loads [N m]."""

    speed_tolerance: float = 0.02  # relative to the point's speed
    speed_floor: float = 1.5  # [rad/s] absolute tolerance at low speeds
    load_tolerance: float = 0.03  # relative to the point's load
    load_floor: float = 0.004  # [N m]
    alpha_max: float = 40.0  # [rad/s^2]
    min_speed: float | None = None  # [rad/s]; None: the rig's own (worm_model.physics.resolution.kinetic_speed)
    settle: int = 2  # blocks left out at the start of each run
    min_blocks: int = 4
    loop_noise: float = 1.25  # [1] (module docstring)

    def slowest(self, rig: Rig) -> float:
        """The slowest speed of a point [rad/s]: ``min_speed``, or the rig's own where it is None."""
        return kinetic_speed(rig) if self.min_speed is None else self.min_speed


@dataclass
class Points:
    """Steady points, arrays of shape (p,): SI, degC."""

    omega: FloatArray  # [rad/s]
    tau_load: FloatArray  # [N m]
    torque: FloatArray  # [N m] K_t i + J alpha
    torque_sigma: FloatArray  # [N m] standard error
    gear_sin: FloatArray  # mean of sin(i theta_worm) over the point (the wheel runout's phase)
    gear_cos: FloatArray  # mean of cos(i theta_worm)
    te: FloatArray  # [rad] mean transmission error (NaN without a gear encoder)
    te_sigma: FloatArray  # [rad]
    temperature: FloatArray  # [degC] (NaN: not measured)
    duration: FloatArray  # [s] averaged
    t: FloatArray  # [s] start of the averaged part

    def __len__(self) -> int:
        return len(self.omega)

    @property
    def rig_time(self) -> float:
        return float(self.duration.sum())


def _groups(blocks: Blocks, rules: PointRules, min_speed: float) -> list[np.ndarray]:
    """Index arrays of the runs of steady blocks (before settle/min_blocks); ``min_speed`` [rad/s]."""
    eligible = blocks.one_way & (np.abs(blocks.alpha) < rules.alpha_max) & (np.abs(blocks.omega) >= min_speed) \
        & np.isfinite(blocks.current) & np.isfinite(blocks.tau_load)
    groups, current = [], []
    sum_w = sum_d = 0.0
    for k in range(len(blocks)):
        if current:
            mean_w, mean_d = sum_w / len(current), sum_d / len(current)
            fits = eligible[k] and blocks.run[k] == blocks.run[current[-1]] \
                and abs(blocks.omega[k] - mean_w) <= max(rules.speed_floor, rules.speed_tolerance * abs(mean_w)) \
                and abs(blocks.tau_load[k] - mean_d) <= max(rules.load_floor, rules.load_tolerance * abs(mean_d))
            if fits:
                current.append(k)
                sum_w += blocks.omega[k]
                sum_d += blocks.tau_load[k]
                continue
            groups.append(np.array(current))
            current = []
        if eligible[k]:
            current, sum_w, sum_d = [k], float(blocks.omega[k]), float(blocks.tau_load[k])
    if current:
        groups.append(np.array(current))
    return groups


def steady_points(blocks: Blocks, rig: Rig, rules: PointRules = PointRules()) -> Points:
    """The steady points of a run of blocks (module docstring)."""
    rows = []
    k_t = rig.drive_motor.torque_constant
    inertia = rig.total_worm_inertia
    for group in _groups(blocks, rules, rules.slowest(rig)):
        use = group[rules.settle:]
        if len(use) < rules.min_blocks:
            continue
        m = len(use)
        current = blocks.current[use]
        white = rules.loop_noise * np.sqrt(blocks.current_noise[use].mean() / (m * blocks.size))
        te = blocks.te[use]
        te_ok = np.isfinite(te)
        te_mean = te[te_ok].mean() if te_ok.any() else np.nan
        te_sigma = te[te_ok].std(ddof=1) / np.sqrt(te_ok.sum()) if te_ok.sum() > 1 else np.nan
        temperature = blocks.temperature[use]
        rows.append((blocks.omega[use].mean(), blocks.tau_load[use].mean(),
                     k_t * current.mean() + inertia * blocks.alpha[use].mean(), k_t * white,
                     blocks.gear_sin[use].mean(), blocks.gear_cos[use].mean(),
                     te_mean, te_sigma, np.nanmean(temperature) if np.isfinite(temperature).any() else np.nan,
                     m * blocks.duration, blocks.t[use[0]]))
    table = np.array(rows, dtype=float).reshape(-1, 11)
    return Points(*(table[:, j] for j in range(11)))


__all__ = ["PointRules", "Points", "steady_points"]
