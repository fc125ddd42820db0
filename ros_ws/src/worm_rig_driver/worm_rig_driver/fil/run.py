"""`make fil`: the rig firmware in the loop with driver_node connected, then a watchdog test.

    python -m worm_rig_driver.fil.run --elf firmware/build/rig.elf --harness firmware/build/libwormfil.so

1. The firmware's ELF runs in simavr (worm_rig_driver.fil.harness), its UART on a pty at
   <log-dir>/rig; the simulated plant closes the loop through the ADC, the encoder
   pins and the PWM duties.
2. driver_node is started on that path (exactly as on /dev/ttyACM0), and
   fil_commander drives the rig through it (a voltage/load profile).
3. Once telemetry flows and fil_commander receives it, the loop runs --duration
   seconds of rig time.
4. The host -> rig line is cut (at a frame boundary) and the time from the last
   byte the firmware received to every bridge off is measured in rig time.
5. Both nodes are stopped (SIGINT); driver_node's link statistics at exit give the
   figures. Progress and details go to stderr; the last line on stdout is

   fil: frames=<n> rate_hz=<r> crc_errors=<n> seq_gaps=<n> watchdog_stop_ms=<t>

   frames: telemetry frames driver_node decoded; rate_hz: their rate in rig
   (firmware) time; crc_errors, seq_gaps: as driver_node counted them.

Exit code 0 when the run completed (whatever the figures), 1 when it could not
(no link, a node died, the AVR stopped), 2 for bad arguments or missing files.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

from worm_model.physics.parameters import load_rig

from worm_rig_driver.fil.harness import FilHarness, FilPlant, FirmwareInTheLoop
from worm_rig_driver.errors import FilError

STATS_MARK = "link statistics at exit: "


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="python -m worm_rig_driver.fil.run", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--elf", type=Path, required=True, help="the firmware ELF (make -C firmware builds build/rig.elf)")
    p.add_argument("--harness", type=Path, required=True,
                   help="the simavr harness library (make -C firmware fil builds build/libwormfil.so)")
    p.add_argument("--duration", type=float, default=10.0,
                   help="rig time [s] to run the closed loop once telemetry flows (default 10)")
    p.add_argument("--log-dir", type=Path, default=Path("out/fil"),
                   help="where the pty link, the nodes' logs and the commander's report go (default out/fil)")
    p.add_argument("--rig-file", default="", help="rig parameter YAML; empty = the bundled NMRV030 rig")
    p.add_argument("--seed", type=int, default=0, help="seed of the plant's sensor noise (default 0)")
    p.add_argument("--speed-mode", action="store_true",
                   help="run the profile with the rig's speed loop (driver_node's PI on every frame, a new duty "
                        "to the firmware each millisecond) instead of held voltages")
    p.add_argument("--domain-id", type=int, default=None,
                   help="ROS_DOMAIN_ID of the run (default: random in 100..230; discovery stays on this host)")
    p.add_argument("--link-timeout", type=float, default=60.0,
                   help="wall time [s] allowed for driver_node to start and bring the link up (default 60)")
    args = p.parse_args(argv)
    if args.duration <= 0:
        p.error("--duration must be > 0")
    return args


def say(message: str) -> None:
    print(f"[fil] {message}", file=sys.stderr, flush=True)


class Nodes:
    """driver_node and fil_commander as child processes with their logs."""

    def __init__(self, log_dir: Path, link: str, env: dict[str, str], speed_mode: bool = False) -> None:
        self.log_dir = log_dir
        self.report = log_dir / "commander.json"
        self.ready = log_dir / "commander.ready"
        for stale in (self.report, self.ready):
            stale.unlink(missing_ok=True)
        common = [sys.executable, "-m"]
        self.driver_log = log_dir / "driver_node.log"
        self.commander_log = log_dir / "fil_commander.log"
        with open(self.driver_log, "w") as out:
            # clock_max_drift 1: the simulated rig's clock may run slower than the host's.
            self.driver = subprocess.Popen(
                common + ["worm_rig_driver.nodes.driver_node", "--ros-args", "-p", f"port:={link}",
                          "-p", "clock_max_drift:=1.0"], stdout=out, stderr=subprocess.STDOUT, env=env)
        with open(self.commander_log, "w") as out:
            self.commander = subprocess.Popen(
                common + ["worm_rig_driver.fil.commander_node", "--ros-args", "-p", f"report_file:={self.report}",
                          "-p", f"ready_file:={self.ready}",
                          "-p", f"speed_mode:={str(speed_mode).lower()}"],
                stdout=out, stderr=subprocess.STDOUT, env=env)

    def failed(self) -> str | None:
        for name, proc in (("driver_node", self.driver), ("fil_commander", self.commander)):
            if proc.poll() is not None:
                return f"{name} exited with {proc.returncode}"
        return None

    def driver_stats(self) -> dict:
        for line in reversed(self.driver_log.read_text(errors="replace").splitlines()):
            if STATS_MARK in line:
                return json.loads(line.split(STATS_MARK, 1)[1])
        return {}

    def tail(self, path: Path, lines: int = 30) -> str:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])

    def kill(self) -> None:
        for proc in (self.commander, self.driver):
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def stop_while_stepping(loop: FirmwareInTheLoop, proc: subprocess.Popen, timeout: float = 15.0) -> int | None:
    """SIGINT a node and keep the rig running until it exits (its shutdown talks to the rig)."""
    proc.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout
    while proc.poll() is None and time.monotonic() < deadline:
        loop.step()
    if proc.poll() is None:
        proc.kill()
    return proc.wait()


def run(args: argparse.Namespace) -> int:
    args.log_dir.mkdir(parents=True, exist_ok=True)
    link = str((args.log_dir / "rig").resolve())
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(args.domain_id if args.domain_id is not None else random.randint(100, 230))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    try:
        rig = load_rig(args.rig_file or None)
        harness = FilHarness(args.harness, args.elf, link)
    except (OSError, ValueError, FilError) as err:
        print(f"fil_run: {err}", file=sys.stderr)
        return 2
    loop = FirmwareInTheLoop(harness, FilPlant(rig, seed=args.seed))
    say(f"firmware {args.elf} in simavr, UART on {link}; ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']}; "
        f"logs in {args.log_dir}")
    nodes = Nodes(args.log_dir, link, env, speed_mode=args.speed_mode)
    try:
        return closed_loop(args, loop, nodes)
    except FilError as err:
        say(f"failed: {err}")
        return 1
    finally:
        nodes.kill()
        harness.close()


def closed_loop(args: argparse.Namespace, loop: FirmwareInTheLoop, nodes: Nodes) -> int:
    # --- wait for telemetry: the AVR sending ~45 bytes per ms ---------------------------------
    deadline = time.monotonic() + args.link_timeout
    window: list[int] = []
    while True:
        out = loop.step()
        window.append(out.avr_bytes)
        window = window[-50:]
        if len(window) == 50 and window[-1] - window[0] > 40 * 49:
            break
        problem = nodes.failed()
        if problem or time.monotonic() > deadline:
            say(f"no telemetry stream: {problem or f'link not up within {args.link_timeout:g} s'}\n"
                f"{nodes.tail(nodes.driver_log)}")
            return 1
    # --- wait for the commander to hear the rig: DDS discovery may take seconds on a busy host ----
    while not nodes.ready.exists():
        for _ in range(20):
            loop.step()
        problem = nodes.failed()
        if problem or time.monotonic() > deadline:
            say(f"fil_commander never received a sample: {problem or f'not within {args.link_timeout:g} s'}\n"
                f"{nodes.tail(nodes.commander_log)}")
            return 1
    start_rig = loop.rig_time
    start_wall = time.monotonic()
    say(f"link up at rig time {start_rig:.3f} s; running {args.duration:g} s of rig time")

    # --- the closed loop ---------------------------------------------------------------------
    next_report = 1.0
    while loop.rig_time - start_rig < args.duration:
        loop.step()
        elapsed = loop.rig_time - start_rig
        if elapsed >= next_report:
            st = loop.status()
            say(f"rig {elapsed:5.1f} s  omega_worm {st.omega_worm:7.1f} rad/s  duty "
                f"{st.duty[0]:+.3f} {st.duty[1]:+.3f} {st.duty[2]:+.3f}")
            next_report += 1.0
            problem = nodes.failed()
            if problem:
                say(f"{problem}\n{nodes.tail(nodes.driver_log)}")
                return 1
    wall = time.monotonic() - start_wall
    say(f"{args.duration:g} s of rig time in {wall:.1f} s of wall time: real-time factor "
        f"{args.duration / wall:.2f} (paced never to exceed 1)")

    # --- cut the commands, time the motors' stop ------------------------------------------------
    stop_s = loop.stop_time_after_cut()
    say(f"host -> rig line cut: every bridge off {stop_s * 1e3:.2f} ms after the last byte received")
    loop.harness.cut(False)
    for _ in range(200):  # the driver sees the watchdog's status before it is stopped
        loop.step()

    commander_code = stop_while_stepping(loop, nodes.commander)
    driver_code = stop_while_stepping(loop, nodes.driver)
    stats = nodes.driver_stats()
    if driver_code != 0 or not stats:
        say(f"driver_node exited {driver_code} without its statistics\n{nodes.tail(nodes.driver_log)}")
        return 1
    if commander_code != 0:
        say(f"fil_commander exited {commander_code}\n{nodes.tail(nodes.commander_log)}")
    if nodes.report.exists():
        report = json.loads(nodes.report.read_text())
        for name, phase in report["phases"].items():
            say(f"phase {name:>14}: {phase['samples']:6d} samples, omega_worm mean {phase['omega_worm_mean']:7.1f} "
                f"rad/s, tau_load mean {phase['tau_load_mean']:+.3f} N m")
    say("driver_node link statistics: " + ", ".join(
        f"{k}={stats[k]}" for k in ("telemetry", "rx_crc_errors", "seq_gaps", "lost_frames", "timeouts",
                                    "handshakes", "rx_discarded_bytes", "fw_rx_crc_errors", "fw_rx_seq_gaps",
                                    "fw_watchdog_stops", "fw_stack_free") if k in stats))
    rate = stats.get("telemetry_rate_hz", math.nan)
    print(f"fil: frames={stats.get('telemetry', 0)} rate_hz={float(rate):.1f} "
          f"crc_errors={stats.get('rx_crc_errors', 0)} "
          f"seq_gaps={stats.get('seq_gaps', 0)} watchdog_stop_ms={stop_s * 1e3:.1f}", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    return run(args)


if __name__ == "__main__":
    raise SystemExit(main())
