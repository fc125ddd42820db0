"""The graph split over two hosts, as a rig computer and a workstation run it, and the link between them cut.

Two network namespaces joined by a veth pair stand for the two hosts (worm_model.ros.two_hosts; the test
creates and removes them; it needs root, as CI has): the rig computer runs sim_node (whose load observer feeds
forward and publishes the graph's /torque_estimate) and controller_node, the workstation runs model_node and a
recorder. DDS finds its peers across the link by multicast (ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET). Fast DDS
is kept to UDP (FASTDDS_BUILTIN_TRANSPORTS=UDPv4), the only transport two real hosts share: two namespaces of
one machine also share /dev/shm, and whether the shared-memory transport pairs them depends on how a Fast DDS
version tells hosts apart (Kilted's did not here; the data stopped at the cut either way).

The rig runs at 150 rad/s against +0.1 N m; then the link is taken down for CUT seconds and brought back.
Judged on the streams' own stamps, in bags recorded on each side:

* the control path lives on the rig computer and does not notice the cut: the estimate goes on (no gap in
  the rig's /torque_estimate), the controller goes on commanding with the feedforward at the rig, the
  speed holds; the controller never feeds forward an estimate older than its estimate_timeout (0.05 s);
* the workstation's recorder sees the gap: no rig sample stamped inside the cut, and its loss report
  (DDS sequence numbers) counts the samples the rig published meanwhile;
* with the link back the workstation's streams resume without a node restarted (the same processes
  run throughout and exit cleanly at the end).
"""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from torque_estimator.graph.runner import Graph, batch_rate, parse_overrides
from worm_model.errors import BagReadError
from worm_model.bags.writer import read_messages
from worm_model.ros.ament import find_executable
from worm_model.ros.two_hosts import TwoHosts, problem

pytestmark = pytest.mark.skipif(bool(problem()), reason=f"creates network namespaces: {problem()} (CI can)")

REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
RIG_NODES = ("sim_node", "controller_node")
STATION_NODES = ("model_node",)
SPEED = 150.0  # [rad/s]
LOAD = 0.1  # [N m]
ESTIMATE_TIMEOUT = 0.05  # [s] controller_node's estimate_timeout (sim_graph.yaml)
CUT = 3.0  # [s] the link is down this long (well inside Fast DDS's 20 s participant lease)
START_TIMEOUT = 60.0  # [s] generous: a loaded 2-core machine starts six Python processes
SUBNET = "10.77.0"  # the two hosts' network (the soak's chaos run uses another)
HOSTS_TAG = "w"  # begins the names of their namespaces and links

# Publishes the load while the test runs (a stand-in for whatever sets the load on a real rig).
LOAD_PUBLISHER = f"""
import rclpy, signal
from worm_msgs.msg import LoadCommand
from worm_model.ros.qos import COMMAND
rclpy.init()
node = rclpy.create_node("load_setter")
pub = node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)
node.create_timer(0.2, lambda: pub.publish(LoadCommand(torque={LOAD})))
signal.signal(signal.SIGINT, lambda *_: rclpy.try_shutdown())
try:
    rclpy.spin(node)
except Exception:
    pass
"""


def stamp_s(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def read(bag: Path, topic: str) -> list:
    """The messages of ``topic`` in the bag so far (the recorder flushes every second), [] if none yet."""
    try:
        return [m for _, m in read_messages(bag, topic)]
    except BagReadError:
        return []


class Run:
    """Every process of the two hosts; logs and bags in ``folder``."""

    def __init__(self, hosts: TwoHosts, env: dict[str, str], folder: Path) -> None:
        self.hosts, self.env, self.folder = hosts, env, folder
        self.graph = Graph(GRAPH_FILE, parse_overrides([f"controller_node.speed_setpoint={SPEED}"]), folder)
        self.processes: dict[str, subprocess.Popen] = {}
        self.rig_bag, self.station_bag = folder / "rig_bag", folder / "station_bag"

    def start(self, name: str, ns: str, command: list[str]) -> None:
        log = open(self.folder / f"{name}.log", "wb")
        self.processes[name] = subprocess.Popen(["ip", "netns", "exec", ns, *command], env=self.env,
                                                stdout=log, stderr=subprocess.STDOUT)

    def recorder(self, name: str, ns: str, bag: Path, topics: str) -> None:
        self.start(name, ns, [str(find_executable("recorder")), "--ros-args", "-p", f"output:={bag}",
                              "-p", f"topics:=[{topics}]", "-p", "discovery_period:=0.1"])

    def log(self, name: str) -> str:
        return (self.folder / f"{name}.log").read_text(errors="replace")

    def start_all(self) -> None:
        for node in RIG_NODES:
            self.start(node, self.hosts.rig, self.graph.command(node))
        self.start("load_setter", self.hosts.rig, [sys.executable, "-c", LOAD_PUBLISHER])
        self.recorder("rig_recorder", self.hosts.rig, self.rig_bag,
                      "/rig/samples,/rig/speed_command,/torque_estimate")
        for node in STATION_NODES:
            self.start(node, self.hosts.station, self.graph.command(node))
        self.recorder("station_recorder", self.hosts.station, self.station_bag,
                      "/rig/samples,/torque_estimate,/gearbox/forces")

    def wait_for(self, what: str, done, timeout: float = START_TIMEOUT) -> None:
        deadline = time.monotonic() + timeout
        while not done():
            assert not (dead := {n: p.returncode for n, p in self.processes.items() if p.poll() is not None}), (
                f"{what}: processes exited {dead}; logs in {self.folder}")
            assert time.monotonic() < deadline, f"{what}: not within {timeout} s; logs in {self.folder}"
            time.sleep(0.5)

    def stop(self) -> dict[str, int]:
        """SIGINT to every process at once (a second one would interrupt a node's clean-up), SIGKILL what
        has not exited 15 s later; returns the exit codes."""
        for p in self.processes.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        deadline = time.monotonic() + 15.0
        for p in self.processes.values():
            try:
                p.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        return {name: p.returncode for name, p in self.processes.items()}


@pytest.fixture(scope="module")
def two_hosts(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Run, float, float]]:
    """The run: (the run, time the link was cut, time it was back) [s, system clock, as the stamps]."""
    hosts = TwoHosts(SUBNET, HOSTS_TAG)
    env = {**ros_env, "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4",
           "OPENBLAS_NUM_THREADS": "1"}
    run = Run(hosts, env, tmp_path_factory.mktemp("two_hosts"))
    hosts.create()
    try:
        run.start_all()
        # feedforward in the rig's bag = the rig's estimate; samples and forces in the station's bag = the link
        run.wait_for("the graph across the link", lambda: any(
            c.feedforward_torque > 0 for c in read(run.rig_bag, "/rig/speed_command")[-50:])
            and read(run.station_bag, "/rig/samples") and read(run.station_bag, "/gearbox/forces"))
        time.sleep(2.0)  # steady at speed before the cut (the judging uses stamps, not this)
        # the times bracket the link's down time from inside: on a busy machine `ip` itself took long enough
        # (taking the time before cutting) that samples stamped 0.1 s after it still crossed
        hosts.cut()
        cut = time.time()
        time.sleep(CUT)
        back = time.time()
        hosts.connect()
        run.wait_for("the workstation's streams after the link came back", lambda: any(
            stamp_s(e.header.stamp) > back for e in read(run.station_bag, "/torque_estimate")[-50:]))
        time.sleep(1.5)  # some feedforward after the return, in the bag
        alive = {n: p.poll() for n, p in run.processes.items()}
        codes = run.stop()
        assert all(code is None for code in alive.values()), f"a process died during the run: {alive}"
        assert all(code == 0 for code in codes.values()), f"unclean exits {codes}; logs in {run.folder}"
        yield run, cut, back
    finally:
        run.stop()
        hosts.remove()


def test_the_control_path_on_the_rig_computer_does_not_notice_the_cut(two_hosts) -> None:
    run, cut, back = two_hosts
    commands = read(run.rig_bag, "/rig/speed_command")
    # An estimate's age when its command goes out: the command's stamp (controller's clock) less the
    # estimate's sample stamp (rig's clock) less the clocks' lag, which FeedforwardGate lets rise by at most
    # 50 ms per s (a simulated rig may fall behind real time): at most any earlier lag + 0.05 x the time since
    # (over the 2 s before: enough, as the lag falls at once to any smaller one).
    sent = [(stamp_s(c.header.stamp), stamp_s(c.header.stamp) - stamp_s(c.sample_stamp), c) for c in commands]
    stale = [c for t, lag, c in sent if c.feedforward_torque != 0.0 and t - stamp_s(c.feedforward_stamp) - min(
        lg + 0.05 * (t - tt) for tt, lg, _ in sent if t - 2.0 <= tt <= t) > ESTIMATE_TIMEOUT + 1e-3]
    assert not stale, f"{len(stale)} commands fed forward an estimate older than {ESTIMATE_TIMEOUT} s"
    # the rig's estimate on the rig computer: no gap across the cut (one per batch)
    estimates = sorted(stamp_s(e.header.stamp) for e in read(run.rig_bag, "/torque_estimate"))
    around = [t for t in estimates if cut - 0.5 < t < back + 0.5]
    # (a stall of the rig's own, 0.11 s once with the demo's calibration beside it, is not the cut's doing)
    assert around and max(b - a for a, b in zip(around, around[1:])) < 0.5, "the rig's estimate stopped at the cut"
    during = [c for c in commands if cut < stamp_s(c.header.stamp) < back]
    assert len(during) > 0.5 * (back - cut) / 0.025, f"the controller went quiet ({len(during)} commands)"
    assert all(c.feedforward_at_rig for c in during) and sum(c.feedforward_torque > 0 for c in during) > \
        0.9 * len(during), "the feedforward did not go on through the cut"
    speeds = [w for m in read(run.rig_bag, "/rig/samples") if cut < stamp_s(m.header.stamp) < back
              for w in m.omega_worm]
    assert speeds and abs(sum(speeds) / len(speeds) - SPEED) < 3.0, "the speed was not held"


def test_the_workstation_recorder_reports_the_gap_and_resumes(two_hosts) -> None:
    run, cut, back = two_hosts
    stamps = sorted(stamp_s(m.header.stamp) for m in read(run.station_bag, "/rig/samples"))
    inside = [t for t in stamps if cut + 0.1 < t < back - 0.1]
    assert not inside, f"{len(inside)} rig samples recorded across a cut link"
    assert stamps[0] < cut and stamps[-1] > back, "the station's bag does not span the cut"
    gap = max(b - a for a, b in zip(stamps, stamps[1:]))
    assert gap > 0.8 * (back - cut), f"longest gap {gap:.2f} s, the link was down {back - cut:.2f} s"
    log = run.log("station_recorder")
    lost = [line for line in log.splitlines() if "recorder: LOST" in line]
    assert lost, f"the recorder did not report the gap:\n{log[-2000:]}"
    # ~ the cut's messages: the batches on /rig/samples, as many estimates... any count > half the batches
    n = int(lost[0].split("recorder: LOST ")[1].split()[0])
    assert n > 0.5 * batch_rate(GRAPH_FILE) * (back - cut), lost[0]
