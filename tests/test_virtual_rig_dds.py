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
from worm_msgs.msg import DriveCommand, LoadCommand, RigSample

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_load
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.ros.testing import probe_node, stop_process
from worm_model.physics.parameters import load_rig
from worm_model.physics.steady_state import steady_worm_speed

RIG = load_rig()
MOTOR = RIG.drive_motor
START_TIMEOUT = 30.0  # [s] processes up and discovery (a functional bound, not a speed requirement)
PROBE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=4000, reliability=ReliabilityPolicy.BEST_EFFORT)


@pytest.fixture(scope="module")
def graph(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict]:
    """virtual_rig and driver_node as processes, a probe node here (ros_env: tests/conftest.py)."""
    logs = tmp_path_factory.mktemp("virtual_rig")
    link = str(logs / "worm_rig")
    rig_log, driver_log = logs / "virtual_rig.log", logs / "driver_node.log"
    with open(rig_log, "w") as out:
        rig = subprocess.Popen([sys.executable, "-m", "worm_rig_driver.sim.virtual_rig", "--link", link, "--seed", "2"],
                               stdout=out, stderr=subprocess.STDOUT, env=ros_env)
    deadline = time.monotonic() + START_TIMEOUT
    while not os.path.lexists(link) and time.monotonic() < deadline and rig.poll() is None:
        time.sleep(0.05)
    with open(driver_log, "w") as out:
        driver = subprocess.Popen([sys.executable, "-m", "worm_rig_driver.nodes.driver_node", "--ros-args",
                                   "-p", f"port:={link}", "-p", "command_timeout:=5.0"],
                                  stdout=out, stderr=subprocess.STDOUT, env=ros_env)
    try:
        with probe_node("virtual_rig_probe", EventsExecutor) as (node, executor):
            samples: list[RigSample] = []
            node.create_subscription(RigSample, "/rig/sample", samples.append, PROBE_QOS)
            yield {"node": node, "executor": executor, "samples": samples, "rig": rig, "driver": driver,
                   "rig_log": rig_log, "driver_log": driver_log,
                   "drive": node.create_publisher(DriveCommand, "/rig/drive_command", STREAM),
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
    _spin(graph, 0.5)  # settle
    samples.clear()
    _spin(graph, 1.0)
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
