"""Recorder benchmark: RigSample at 1 kHz for 5 minutes into the `recorder` node; nothing may be lost.

This process publishes worm_msgs/RigSample with consecutive seq at --rate for
--duration; the installed `recorder` executable (its own process, as `ros2 run
worm_rig_driver recorder`) records /rig/sample into a bag; on SIGINT it writes
what is queued, closes the bag and states what it lost. Then the bag is read
back from storage and every seq checked.

Prints `<metric>: <value> <unit>`:
    recorder_published       messages published
    recorder_recorded        messages in the bag (read from storage)
    recorder_lost_messages   published - recorded
    recorder_seq_gaps        seqs missing between the first and last recorded one
    recorder_verdict_agrees  1 if the recorder's own end-of-run line says what the bag shows
    recorder_publish_rate    achieved publishing rate
    recorder_duration        publishing time
    recorder_bag_size        size of the bag

QoS (--qos): `reliable` (default) is KEEP_LAST(--depth) RELIABLE, so only a
recorder that falls behind by more than --depth messages loses any: it
measures the recorder. `stream` is the graph's sensor-data profile (best
effort, depth 100): it measures the recorder plus DDS on this machine.
Use its own ROS_DOMAIN_ID (run_all.py sets one) and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST.
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from worm_msgs.msg import RigSample

from worm_model.ros.qos import STREAM
from worm_model.bags.reader import BagReader
from worm_model.ros.ament import find_executable
from worm_model.bags.seq_check import StreamCheck

TOPIC = "/rig/sample"
DISCOVERY_TIMEOUT = 30.0  # [s]
EXIT_TIMEOUT = 60.0  # [s] for the recorder to drain and close after SIGINT


def publish(node: Node, recorder: subprocess.Popen, args: argparse.Namespace) -> tuple[int, float]:
    """Publish seq 0..n-1 at args.rate once the recorder subscribed; returns (n, seconds)."""
    if args.qos == "reliable":
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=args.depth,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    else:
        qos = STREAM
    publisher = node.create_publisher(RigSample, TOPIC, qos)
    deadline = time.monotonic() + DISCOVERY_TIMEOUT
    while publisher.get_subscription_count() == 0:
        if recorder.poll() is not None or time.monotonic() > deadline:
            raise SystemExit("recorder_bench: the recorder did not subscribe")
        time.sleep(0.05)
    n = int(round(args.duration * args.rate))
    period = 1.0 / args.rate
    start = time.perf_counter()
    msg = RigSample(status=RigSample.STATUS_SIMULATED)
    msg.header.frame_id = "worm_rig"
    for seq in range(n):
        msg.seq = seq
        msg.omega_worm = 1e-3 * seq
        msg.header.stamp = node.get_clock().now().to_msg()
        publisher.publish(msg)
        if (delay := start + (seq + 1) * period - time.perf_counter()) > 0:
            time.sleep(delay)
        if seq % 10000 == 0 and seq:
            print(f"[recorder_bench] {seq}/{n} published", file=sys.stderr, flush=True)
    elapsed = time.perf_counter() - start
    if args.qos == "reliable":
        publisher.wait_for_all_acked(Duration(seconds=30))
    return n, elapsed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=300.0,
                        help="[s] publishing time (default 300 = the issue's 5 minutes)")
    parser.add_argument("--rate", type=float, default=1000.0, help="[Hz] publishing rate (default 1000)")
    parser.add_argument("--qos", choices=("reliable", "stream"), default="reliable",
                        help="publisher QoS: reliable KEEP_LAST(--depth), or the graph's best-effort "
                             "stream profile (default reliable)")
    parser.add_argument("--depth", type=int, default=10000,
                        help="[messages] KEEP_LAST depth of the reliable publisher (default 10000 = 10 s)")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="bag storage")
    parser.add_argument("--keep", type=Path, default=None,
                        help="write the bag here and keep it (default: a temporary directory)")
    args = parser.parse_args(argv)

    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.update(env)
    with tempfile.TemporaryDirectory(prefix="recorder_bench_") as tmp:
        bag = args.keep if args.keep is not None else Path(tmp) / "bag"
        log_path = Path(tmp) / "recorder.log"
        with log_path.open("wb") as log:
            recorder = subprocess.Popen(
                [str(find_executable("recorder")), "--ros-args", "-p", f"output:={bag}",
                 "-p", f"storage:={args.storage}", "-p", f"topics:=[{TOPIC}]", "-p", "discovery_period:=0.2"],
                env=env, stdout=log, stderr=subprocess.STDOUT)
        rclpy.init()
        node = Node("recorder_bench_source")
        try:
            published, elapsed = publish(node, recorder, args)
        finally:
            node.destroy_node()
            rclpy.try_shutdown()
            recorder.send_signal(signal.SIGINT)
            try:
                code = recorder.wait(EXIT_TIMEOUT)
            except subprocess.TimeoutExpired:
                recorder.kill()
                code = recorder.wait()
        output = log_path.read_text(errors="replace")
        if code != 0:
            print(output[-3000:], file=sys.stderr)
            raise SystemExit(f"recorder_bench: recorder exited with {code}")

        with BagReader(bag) as reader:
            check = StreamCheck()
            check.watch(TOPIC, reader.typestore_for("worm_msgs/msg/RigSample"), "worm_msgs/msg/RigSample")
            recorded = 0
            for message in reader.raw_messages([TOPIC]):
                recorded += 1
                check.add(TOPIC, message.data)
        size = sum(p.stat().st_size for p in bag.rglob("*") if p.is_file())
    tracker = check.trackers[TOPIC]
    lost = published - recorded
    said_nothing_lost = "recorder: lost nothing" in output
    verdict_agrees = said_nothing_lost == (tracker.lost == 0)
    for line in output.splitlines():
        if "recorder:" in line or "seq " in line:
            print(f"[recorder_bench] {line.strip()}", file=sys.stderr)
    print(f"[recorder_bench] bag: {tracker.summary()}", file=sys.stderr)
    print(f"recorder_published: {published} count")
    print(f"recorder_recorded: {recorded} count")
    print(f"recorder_lost_messages: {lost} count")
    print(f"recorder_seq_gaps: {tracker.lost} count")
    print(f"recorder_verdict_agrees: {int(verdict_agrees)} bool")
    print(f"recorder_publish_rate: {published / elapsed:.1f} Hz")
    print(f"recorder_duration: {elapsed:.1f} s")
    print(f"recorder_bag_size: {size / 2**20:.1f} MiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
