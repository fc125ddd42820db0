"""System test of driver_node over a real pseudo-terminal, with a Python peer speaking the rig's protocol.

driver_node runs in its own process (as `ros2 run` starts it) on the slave end of
a pty that worm_rig_driver.link.rig_peer.PtyRigPeer serves, through a symlink, the way
a udev /dev/serial/by-id link points at a USB serial device. A probe node in this
process subscribes to what the driver publishes and sends commands. Faults are
made by the peer: garbage bytes, broken CRCs, skipped sequence numbers, silence,
and the port disappearing (pty closed, symlink removed) and coming back.

ROS_DOMAIN_ID: the environment's if set, else a random one in 100..230; discovery on
this host only (the ros_env fixture of tests/conftest.py). The node must exit 0 on
SIGINT and tell the rig to STOP on its way out.
"""
from __future__ import annotations

import math
import os
import random
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import JointState
from worm_msgs.msg import DriveCommand, EncoderCounts, LoadCommand, MotorCurrents, RigSample

from worm_model.ros.qos import COMMAND, STREAM
from worm_model.ros.testing import probe_node, stop_process
from worm_model.physics.parameters import load_rig
import worm_rig_driver.link.core as link
import worm_rig_driver.protocol.table as table
from worm_rig_driver.link.rig_peer import PtyRigPeer

MAX_DRIVE_VOLTAGE = 12.0
START_TIMEOUT = 30.0  # [s] node start-up and discovery
EVENT_TIMEOUT = 5.0  # [s] for an effect to show (functional bound, not a speed requirement)
PROBE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=2000, reliability=ReliabilityPolicy.BEST_EFFORT)
RIG = load_rig()


class Probe:
    def __init__(self, node: Node, executor: EventsExecutor) -> None:
        self.node = node
        self.executor = executor
        self.samples: list[RigSample] = []
        self.channels: dict[str, int] = {"currents": 0, "joints": 0, "encoders": 0}
        self.encoders: list[EncoderCounts] = []
        self.diagnostics: dict[str, str] = {}
        self.messages: dict[str, tuple[int, str]] = {}  # the last (level, message) of every node on /diagnostics
        self.node.create_subscription(RigSample, "/rig/sample", self.samples.append, PROBE_QOS)
        self.node.create_subscription(MotorCurrents, "/rig/currents", lambda m: self._count("currents"), PROBE_QOS)
        self.node.create_subscription(JointState, "/rig/joint_states", lambda m: self._count("joints"), PROBE_QOS)
        self.node.create_subscription(EncoderCounts, "/rig/encoders", self.encoders.append, PROBE_QOS)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 10)
        self.drive = self.node.create_publisher(DriveCommand, "/rig/drive_command", STREAM)
        self.load = self.node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)

    def _count(self, key: str) -> None:
        self.channels[key] += 1

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            level = int.from_bytes(status.level, "little") if isinstance(status.level, bytes) else status.level
            self.messages[status.name] = (level, status.message)
            if status.name == "driver_node":
                self.diagnostics = {kv.key: kv.value for kv in status.values}
                self.diagnostics["_level"] = str(level)
                self.diagnostics["_message"] = status.message

    def spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while not done():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            self.executor.spin_until_future_complete(Future(executor=self.executor), timeout_sec=min(0.05, left))
        return True

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def diag(self, key: str) -> int:
        return int(self.diagnostics.get(key, "-1"))

    def send_drive(self, voltage: float) -> None:
        self.drive.publish(DriveCommand(voltage=voltage))


@pytest.fixture(scope="module")
def probe(ros_env: dict[str, str]) -> Iterator[Probe]:
    """The probe node, in this module's DDS domain (ros_env: tests/conftest.py)."""
    with probe_node("driver_test_probe", EventsExecutor) as (node, executor):
        yield Probe(node, executor)


@pytest.fixture(scope="module")
def peer(tmp_path_factory: pytest.TempPathFactory) -> Iterator[PtyRigPeer]:
    p = PtyRigPeer(str(tmp_path_factory.mktemp("port") / "rig"))
    p.start()
    yield p
    p.close()


class Driver:
    def __init__(self, process: subprocess.Popen, log: Path) -> None:
        self.process = process
        self.log = log

    def output(self) -> str:
        return self.log.read_text(errors="replace")


@pytest.fixture(scope="module")
def driver(probe: Probe, peer: PtyRigPeer, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Driver]:
    log = tmp_path_factory.mktemp("driver") / "driver_node.log"
    with open(log, "w") as out:
        process = subprocess.Popen(
            [sys.executable, "-m", "worm_rig_driver.nodes.driver_node", "--ros-args", "-p", f"port:={peer.link}",
             "-p", f"max_drive_voltage:={MAX_DRIVE_VOLTAGE}", "-p", "command_timeout:=5.0"],
            stdout=out, stderr=subprocess.STDOUT, env=dict(os.environ))
    d = Driver(process, log)
    try:
        if not probe.spin_until(lambda: len(probe.samples) > 100 or process.poll() is not None, START_TIMEOUT):
            pytest.fail(f"no /rig/sample within {START_TIMEOUT} s:\n{d.output()}")
        yield d
    finally:
        stops_before = sum(1 for f in peer.log.frames if f.name == "STOP")
        code = stop_process(process)
        time.sleep(0.1)
        stops = sum(1 for f in peer.log.frames if f.name == "STOP") - stops_before
        assert code == 0, f"driver_node exited {code} on SIGINT:\n{d.output()}"
        assert stops >= 1, "driver_node did not send STOP on shutdown"


def fresh(probe: Probe, seconds: float) -> list[RigSample]:
    probe.samples.clear()
    probe.spin_for(seconds)
    return list(probe.samples)


def test_samples_flow_with_every_channel(probe: Probe, driver: Driver) -> None:
    samples = fresh(probe, 1.0)
    assert len(samples) > 500, f"{len(samples)} samples in 1 s"
    seqs = [s.seq for s in samples]
    assert all(b - a == 1 for a, b in zip(seqs, seqs[1:])), "the rig's tick numbers must follow each other"
    stamps = [s.header.stamp.sec + 1e-9 * s.header.stamp.nanosec for s in samples]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))
    assert abs(stamps[-1] - time.time()) < 2.0  # mapped onto host time
    assert all(s.header.frame_id == "worm_rig" for s in samples)
    assert probe.channels["currents"] > 0 and probe.channels["joints"] > 0 and probe.encoders
    assert probe.encoders[-1].counts_per_rev == 2000
    assert probe.spin_until(lambda: probe.diagnostics.get("state") == "up", EVENT_TIMEOUT)
    assert probe.diag("handshakes") == 1 and probe.diag("rx_crc_errors") == 0


def test_rig_sample_status_constants_match_the_core() -> None:
    assert link.RIG_STATUS_DRIVE_LIMIT == RigSample.STATUS_DRIVE_LIMIT
    assert link.RIG_STATUS_WATCHDOG_STOP == RigSample.STATUS_WATCHDOG_STOP
    assert link.RIG_STATUS_SENSOR_FAULT == RigSample.STATUS_SENSOR_FAULT


def test_drive_command_reaches_the_rig(probe: Probe, peer: PtyRigPeer, driver: Driver) -> None:
    probe.send_drive(6.0)
    assert probe.spin_until(lambda: any(sp.drive == 2500 for sp in peer.log.setpoints), EVENT_TIMEOUT), (
        f"no SETPOINT with drive duty 2500: {peer.log.setpoints[-3:]}")
    assert probe.spin_until(lambda: bool(probe.samples) and probe.samples[-1].voltage_drive == 6.0, EVENT_TIMEOUT)
    start = probe.samples[-1].theta_worm
    probe.spin_for(0.3)
    assert probe.samples[-1].theta_worm > start  # the peer's encoder turns with the duty


def test_commands_beyond_the_limits_are_refused_with_a_reason(probe: Probe, peer: PtyRigPeer,
                                                               driver: Driver) -> None:
    before = len(peer.log.setpoints)
    probe.send_drive(20.0)
    probe.send_drive(math.nan)
    probe.load.publish(LoadCommand(torque=5.0))
    assert probe.spin_until(lambda: probe.diag("rejected_commands") >= 3, EVENT_TIMEOUT), probe.diagnostics
    assert all(abs(sp.drive) <= 5000 for sp in peer.log.setpoints[before:])  # 12 V max = 5000
    text = driver.output()
    assert f"rejected drive command: |voltage|=20 V exceeds max_drive_voltage={MAX_DRIVE_VOLTAGE:g} V" in text
    assert "rejected load command: |torque|=5 N m exceeds max_load_torque" in text
    assert driver.process.poll() is None


def test_load_command_becomes_current_targets(probe: Probe, peer: PtyRigPeer, driver: Driver) -> None:
    probe.load.publish(LoadCommand(torque=0.1))
    per_motor = round(0.1 / (2 * RIG.load_motor.torque_constant) / RIG.sensors.current_lsb)
    assert probe.spin_until(lambda: any(sp.load_1 == per_motor == sp.load_2 and sp.mode == 0b110
                                        for sp in peer.log.setpoints), EVENT_TIMEOUT)
    assert probe.spin_until(lambda: abs(probe.samples[-1].tau_load - 0.1) < 0.01, EVENT_TIMEOUT), (
        probe.samples[-1].tau_load)


def test_garbage_crc_errors_and_gaps_are_survived_and_counted(probe: Probe, peer: PtyRigPeer,
                                                             driver: Driver) -> None:
    probe.spin_until(lambda: "rx_crc_errors" in probe.diagnostics, EVENT_TIMEOUT)
    crc0, gaps0, lost0 = probe.diag("rx_crc_errors"), probe.diag("seq_gaps"), probe.diag("lost_frames")
    garbage0 = probe.diag("rx_discarded_bytes")
    peer.inject(bytes(random.Random(3).randrange(1, 256) for _ in range(500)) + b"\x00")
    peer.corrupt_next(5)
    probe.spin_for(0.1)
    peer.skip_seq(10)
    assert probe.spin_until(lambda: probe.diag("rx_crc_errors") >= crc0 + 5 and probe.diag("seq_gaps") >= gaps0 + 2
                            and probe.diag("lost_frames") >= lost0 + 15, EVENT_TIMEOUT), probe.diagnostics
    assert probe.diag("rx_discarded_bytes") >= garbage0 + 500
    assert probe.diag("rx_oversize") >= 1  # the garbage has no 0x00 for 500 bytes
    assert len(fresh(probe, 0.5)) > 200 and driver.process.poll() is None


def test_silence_is_counted_as_a_timeout_and_the_link_recovers(probe: Probe, peer: PtyRigPeer,
                                                              driver: Driver) -> None:
    timeouts0, handshakes0 = probe.diag("timeouts"), probe.diag("handshakes")
    peer.silence(0.6)
    assert probe.spin_until(lambda: probe.diag("timeouts") >= timeouts0 + 1, EVENT_TIMEOUT), probe.diagnostics
    assert probe.spin_until(lambda: probe.diag("handshakes") >= handshakes0 + 1, EVENT_TIMEOUT), (
        f"{probe.diagnostics}\npeer: {peer.log.hellos} HELLOs, last frames {peer.log.frames[-5:]}\n"
        f"{driver.output()[-3000:]}")
    assert len(fresh(probe, 0.5)) > 200


def test_port_unplugged_and_back_reconnects(probe: Probe, peer: PtyRigPeer, driver: Driver) -> None:
    disconnects0, connects0 = probe.diag("disconnects"), probe.diag("connects")
    peer.unplug()
    probe.spin_for(0.5)
    assert probe.spin_until(lambda: probe.diagnostics.get("state") == "closed", EVENT_TIMEOUT), probe.diagnostics
    assert not fresh(probe, 0.3)
    peer.plug()
    plugged = time.monotonic()
    assert probe.spin_until(lambda: len(probe.samples) > 10, EVENT_TIMEOUT), driver.output()[-2000:]
    print(f"samples again {time.monotonic() - plugged:.3f} s after the port came back")
    assert probe.spin_until(lambda: probe.diag("disconnects") == disconnects0 + 1
                            and probe.diag("connects") == connects0 + 1, EVENT_TIMEOUT), probe.diagnostics
    assert driver.process.poll() is None


def test_a_rig_with_another_protocol_is_refused(probe: Probe, tmp_path: Path) -> None:
    other = PtyRigPeer(str(tmp_path / "old_rig"), version=table.PROTOCOL_VERSION + 1)
    other.start()
    log = tmp_path / "driver.log"
    try:
        with open(log, "w") as out:
            process = subprocess.Popen([sys.executable, "-m", "worm_rig_driver.nodes.driver_node", "--ros-args",
                                        "-r", "__node:=driver_node_old", "-p", f"port:={other.link}"],
                                       stdout=out, stderr=subprocess.STDOUT)
        # the refusal as a user sees it on /diagnostics, which also says the node is built and running (a
        # stop signal while it is still being built ends it with 130, as every node here)
        refused = (int.from_bytes(DiagnosticStatus.ERROR, "little"), "firmware speaks another protocol version")
        running = probe.spin_until(lambda: probe.messages.get("driver_node_old") == refused
                                   or process.poll() is not None, START_TIMEOUT)
        assert running and process.poll() is None, (probe.messages, log.read_text())
        assert stop_process(process) == 0, log.read_text()
    finally:
        other.close()
    text = log.read_text()
    assert f"incompatible firmware: protocol v{table.PROTOCOL_VERSION + 1}" in text
    assert other.log.setpoints == [] and other.log.telemetry_sent == 0
