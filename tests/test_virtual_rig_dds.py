"""System test: the real driver_node, unchanged, against the virtual serial rig (virtual_rig).

virtual_rig runs the simulated rig behind a pseudo-terminal, speaking the
firmware's protocol; driver_node opens it through the symlink as it would open
the board's /dev/serial/by-id link. A probe node commands a speed and a load
over DDS and checks that what the driver publishes is the physics: the steady
speed and current of Eqs 28-30 and the load torque commanded.

ROS_DOMAIN_ID: the environment's if set, else a random one in 100..230; discovery
on this host only (the ros_env fixture of tests/conftest.py). Both processes must
exit 0 on SIGINT.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from rclpy.experimental import EventsExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from worm_msgs.msg import DriveCommand, LoadCommand, RigSample, SpeedCommand

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_load
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.ros.testing import probe_node, stop_process
from worm_model.physics.parameters import load_rig
from worm_model.physics.steady_state import steady_worm_speed
from worm_rig_driver.drive.realtime import realtime_permitted

RIG = load_rig()
MOTOR = RIG.drive_motor
START_TIMEOUT = 30.0  # [s] processes up and discovery (a functional bound, not a speed requirement)
#: the rig's two processes at the rig computer's SCHED_FIFO priority where permitted (as run_graph runs them):
#: driver_node closes the speed loop on every frame, and another test file running beside this one (make test
#: runs two at a time) once delayed its feedforward past the 5-15 samples the test judges
REALTIME = ["chrt", "-f", "40"] if realtime_permitted(40) else []
PROBE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=4000, reliability=ReliabilityPolicy.BEST_EFFORT)


@pytest.fixture(scope="module")
def graph(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict]:
    """virtual_rig and driver_node as processes, a probe node here (ros_env: tests/conftest.py)."""
    logs = tmp_path_factory.mktemp("virtual_rig")
    link = str(logs / "worm_rig")
    rig_log, driver_log = logs / "virtual_rig.log", logs / "driver_node.log"
    with open(rig_log, "w") as out:
        rig = subprocess.Popen([*REALTIME, sys.executable, "-m", "worm_rig_driver.sim.virtual_rig", "--link", link,
                                "--seed", "2"],
                               stdout=out, stderr=subprocess.STDOUT, env=ros_env)
    deadline = time.monotonic() + START_TIMEOUT
    while not os.path.lexists(link) and time.monotonic() < deadline and rig.poll() is None:
        time.sleep(0.05)
    with open(driver_log, "w") as out:
        driver = subprocess.Popen([*REALTIME, sys.executable, "-m", "worm_rig_driver.nodes.driver_node", "--ros-args",
                                   "-p", f"port:={link}", "-p", "command_timeout:=5.0",
                                   "-p", "feedforward_estimator:=observer"],
                                  stdout=out, stderr=subprocess.STDOUT, env=ros_env)
    try:
        with probe_node("virtual_rig_probe", EventsExecutor) as (node, executor):
            samples: list[RigSample] = []
            node.create_subscription(RigSample, "/rig/sample", samples.append, PROBE_QOS)
            yield {"node": node, "executor": executor, "samples": samples, "rig": rig, "driver": driver,
                   "rig_log": rig_log, "driver_log": driver_log,
                   "drive": node.create_publisher(DriveCommand, "/rig/drive_command", STREAM),
                   "speed": node.create_publisher(SpeedCommand, "/rig/speed_command", STREAM),
                   "load": node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)}
    finally:
        driver_code = stop_process(driver)
        rig_code = stop_process(rig)
    assert driver_code == 0, Path(driver_log).read_text()
    assert rig_code == 0, Path(rig_log).read_text()


def _spin(parts: dict, seconds: float, until=None) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if until is not None and until():
            return True
        parts["executor"].spin_until_future_complete(Future(executor=parts["executor"]), timeout_sec=0.05)
    return until is None


def test_driver_node_runs_the_virtual_rig_like_the_real_one(graph: dict) -> None:
    samples = graph["samples"]
    assert _spin(graph, START_TIMEOUT, lambda: len(samples) > 200), (
        f"no /rig/sample from driver_node:\n{graph['driver_log'].read_text()}\n{graph['rig_log'].read_text()}")
    voltage, torque = 6.0, 0.1
    graph["drive"].publish(DriveCommand(voltage=voltage))
    graph["load"].publish(LoadCommand(torque=torque))
    assert _spin(graph, 10.0, lambda: samples[-1].voltage_drive == voltage and abs(samples[-1].tau_load - torque)
                 < 0.02), samples[-1]
    # settle for 1 s and measure over 1 s of the rig's own clock (its ticks): under load the virtual rig's
    # time may run slower than the wall clock's
    settled = samples[-1].seq + 1000
    assert _spin(graph, 60.0, lambda: samples[-1].seq >= settled), "the rig stopped ticking"
    samples.clear()
    assert _spin(graph, 60.0, lambda: len(samples) > 1 and samples[-1].seq - samples[0].seq >= 1000)
    window = list(samples)
    assert len(window) > 300
    seqs = np.array([s.seq for s in window])
    assert np.all(np.diff(seqs) >= 1)  # the rig's ticks, in order (best-effort transport may drop some)
    omega = np.mean([s.omega_worm for s in window])
    tau = np.mean([s.tau_load for s in window])
    current = np.mean([s.current_drive for s in window])
    # the physics through the protocol: steady state of Eqs 28-30 at the applied duty and measured load
    assert tau == pytest.approx(torque, abs=0.005)
    assert omega == pytest.approx(steady_worm_speed(RIG, voltage, tau), abs=1.0)
    mu = friction_coefficient(RIG.friction, RIG.gearbox, omega)
    predicted = (MOTOR.viscous_drag * omega + MOTOR.coulomb_drag
                 + float(reflected_input_torque(RIG.gearbox, mu, gear_side_load(RIG, tau, omega), omega))) \
        / MOTOR.torque_constant
    assert current == pytest.approx(predicted, abs=0.01)
    theta = [s.theta_worm for s in window]
    assert theta[-1] - theta[0] == pytest.approx(omega * (window[-1].seq - window[0].seq) * 1e-3, rel=0.05)


def test_driver_node_feeds_forward_its_own_estimate_of_the_load(graph: dict) -> None:
    """driver_node runs the observer beside its speed loop (feedforward_estimator), on every frame the
    firmware's protocol brings through the pseudo-terminal. A speed command with feedforward_at_rig gets its
    feedforward: after a load step the drive voltage has made most of its way to the new steady value 5-15
    samples later; with the same command without it the PI alone has barely started. Judged on the rig's
    own ticks (the samples' seq and their applied load)."""
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS

    samples = graph["samples"]

    def command(at_rig: bool) -> SpeedCommand:
        return SpeedCommand(speed_setpoint=150.0, kp=DEFAULT_GAINS.kp, ki=DEFAULT_GAINS.ki,
                            voltage_limit=RIG.supply_voltage, feedforward_at_rig=at_rig)

    def hold(at_rig: bool, seconds: float) -> None:
        """Keep sending the speed command (as controller_node does, every 20 ms) for `seconds` of the rig's
        clock (its ticks)."""
        end, deadline = samples[-1].seq + int(seconds * 1000), time.monotonic() + 60.0
        while samples[-1].seq < end and time.monotonic() < deadline:
            graph["speed"].publish(command(at_rig))
            _spin(graph, 0.02)
        assert samples[-1].seq >= end, "the rig stopped ticking"

    def step_response(at_rig: bool, torque: float) -> float | None:
        """How far the voltage has gone 5-15 samples after a load step; None if rig/sample (best effort) lost
        samples around the step: the first one seen under the new load would then be a later one."""
        graph["load"].publish(LoadCommand(torque=0.0))
        hold(at_rig, 2.0)  # settled at the set-point under the present load
        first = len(samples)
        graph["load"].publish(LoadCommand(torque=torque))
        hold(at_rig, 1.5)
        window = samples[first - 300:]
        seq = np.array([s.seq for s in window])
        tau = np.array([s.tau_load for s in window])
        volts = np.array([s.voltage_drive for s in window])
        k = int(np.argmax(np.abs(tau - torque) < 0.05))  # the first sample under the new load
        step = seq[k]
        if k < 20 or np.any(np.diff(seq[k - 20:k + 16]) != 1):
            return None
        before = volts[(seq >= step - 200) & (seq < step)].mean()
        after = volts[seq >= seq[-1] - 300].mean()
        soon = volts[(seq >= step + 5) & (seq <= step + 15)]
        assert len(soon) >= 5 and k >= 100, (len(soon), k)
        return float((soon.mean() - before) / (after - before))

    def measured(at_rig: bool, reads_as_it_should) -> list[float]:
        """step_response until one reads as the loop should, three readings at most (tries whose samples were
        lost around the step not counted). The voltage at the rig is driver_node's answer to each frame, so a
        host that holds driver_node back for the 15 samples judged measures itself, not the loop: once in CI
        the feedforward read -0.004 (no move at all, not even the PI's), once the PI alone 0.94 (a stalled
        loop catching up at once). A loop without the feature reads wrong every time."""
        readings: list[float] = []
        for _ in range(6):
            if (ratio := step_response(at_rig, 0.2)) is None:
                continue
            readings.append(ratio)
            if reads_as_it_should(ratio) or len(readings) == 3:
                return readings
        if not readings:
            pytest.fail("samples lost around the load step in 6 tries")
        return readings

    graph["load"].publish(LoadCommand(torque=0.0))
    hold(True, 1.0)
    assert abs(samples[-1].omega_worm - 150.0) < 10.0, samples[-1]
    # measured in 10 runs (6 with a CPU hog): 0.89-1.91 with the feedforward, 0.36-0.43 without
    def fed_forward(ratio: float) -> bool:
        return ratio > 0.75

    def pi_alone_started(ratio: float) -> bool:
        return ratio < 0.55

    at_rig = measured(True, fed_forward)
    pi_alone = measured(False, pi_alone_started)
    assert fed_forward(at_rig[-1]) and pi_alone_started(pi_alone[-1]), (
        at_rig, pi_alone, graph["driver_log"].read_text()[-2000:])
