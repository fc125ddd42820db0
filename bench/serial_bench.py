"""Serial link benchmarks: the Python decoder's throughput and driver_node's CPU at 1 kHz telemetry.

Prints (stdout):
  decoder_throughput: <x> frames/s   StreamDecoder on a stream of telemetry frames, fed in 4 KiB reads
  driver_cpu_at_1khz: <x> %          CPU time of the driver_node process (user + system, /proc) per
                                     wall second, while a pty peer streams 1 kHz telemetry to it and it
                                     publishes /rig/sample (+ the decimated channels); 100 % = one core
  driver_reconnect_time: <x> s       from the port reappearing (pty recreated behind the same path)
                                     to driver_node's new handshake reaching the peer
Progress on stderr. Runs driver_node on its own ROS_DOMAIN_ID (the environment's if set, else a random one
in 100..230), discovery on this host.
"""
from __future__ import annotations

import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from worm_model.ros.testing import local_domain, stop_process
from worm_rig_driver.protocol.codec import StreamDecoder, encode_frame
from worm_rig_driver.link.rig_peer import PtyRigPeer

FRAMES = 200_000
CPU_WINDOW = 5.0  # [s]
WARMUP = 2.0  # [s]


def log(message: str) -> None:
    print(f"[serial_bench] {message}", file=sys.stderr, flush=True)


def decoder_throughput() -> float:
    rng = random.Random(1)
    frames = [encode_frame("TELEMETRY", i & 0xFFFF, t_us=1000 * i & 0xFFFFFFFF,
                           current_drive=rng.randrange(1024), current_load_1=rng.randrange(1024),
                           current_load_2=rng.randrange(1024), tacho_drive=rng.randrange(1024),
                           tacho_load_1=rng.randrange(1024), tacho_load_2=rng.randrange(1024),
                           count_drive=rng.randrange(-2**31, 2**31), count_load_1=rng.randrange(-2**20, 2**20),
                           count_load_2=rng.randrange(-2**20, 2**20), duty_drive=rng.randrange(-10000, 10001),
                           duty_load_1=0, duty_load_2=0, status=0, cmd_seq=i & 0xFFFF)
              for i in range(2000)]
    stream = b"".join(frames[i % len(frames)] for i in range(FRAMES))
    chunks = [stream[i:i + 4096] for i in range(0, len(stream), 4096)]
    decoder = StreamDecoder()
    start = time.perf_counter()
    n = 0
    for chunk in chunks:
        n += len(decoder.feed(chunk))
    elapsed = time.perf_counter() - start
    assert n == FRAMES and decoder.stats.bad_frames == 0
    return n / elapsed


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def wait_for(condition, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def driver_figures() -> tuple[float, float]:
    env = dict(os.environ, **local_domain())
    with tempfile.TemporaryDirectory() as tmp:
        peer = PtyRigPeer(str(Path(tmp) / "rig"))
        peer.start()
        driver_log = Path(tmp) / "driver.log"
        with open(driver_log, "w") as out:
            driver = subprocess.Popen([sys.executable, "-m", "worm_rig_driver.nodes.driver_node", "--ros-args",
                                       "-p", f"port:={peer.link}"], stdout=out, stderr=subprocess.STDOUT, env=env)
        try:
            if not wait_for(lambda: peer.streaming, 60.0):
                raise RuntimeError(f"driver_node did not start streaming:\n{driver_log.read_text()[-2000:]}")
            time.sleep(WARMUP)
            sent0, cpu0, t0 = peer.log.telemetry_sent, cpu_seconds(driver.pid), time.monotonic()
            time.sleep(CPU_WINDOW)
            sent1, cpu1, t1 = peer.log.telemetry_sent, cpu_seconds(driver.pid), time.monotonic()
            rate = (sent1 - sent0) / (t1 - t0)
            cpu = 100.0 * (cpu1 - cpu0) / (t1 - t0)
            log(f"peer streamed {rate:.0f} Hz for {t1 - t0:.1f} s; driver_node used {cpu1 - cpu0:.2f} s of CPU")

            hellos = peer.log.hellos
            peer.unplug()
            time.sleep(0.5)
            peer.plug()
            plugged = time.monotonic()
            if not wait_for(lambda: peer.log.hellos > hellos and peer.streaming, 10.0):
                raise RuntimeError("driver_node did not reconnect within 10 s")
            reconnect = time.monotonic() - plugged
        finally:
            stop_process(driver)
            peer.close()
    return cpu, reconnect


def main() -> int:
    log(f"decoding {FRAMES} telemetry frames")
    throughput = decoder_throughput()
    print(f"decoder_throughput: {throughput:.0f} frames/s", flush=True)
    log("driver_node on a pty with a 1 kHz peer")
    cpu, reconnect = driver_figures()
    print(f"driver_cpu_at_1khz: {cpu:.1f} %", flush=True)
    print(f"driver_reconnect_time: {reconnect:.3f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
