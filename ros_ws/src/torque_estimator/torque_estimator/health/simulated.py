"""Health checks on the simulated rig, many side by side: runs whose truth is known, faster than real time.

n rigs of the vectorised SimulatedRig (as calibration.batch runs its grid) each walk the reference run
(health.reference) held by its own PI (worm_rig_driver.drive.SpeedController), with its own oil
temperature at the start (the ``oil_temperature`` effect's state), its own age (the ``wear`` effect's
state) and its own load scale; the samples go straight into a worm_model.health.blocks.BlockAccumulator,
so nothing but the blocks is kept (1000 checks of 30 s would otherwise be ~2 GB of samples). The oil
temperature the effect holds is recorded with every sample: a caller that watches a drive without a
sensor simply ignores it. No ROS.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from worm_model.health.blocks import BLOCK_TIME, BlockAccumulator, Blocks
from worm_model.physics.parameters import Rig
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiGains, SpeedController
from worm_rig_driver.sim.effects import EffectsConfig, as_config
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.health.reference import reference_run
from torque_estimator.identification.excitation import sampled


def _effect(sim: SimulatedRig, name: str):
    return next((e for e in sim.plant.fx.effects if e.name == name), None)


def simulate_checks(rig: Rig, n: int, *, effects: EffectsConfig | dict | None = None, seed: int = 0,
                    temperature=None, hours=None, load_scale=1.0, angle=None, timeline=None,
                    gains: PiGains = DEFAULT_GAINS,
                    block_time: float = BLOCK_TIME,
                    progress: Callable[[int, int], None] | None = None) -> Blocks:
    """Run n checks at once; return their blocks as (m, n) arrays (``Blocks.rig(k)``: check k's).

    Args:
        effects: the simulator's effects (SimulatedRig's ``effects``); ``temperature`` needs
            ``oil_temperature`` among them and ``hours`` needs ``wear``.
        temperature: oil temperature of each rig at the start [degC], shape (n,) or a scalar.
        hours: age of each rig [h] (the wear effect's state), shape (n,) or a scalar.
        load_scale: multiplies the reference run's loads, per rig.
        angle: the worm's angle at the start [rad], per rig (default: drawn from the seed, one gear turn
            wide: a check starts wherever the gearbox stopped, so the wheel's runout meets it at any phase).
        timeline: the run (default health.reference.reference_run(rig)).
        progress: called with (samples done, samples in all) about every second of rig time.

    Raises:
        ValueError: temperature or hours given without the effect that holds it.
    """
    config = as_config(effects)
    timeline = reference_run(rig) if timeline is None else timeline
    sim = SimulatedRig(rig, n=n, seed=seed, effects=config, scalar=False)
    oil, wear = _effect(sim, "oil_temperature"), _effect(sim, "wear")
    for value, effect, name in ((temperature, oil, "oil_temperature"), (hours, wear, "wear")):
        if value is not None and effect is None:
            raise ValueError(f"per-rig {name} needs the {name!r} effect switched on")
    if temperature is not None:
        oil.temperature = np.broadcast_to(np.asarray(temperature, dtype=float), (n,)).copy()
    if hours is not None:
        wear.hours = np.broadcast_to(np.asarray(hours, dtype=float), (n,)).copy()
    scale = np.broadcast_to(np.asarray(load_scale, dtype=float), (n,))
    if angle is None:
        angle = np.random.default_rng([seed, 29]).uniform(0.0, 2.0 * np.pi / rig.gearbox.ratio, n)
    state = sim.plant.state
    state.theta_worm = np.broadcast_to(np.asarray(angle, dtype=float), (n,)).copy()
    state.theta_gear = rig.gearbox.ratio * state.theta_worm  # (teeth mid-gap, as the plant starts)
    controller = SpeedController(rig, gains, n=n)
    period = sim.sample_period
    _index, speeds, loads = sampled(timeline, period)
    blocks = BlockAccumulator(n, period, rig.gearbox.ratio, block_time)
    total = len(speeds)
    every = max(1, int(round(1.0 / period)))
    for k in range(total):
        sim.command(load_torque=loads[k] * scale)
        m = sim.sample()
        blocks.add(k * period, m.omega_worm, m.current_drive, m.tau_load, m.theta_worm, m.theta_gear,
                   None if oil is None else oil.temperature)
        sim.command(voltage_drive=controller.update(period, speeds[k], m.omega_worm).voltage)
        if progress is not None and (k + 1) % every == 0:
            progress(k + 1, total)
    return blocks.blocks()


__all__ = ["simulate_checks"]
