"""The feedforward a rig runs beside its PI: found by entry point, and the very loop the benchmark's rig timing runs."""
from __future__ import annotations

import numpy as np
import pytest

from worm_model.physics.parameters import load_rig
from worm_rig_driver.drive.feedforward_plugin import load_rig_feedforward
from worm_rig_driver.errors import FeedforwardUnavailable
from worm_rig_driver.drive.rig_loop import RigLoop, SpeedCommand
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS
from worm_rig_driver.sim.simulated_rig import SimulatedRig, rig_sample

from torque_estimator.control.rig_feedforward import (FEEDFORWARD_FALSE_ALARM, EstimatorFeedforward, build,
                                                      feedforward_estimator)
from torque_estimator.evaluation.closed_loop import run_scenario
from torque_estimator.evaluation.scenario import Segment, segment_at

RIG = load_rig()
T = 1e-3


def test_the_installed_entry_point_builds_the_observer_feedforward() -> None:
    """sim_node / driver_node find torque_estimator's factory through the entry point, as installed."""
    source = load_rig_feedforward("observer", "", RIG, T)
    assert isinstance(source, EstimatorFeedforward)
    assert source.live.stream.load.false_alarm == FEEDFORWARD_FALSE_ALARM


@pytest.mark.parametrize("method, calibration, words", [
    ("kalman", "", "unknown estimator 'kalman'"),
    ("knn", "", "needs a calibration file"),
    ("observer", "/nonexistent/calibration.npz", "calibration.npz"),
])
def test_what_cannot_be_built_is_said_in_one_line(method: str, calibration: str, words: str) -> None:
    with pytest.raises(FeedforwardUnavailable) as err:
        load_rig_feedforward(method, calibration, RIG, T)
    assert words in str(err.value) and "\n" not in str(err.value)
    with pytest.raises((ValueError, OSError)):
        build(method, calibration, RIG, T)


def test_the_rig_loop_with_its_feedforward_is_the_benchmarks_rig_timing() -> None:
    """SimulatedRig + RigLoop + EstimatorFeedforward (what sim_node's clock thread runs) give the very speeds of
    closed_loop.run_scenario at batch 1, latency 0 with the feedforward's estimator (controller_bench's rig
    timing): so the bench's figures are the rig's."""
    scenario = (Segment(0.3, 150.0, 0.0, "no load"), Segment(0.3, 150.0, 0.2, "resistive"),
                Segment(0.3, 150.0, -0.2, "assistive"))
    bench = run_scenario(RIG, scenario, ("estimate",), estimator=feedforward_estimator("observer", None, RIG),
                         seed=3, ff_batch=1, ff_latency=0)["estimate"]
    sim = SimulatedRig(RIG, n=1, seed=3)
    loop = RigLoop(RIG, sim.sample_period, 0.1, DEFAULT_GAINS, feedforward=build("observer", "", RIG, T))
    omega, feedforward, segment = [], [], None
    for k in range(len(bench.t)):
        if (current := segment_at(scenario, k * T)) != segment:
            segment = current
            sim.command(load_torque=scenario[segment].load)
            command = SpeedCommand(scenario[segment].speed, 0.0, DEFAULT_GAINS.kp, DEFAULT_GAINS.ki,
                                   RIG.supply_voltage, at_rig=True)
        loop.command_speed(command, k * T)  # as a controller keeps sending it (the rig's watchdog)
        m = sim.sample()
        loop.observe(rig_sample(m, sim.seq), sim.seq)
        out = loop.step(k * T, float(m.omega_worm[0]), sim.seq)
        sim.command(voltage_drive=out.voltage)
        omega.append(float(sim.plant.state.omega_worm[0]))
        feedforward.append(out.feedforward)
    np.testing.assert_allclose(feedforward, bench.feedforward, rtol=0, atol=1e-12)
    np.testing.assert_allclose(omega, bench.omega_true, rtol=0, atol=1e-9)
    assert np.ptp(feedforward) > 0.01  # it did feed the load forward
