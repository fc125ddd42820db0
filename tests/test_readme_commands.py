"""The documented command lines, run as a user runs them: every `ros2 run` line of docs/running.md's "The nodes,
one by one or as a graph" through the installed executable (where `ros2 run` finds it), every `ros2 topic pub`
line with exactly the QoS the CLI publishes with by default (reliable, volatile, depth 10).

The lines are read from the page itself; a line this test does not know how to run fails it, so a command
added to the page comes with its test. (`calibrate --live [--resume]` is run by test_calibrate_live_dds.)
"""
from __future__ import annotations

import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from worm_model.rig_data.samples import unbatch
from worm_model.ros.ament import find_executable
from worm_model.ros.qos import STREAM
from worm_model.ros.testing import probe_node, stop_process, spin_until

REPO = Path(__file__).resolve().parents[1]
GRAPH_FILE = REPO / "ros_ws" / "src" / "torque_estimator" / "config" / "sim_graph.yaml"
#: what `ros2 topic pub` offers by default (ros2cli: QoSProfile(depth=10), reliable, volatile)
TOPIC_PUB_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.VOLATILE)
START_TIMEOUT = 45.0  # [s]


PAGE = REPO / "docs" / "running.md"
SECTION = ("## The nodes, one by one or as a graph", "## Choosing the estimator")


def documented_commands() -> list[str]:
    """The `ros2 ...` lines of the code block of docs/running.md's section SECTION, comments dropped."""
    text = PAGE.read_text(encoding="utf-8")
    section = text[text.index(SECTION[0]):text.index(SECTION[1])]
    lines = []
    for block in re.findall(r"```\n(.*?)```", section, flags=re.S):
        for line in block.splitlines():
            line = line.split("#", 1)[0].strip()
            if line.startswith("ros2 "):
                lines.append(re.sub(r"\s+", " ", line))
    return lines


def command(line: str, tmp: Path) -> list[str]:
    """A `ros2 run <pkg> <exe> args` line as the process `ros2 run` starts, files moved into tmp."""
    words = line.replace("\"", "").split()
    assert words[:2] == ["ros2", "run"], line
    args = []
    for word in words[4:]:
        word = word.replace("ros_ws/src/torque_estimator/config/sim_graph.yaml", str(GRAPH_FILE))
        word = word.replace(".../sim_graph.yaml", str(GRAPH_FILE))
        word = word.replace("calibration.json", str(tmp / "calibration.json"))
        word = re.sub(r"\bmy_bag\b", str(tmp / "my_bag"), word)
        args.append(word)
    return [str(find_executable(words[3])), *args]


def topic_pub(node, line: str):
    """Publish a `ros2 topic pub <topic> <type> "<yaml>"` line once its subscriber matches."""
    m = re.fullmatch(r"ros2 topic pub (\S+) (\S+)/msg/(\S+) \"?(\{.*\})\"?", line)
    assert m, line
    topic, package, name, values = m.groups()
    msg_type = getattr(__import__(f"{package}.msg", fromlist=[name]), name)
    msg = msg_type(**yaml.safe_load(values))
    return node.create_publisher(msg_type, topic, TOPIC_PUB_QOS), msg


def test_every_documented_command(ros_env: dict[str, str], tmp_path: Path) -> None:
    lines = documented_commands()
    nodes = [line for line in lines if re.match(r"ros2 run \S+ \S+_node ", line)]
    pubs = [line for line in lines if line.startswith("ros2 topic pub ")]
    graphs = [line for line in lines if " run_graph " in line]
    known = {"calibrate_out": [line for line in lines if " calibrate " in line and "--live" not in line],
             "live": [line for line in lines if " calibrate " in line and "--live" in line],
             "recorder": [line for line in lines if " recorder " in line],
             "bag": [line for line in lines if " bag info " in line],
             "replay": [line for line in lines if " replay " in line]}
    handled = set(nodes) | set(pubs) | set(graphs) | {line for group in known.values() for line in group}
    assert set(lines) == handled, f"documented commands with no test: {sorted(set(lines) - handled)}"
    assert len(nodes) == 3 and len(pubs) == 2 and len(graphs) == 3 and all(len(v) == 1 for v in known.values())

    done = subprocess.run(command(known["calibrate_out"][0], tmp_path), env=ros_env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0 and (tmp_path / "calibration.json").exists(), done.stderr

    # the three nodes, one `ros2 run` each, then the two `ros2 topic pub` lines and the recorder
    procs = [subprocess.Popen(command(line, tmp_path), env=ros_env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True) for line in nodes]
    recorder = None
    try:
        with probe_node("readme_probe") as (probe, executor):
            samples: list = []
            probe.create_subscription(__import__("worm_msgs.msg", fromlist=["RigSamples"]).RigSamples,
                                      "/rig/samples", lambda m: samples.extend(unbatch(m)), STREAM)

            assert spin_until(executor, lambda: bool(samples), START_TIMEOUT), "the documented nodes did not stream"
            recorder = subprocess.Popen(command(known["recorder"][0], tmp_path), env=ros_env,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            # the recorder has subscribed (model, this probe and it)
            assert spin_until(executor, lambda: probe.count_subscribers("/rig/samples") >= 3, START_TIMEOUT)
            published = [topic_pub(probe, line) for line in pubs]
            # matched by the commanded node (its volatile subscription) and by the recorder (it records every
            # topic): one match alone may be the recorder's, which finds a new publisher within 0.1 s, and a
            # volatile message sent before the node has matched never reaches it
            assert spin_until(executor, lambda: all(pub.get_subscription_count() >= 2 for pub, _ in published), 30.0)
            for pub, msg in published:  # `ros2 topic pub` repeats at 1 Hz: twice is enough here
                pub.publish(msg)
            spin_until(executor, lambda: False, 1.0)
            for pub, msg in published:
                pub.publish(msg)
            samples.clear()
            spin_until(executor, lambda: False, 3.0)
            speed = sum(s.omega_worm for s in samples[-500:]) / 500
            load = sum(s.tau_load for s in samples[-500:]) / 500
            assert speed == pytest.approx(150.0, abs=3.0) and load == pytest.approx(0.2, abs=0.01), (speed, load)
    finally:
        if recorder is not None:
            assert stop_process(recorder, grace=30.0) == 0, recorder.stderr.read()
        codes = [stop_process(p) for p in procs]
    assert codes == [0, 0, 0], codes

    done = subprocess.run(command(known["bag"][0], tmp_path), env=ros_env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and "/rig/samples" in done.stdout, done.stderr
    done = subprocess.run(command(known["replay"][0], tmp_path) + ["--quiet"], env=ros_env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "replay_speed_factor" in done.stdout

    # the whole graph from one file, both ways: it streams, and Ctrl-C stops every node cleanly
    for line in graphs:
        proc = subprocess.Popen(command(line, tmp_path), env=ros_env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
        try:
            with probe_node("readme_graph_probe") as (probe, executor):
                got: list = []
                probe.create_subscription(__import__("worm_msgs.msg", fromlist=["RigSamples"]).RigSamples,
                                          "/rig/samples", got.append, STREAM)
                deadline = time.monotonic() + START_TIMEOUT
                while len(got) < 20 and time.monotonic() < deadline:
                    executor.spin_once(timeout_sec=0.05)
                assert len(got) >= 20, f"{line}: no samples"
        finally:
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=60)
        assert proc.returncode == 0, f"{line}: exit {proc.returncode}\n{err}"
