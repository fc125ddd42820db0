"""System test: Foxglove's own decoders read every message of the bags we write, as our reader reads them.

The graph of sim_graph.yaml runs over DDS at 150 rad/s under a load command while three `recorder`
processes record every topic of it at once: MCAP (the default), MCAP with zstd chunks
(``compression:=zstd``) and sqlite3. ``bag import`` writes RigSample bags from a CSV (MCAP and
sqlite3). Each bag is decoded by tests/foxglove/decode.mjs (Node, with @mcap/core, @mcap/support's
decompressors, @foxglove/rosmsg and @foxglove/rosmsg2-serialization: what Foxglove runs; for
sqlite3, Foxglove's @foxglove/rosbag2-web) and by worm_model.bags.reader.BagReader; every message
of every topic must be there in both, with the same receive time and every field equal: floats
exactly (NaN equal to NaN), 64-bit integers exactly, arrays element by element. `make setup`
installs the npm packages (npm ci, pinned by tests/foxglove/package-lock.json).
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import re
import shutil
import subprocess
import time
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from worm_msgs.msg import LoadCommand

from torque_estimator.graph.runner import Graph, batch_rate, parse_overrides
from worm_model.bags.reader import BagReader
from worm_model.ros.ament import find_executable
from worm_model.ros.testing import probe_node, stop_process

REPO = Path(__file__).resolve().parents[1]
FOXGLOVE = REPO / "tests" / "foxglove"
LAYOUT = REPO / "docs" / "foxglove_layout.json"
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
#: recording name -> (storage, compression)
RECORDINGS = {"mcap": ("mcap", "none"), "mcap_zstd": ("mcap", "zstd"), "sqlite3": ("sqlite3", "none")}
#: the types the graph publishes (with a recorder subscribed to everything) and this test's probe adds
GRAPH_TYPES = {
    "worm_msgs/msg/RigSamples", "worm_msgs/msg/SimTruth", "worm_msgs/msg/SimTruths", "worm_msgs/msg/MotorCurrents",
    "worm_msgs/msg/EncoderCounts", "worm_msgs/msg/GearboxForces", "worm_msgs/msg/TorqueEstimate",
    "worm_msgs/msg/SpeedCommand", "worm_msgs/msg/LoadCommand", "sensor_msgs/msg/JointState",
    "geometry_msgs/msg/WrenchStamped", "diagnostic_msgs/msg/DiagnosticArray", "std_msgs/msg/Float64",
}
RECORD_S = 3.0  # [s] recorded once every recorder records /torque_estimate
START_TIMEOUT = 60.0  # [s]
DECODE_TIMEOUT = 120.0  # [s]


def foxglove_decode(bag: Path) -> list[dict[str, Any]]:
    """Every message of the bag as decode.mjs prints it (JSON lines), 64-bit ints and non-finite floats restored."""
    node = shutil.which("node")
    assert node and (FOXGLOVE / "node_modules" / "@mcap" / "core").is_dir(), \
        "Node or the Foxglove test's npm packages are missing: run make setup"
    done = subprocess.run([node, str(FOXGLOVE / "decode.mjs"), str(bag)], capture_output=True, text=True,
                          timeout=DECODE_TIMEOUT)
    assert done.returncode == 0, done.stderr
    return [json.loads(line, object_hook=_special) for line in done.stdout.splitlines()]


def _special(obj: dict[str, Any]) -> Any:
    if obj.keys() == {"$int"}:
        return int(obj["$int"])
    if obj.keys() == {"$float"}:
        return float(obj["$float"])
    return obj


def plain(value: Any) -> Any:
    """A message decoded by rosbags (dataclasses, numpy arrays) as plain Python values."""
    if dataclasses.is_dataclass(value):
        # not rosbags' __msgtype__, nor the constants it keeps as fields (upper case, as ROS 2 requires
        # of constants and forbids for field names); Foxglove's MessageReader has fields only
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if not f.name.startswith("__") and not f.name[0].isupper()}
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()]
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def differences(ours: Any, theirs: Any, path: str) -> Iterator[str]:
    """Where two plain values differ (exactly; NaN equals NaN; bool stays bool)."""
    if isinstance(ours, dict) and isinstance(theirs, dict):
        if ours.keys() != theirs.keys():
            yield f"{path}: fields {sorted(ours)} != {sorted(theirs)}"
            return
        for key in ours:
            yield from differences(ours[key], theirs[key], f"{path}.{key}")
    elif isinstance(ours, list) and isinstance(theirs, list):
        if len(ours) != len(theirs):
            yield f"{path}: {len(ours)} != {len(theirs)} elements"
            return
        for i, (a, b) in enumerate(zip(ours, theirs)):
            yield from differences(a, b, f"{path}[{i}]")
    elif isinstance(ours, bool) or isinstance(theirs, bool):
        if ours is not theirs:
            yield f"{path}: {ours!r} != {theirs!r}"
    elif isinstance(ours, float) and isinstance(theirs, (int, float)):
        if not (ours == theirs or (math.isnan(ours) and math.isnan(float(theirs)))):
            yield f"{path}: {ours!r} != {theirs!r}"
    elif type(ours) is not type(theirs) or ours != theirs:
        yield f"{path}: {ours!r} != {theirs!r}"


def compare_with_foxglove(bag: Path) -> dict[str, tuple[str, int]]:
    """Assert Foxglove's decoding equals ours message by message; return {topic: (type, count)}."""
    theirs: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for line in foxglove_decode(bag):
        theirs[line["topic"]].append(line)
    ours: dict[str, list[tuple[int, Any]]] = defaultdict(list)
    with BagReader(bag) as reader:
        types = {name: info.type for name, info in reader.topics.items()}
        for message in reader.messages():
            ours[message.topic].append((message.timestamp, plain(message.decoded)))
    assert sorted(theirs) == sorted(ours), f"{bag}: topics differ"
    problems: list[str] = []
    for topic, messages in ours.items():
        if len(messages) != len(theirs[topic]):
            problems.append(f"{topic}: {len(messages)} messages here, {len(theirs[topic])} in Foxglove")
            continue
        for i, ((stamp, value), line) in enumerate(zip(messages, theirs[topic])):
            if line["type"] != types[topic]:
                problems.append(f"{topic}: type {line['type']} in Foxglove, {types[topic]} here")
            if int(line["log_time"]) != stamp:
                problems.append(f"{topic}[{i}]: receive time {stamp} here, {line['log_time']} in Foxglove")
            problems.extend(differences(value, line["message"], f"{topic}[{i}]"))
            if len(problems) > 20:
                break
    assert not problems, f"{bag}: Foxglove decodes differently:\n" + "\n".join(problems[:20])
    return {topic: (types[topic], len(messages)) for topic, messages in ours.items()}


@dataclasses.dataclass(frozen=True)
class Recordings:
    """The recorded bags, {name: path}, and the window [ns, system clock] the worm was held at the set-point."""
    bags: dict[str, Path]
    window: tuple[int, int]


@pytest.fixture(scope="module")
def recordings(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Recordings:
    """The graph at 150 rad/s under a load command, recorded by three recorders."""
    tmp = tmp_path_factory.mktemp("foxglove")
    recorders: dict[str, tuple[subprocess.Popen, Path]] = {}
    graph = Graph(GRAPH_FILE, parse_overrides(["controller_node.speed_setpoint=150.0"]), tmp / "logs")
    try:
        graph.start()
        for name, (storage, compression) in RECORDINGS.items():
            log_path = tmp / f"{name}.log"
            with log_path.open("wb") as log:
                recorders[name] = subprocess.Popen(
                    [str(find_executable("recorder")), "--ros-args", "-p", f"output:={tmp / name}",
                     "-p", f"storage:={storage}", "-p", f"compression:={compression}",
                     "-p", "discovery_period:=0.2"],
                    stdout=log, stderr=subprocess.STDOUT, env=ros_env), log_path
        with probe_node("foxglove_probe") as (probe, executor):
            latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
            load = probe.create_publisher(LoadCommand, "/rig/load_command", latched)
            setpoint = probe.create_publisher(Float64, "/controller/speed_setpoint", latched)
            # the window starts once every recorder records and the worm is at the set-point: on a busy machine
            # the controller's process can come up seconds after the rig's, whose topics the recorders record
            speeds: list[float] = []
            probe.create_subscription(JointState, "/rig/joint_states",
                                      lambda m: speeds.append(m.velocity[0]), qos_profile_sensor_data)

            def logs() -> dict[str, str]:
                return {name: log.read_text(errors="replace") for name, (_, log) in recorders.items()}

            deadline = time.monotonic() + START_TIMEOUT
            while not (all("Recording /torque_estimate" in text and "Recording /rig/load_command" in text
                           for text in logs().values()) and speeds and abs(speeds[-1] - 150.0) < 5.0):
                assert not graph.failed() and all(p.poll() is None for p, _ in recorders.values()), logs()
                assert time.monotonic() < deadline, (f"the worm at {speeds[-5:]} rad/s", logs())
                load.publish(LoadCommand(torque=0.1))
                setpoint.publish(Float64(data=150.0))
                executor.spin_once(timeout_sec=0.2)
            window_start = time.time_ns()  # the recorders stamp receive times on the system clock
            end = time.monotonic() + RECORD_S
            while time.monotonic() < end:  # a load step in the middle
                load.publish(LoadCommand(torque=0.1 if time.monotonic() < end - RECORD_S / 2 else 0.2))
                setpoint.publish(Float64(data=150.0))
                executor.spin_once(timeout_sec=0.2)
            window = (window_start, time.time_ns())
    finally:
        codes = graph.stop()
        time.sleep(0.5)  # the last outputs reach the recorders
        recorder_codes = {name: stop_process(process, grace=60.0) for name, (process, _) in recorders.items()}
    assert all(code == 0 for code in codes.values()), codes
    outputs = {name: log.read_text(errors="replace") for name, (_, log) in recorders.items()}
    assert all(code == 0 for code in recorder_codes.values()), (recorder_codes, outputs)
    return Recordings({name: tmp / name for name in RECORDINGS}, window)


@pytest.mark.parametrize("name", list(RECORDINGS))
def test_foxglove_decodes_every_recorded_message_as_we_do(recordings: Recordings, name: str) -> None:
    bag = recordings.bags[name]
    topics = compare_with_foxglove(bag)
    print(name, {topic: count for topic, (_, count) in sorted(topics.items())})
    types = {type_name for type_name, _ in topics.values()}
    assert GRAPH_TYPES <= types, f"not recorded: {sorted(GRAPH_TYPES - types)}"
    assert topics["/rig/samples"][1] > 0.5 * RECORD_S * batch_rate(GRAPH_FILE)
    storage, compression = RECORDINGS[name]
    if storage == "mcap":  # chunks compressed as asked (what Foxglove had to decompress)
        (file,) = bag.glob("*.mcap")
        with file.open("rb") as stream:
            summary = make_reader(stream).get_summary()
        assert summary is not None and summary.chunk_indexes
        expected = "zstd" if compression == "zstd" else ""
        assert {c.compression for c in summary.chunk_indexes} == {expected}


def layout_paths() -> list[str]:
    """The message paths the plots of docs/foxglove_layout.json draw."""
    layout = json.loads(LAYOUT.read_text(encoding="utf-8"))
    return [path["value"] for panel in layout["configById"].values() for path in panel.get("paths", [])]


def resolve(path: str, topics: set[str], messages: list[dict[str, Any]]) -> list[Any]:
    """A Foxglove message path (``/topic.field.sub[i]``) evaluated on every message of its topic."""
    topic = max((t for t in topics if path.startswith(t + ".")), key=len, default=None)
    assert topic is not None, f"{path}: no such topic in the recording ({sorted(topics)})"
    steps = re.findall(r"\.(\w+)|\[(\d+)\]", path[len(topic):])
    values = []
    for line in messages:
        if line["topic"] != topic:
            continue
        value = line["message"]
        for field, index in steps:
            value = value[field] if field else value[int(index)]
        values.append(value)
    return values


def test_layout_plots_what_a_recording_holds(recordings: Recordings) -> None:
    """Every path the shipped Foxglove layout plots is a number in every message of a recorded run."""
    lines = foxglove_decode(recordings.bags["mcap"])
    topics = {line["topic"] for line in lines}
    paths = layout_paths()
    assert {"/torque_estimate.torque", "/sim/truth.tau_load", "/rig/speed_command.speed_setpoint"} <= set(paths)
    for path in paths:
        values = resolve(path, topics, lines)
        assert len(values) > 10 and all(isinstance(v, float | int) and math.isfinite(v) for v in values), path
    first, last = recordings.window
    window = [line for line in lines if first <= int(line["log_time"]) <= last]
    speed = resolve("/rig/joint_states.velocity[0]", topics, window)
    names = {tuple(line["message"]["name"]) for line in lines if line["topic"] == "/rig/joint_states"}
    # the worm's, at the set-point through the window the fixture held it there (before it the graph starts; after
    # it the graph stops first and the rig's watchdog brakes the worm while the recorders still record)
    assert names == {("worm", "gear")} and len(speed) > 10 and abs(float(np.median(speed)) - 150.0) < 5.0


def rig_csv(path: Path, rows: int) -> None:
    """A rig-data CSV with every column, an empty optional cell (NaN) and awkward floats."""
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(["t", "current_drive", "omega_worm", "theta_worm", "tau_load",
                         "voltage_drive", "theta_gear", "current_load", "temperature"])
        for i in range(rows):
            t = i * 1e-3
            writer.writerow([repr(t), repr(0.3 + 0.01 * math.sin(i)), repr(150.0 + 1e-13 * i), repr(150.0 * t),
                             repr(0.1 if i < rows // 2 else -0.2), repr(6.0 + (i % 70) / 7),
                             "" if i % 10 == 3 else repr(150.0 * t / 30.0), repr(-1.5e-300 * i), repr(25.0)])


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_foxglove_decodes_bag_import_as_we_do(tmp_path: Path, storage: str) -> None:
    rows = 500
    rig_csv(tmp_path / "run.csv", rows)
    bag = tmp_path / "imported"
    done = subprocess.run([str(find_executable("bag")), "import", str(tmp_path / "run.csv"), "--out", str(bag),
                           "--storage", storage], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    topics = compare_with_foxglove(bag)
    assert {t for t, _ in topics.values()} == {"worm_msgs/msg/RigSample"}
    assert sum(count for _, count in topics.values()) == rows
    theirs = foxglove_decode(bag)
    assert sum(math.isnan(line["message"]["theta_gear"]) for line in theirs) == rows // 10
