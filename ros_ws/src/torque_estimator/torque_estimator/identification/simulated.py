"""The excitation on the simulated rig in this process: what ``identify`` records over the graph, without DDS.

The rig (worm_rig_driver's SimulatedRig, effects switched on in the simulator only) is held by
the rig's own speed loop (worm_rig_driver.drive: the PI every sample, as sim_node runs it) at
the timeline's speed set-point while the load motors apply its load; every sample goes to an
:class:`~torque_estimator.session.recording.ExcitationRun`.  Deterministic for a seed.
Used by the tests, ``make evaluate`` and ``make bench``; no ROS.
"""
from __future__ import annotations

from collections.abc import Callable

from worm_model.physics.parameters import Rig
from worm_model.rig_data.schema import MeasuredData
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiGains, PiLoop
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.session.recording import ExcitationRun, Journal, run_settings


def record_on_simulator(rig: Rig, timeline, *, effects=None, seed: int = 0, gains: PiGains = DEFAULT_GAINS,
                        journal: Journal | None = None,
                        progress: Callable[[int, int], None] | None = None) -> MeasuredData:
    """Run ``timeline`` on a simulated ``rig`` (true parameters; ``effects`` as SimulatedRig takes them) and
    return the recorded samples. ``progress(done, total)`` is called about every 0.5 s of rig time."""
    sim = SimulatedRig(rig, n=1, seed=seed, effects=effects)
    loop = PiLoop(rig, gains, rig.supply_voltage)
    journal = journal or Journal(run_settings(timeline, {}, "simulator", seed=seed))
    run = ExcitationRun(timeline, journal, sim.sample_period)
    report_every = max(1, int(0.5 / sim.sample_period))
    while (target := run.setpoints()) is not None:
        speed, load = target
        sim.command(load_torque=load)
        m = sim.sample()
        run.add({"current_drive": m.current_drive[0], "omega_worm": m.omega_worm[0], "theta_worm": m.theta_worm[0],
                 "tau_load": m.tau_load[0], "voltage_drive": m.voltage_drive[0], "theta_gear": m.theta_gear[0],
                 "current_load": m.current_load_1[0] + m.current_load_2[0]})
        sim.command(voltage_drive=loop.update(sim.sample_period, speed, float(m.omega_worm[0])))
        if progress is not None and run.samples_done % report_every == 0:
            progress(run.samples_done, run.total_samples)
    return journal.data(f"simulator (seed {seed})")


__all__ = ["record_on_simulator"]
