"""Faults for the soak (bench/soak_bench.py --chaos): which, when, and what they are judged by.

The graph runs with respawn for every node (run_graph's ``--respawn all --respawn-delay 1``: Graph(respawn=...,
respawn_delay=RESPAWN_DELAY), its supervise() called every 0.2 s); the recorder is started again here after
the same delay with the same command, as a user's respawn does, and records beside the bag it was killed
writing (bag, bag.1, bag.2, ...). At seeded random moments, at least SPACING apart (less in a run too short
for it), one of each kind per 10 minutes (at least one each; a fault waits while the recorder starts again,
or for half the spacing after the last one):

  kill_control   kill -9 of the process of model_node and controller_node (a rig computer runs them together)
  kill_rig       kill -9 of sim_node (the rig and its estimator)
  kill_recorder  kill -9 of the recorder
  cpu_hog        HOG_PROCESSES processes spinning at normal priority for HOG_SECONDS (the graph's run at
                 SCHED_FIFO 40 and the recorder at 30 unless --recorder-priority 0; this process does not)
  dds_cut        the link between the rig computer's network namespace (the graph, its recorder, this
                 process) and a workstation's (a second recorder, of /rig/samples and /torque_estimate)
                 down for CUT seconds; the two hosts are two network namespaces joined by a veth pair
                 (worm_model.ros.two_hosts, as tests/test_two_hosts_dds.py has them, on SUBNET), DDS discovery
                 on the subnet. It needs root and iproute2: without them the run says why and has no cut (and
                 the graph runs on localhost as in the soak)

Counted over the run, from the bags (the rig's own stamps) and what this process saw, and printed (each
fault's outcome on stderr):

  chaos_faults_<kind>: <n>
  chaos_watchdog_stop_max: <x> ms        the longest from a kill of controller_node's process to the first rig
                                         sample its watchdog stopped (STATUS_WATCHDOG_STOP, that sample's stamp)
  chaos_watchdog_late: <n>               such kills after which the rig drove on past 105 ms (command_timeout
                                         0.1 s after a last command <= 20 ms before the kill, and the sample
                                         period) or was not seen to stop
  chaos_watchdog_unmeasured: <n>         such kills while no recorder was recording (its own respawn)
  chaos_respawns: <n>                    processes started again (the graph's, and the recorder)
  chaos_resume_max_<process>: <x> s      the longest from a respawn of that process (the time supervise()
                                         or this script started it again) to the first of each of its outputs,
                                         by their stamps (controller_node: /rig/speed_command, model_node:
                                         /gearbox/forces; sim_node: /rig/samples, /torque_estimate; the
                                         recorder: the first message in its new bag, by its receive time)
  chaos_resume_late: <n>                 respawns after which an output took more than 2 s
  chaos_resume_unmeasured: <n>           respawns of the graph's while no recorder was recording
  chaos_diagnostics_back_max: <x> s      the longest from a respawn to its nodes' first /diagnostics (their
                                         1 Hz timer's first tick: a second after the node is up)
  chaos_recorder_bags: <n>               bags the recorder wrote (one more per kill)
  chaos_recorder_damaged_bags: <n>       bags that do not read back whole (a record cut short)
  chaos_recorder_lost_samples: <n>       rig samples missing inside any bag (seq gaps of /rig/samples other
                                         than the rig's own restarts)
  chaos_recorder_truth_gaps: <n>         the same for /sim/truth_samples (printed, not judged: best effort)
  chaos_recorder_unflushed_max: <x> s    the longest from a killed recorder's last recorded message to its kill
                                         (it flushes every second: what it received since is lost with it)
  chaos_recorder_received_not_written: <n>  messages the recorder stopped at the end says it received and its
                                         bag does not hold
  chaos_recorder_said_lost: <n>          what that recorder says DDS never delivered (a killed publisher's last
                                         messages count there)
  chaos_silent_max: <x> s                the longest a node went without /diagnostics (1 Hz), its own process's
                                         kills excepted
  chaos_stuck: <n>                       nodes silent for more than 3 s other than that, and processes not
                                         running at the end
  chaos_cut_station_resume_max: <x> s    from the link's return to the workstation's first sample after it
  chaos_cut_rig_stops: <n>               rig samples its watchdog stopped during a cut (the control path lives
                                         on the rig computer: 0)
  chaos_cut_station_inside: <n>          /rig/samples batches the workstation recorded stamped inside a cut (a
                                         cut that cuts: 0)

and verdict lines watchdog, respawn, recorder, stuck, cut (SKIPPED, with the reason, without a cut).
"""
from __future__ import annotations

import bisect
import math
import os
import random
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

from worm_model.ros import two_hosts

RESPAWN_DELAY = 1.0  # [s]
SUPERVISE_PERIOD = 0.2  # [s]
SPACING = 40.0  # [s] between two faults at least (less in a short run: fault_spacing)
HOG_PROCESSES = 2
HOG_SECONDS = 20.0  # [s] (at most half the spacing of the faults)
CUT = 3.0  # [s] the link down (well inside Fast DDS's 20 s participant lease)
KINDS = ("kill_control", "kill_rig", "kill_recorder", "cpu_hog", "dds_cut")
WATCHDOG_LIMIT = 0.105  # [s] from a controller's kill to the rig's stop
RESUME_LIMIT = 2.0  # [s] from a respawn to its node and outputs back
SILENT_LIMIT = 3.0  # [s] of /diagnostics silence (1 Hz) that counts a node stuck
CONTROL, RIG, RECORDER = "model_node+controller_node", "sim_node", "recorder"
OUTPUTS = {CONTROL: ("/rig/speed_command", "/gearbox/forces"), RIG: ("/rig/samples", "/torque_estimate")}
NODES = {CONTROL: ("model_node", "controller_node"), RIG: ("sim_node",)}
SUBNET = "10.78.0"  # the two hosts' network (the two-hosts test uses another)
HOSTS_TAG = "s"  # begins the names of their namespaces and links


def info(text: str) -> None:
    print(f"[soak chaos] {text}", file=sys.stderr, flush=True)


def fault_plan(seed: int, duration: float, kinds: tuple[str, ...] = KINDS) -> list[tuple[float, str]]:
    """(time [s after the first window's start], kind) of every fault, sorted: one of each kind per 10 minutes
    (at least one), at seeded random moments at least :func:`fault_spacing` apart, none in the first or last
    spacing of the run."""
    rng = random.Random(f"chaos {seed}")
    per_kind = max(1, round(duration / 600.0))
    faults = [kind for kind in kinds for _ in range(per_kind)]
    rng.shuffle(faults)
    spacing = fault_spacing(duration, len(faults))
    slack = duration - spacing * (len(faults) + 1)  # spread at random over the gaps
    offsets = sorted(rng.uniform(0, slack) for _ in faults)
    return [(round(spacing * (k + 1) + offset, 3), kind) for k, (offset, kind) in enumerate(zip(offsets, faults))]


def fault_spacing(duration: float, faults: int) -> float:
    """[s] between two faults at least: SPACING, or less in a run too short for it."""
    return min(SPACING, duration / (faults + 1))


def hog_seconds(spacing: float) -> float:
    """[s] of a CPU hog burst: HOG_SECONDS, at most half the faults' spacing (over before the next)."""
    return min(HOG_SECONDS, 0.5 * spacing)


# --- during the run ---------------------------------------------------------------------------------------------

class Chaos:
    """The faults of one run: soak_bench's loop calls :meth:`tick` between its spins."""

    def __init__(self, seed: int, duration: float, work: Path,
                 start_recorder: Callable[[Path, Path], subprocess.Popen], kinds: tuple[str, ...] = KINDS) -> None:
        self.work, self.duration, self.start_recorder = work, duration, start_recorder
        self.hosts: two_hosts.TwoHosts | None = None
        self.cut_skipped = two_hosts.problem() if "dds_cut" in kinds else "not asked for (--faults)"
        if not self.cut_skipped:
            hosts = two_hosts.TwoHosts(SUBNET, HOSTS_TAG)
            try:
                hosts.create()
                hosts.enter_rig()
                self.hosts = hosts
            except (OSError, subprocess.SubprocessError) as err:
                hosts.remove()
                self.cut_skipped = f"network namespaces could not be made here: {err}"
        if self.hosts is not None:
            # discovery on the subnet; Fast DDS's default transports, as on a real rig computer: shared memory
            # between the rig computer's processes, UDP to the workstation (the namespaces share /dev/shm, but
            # Kilted's Fast DDS does not pair them over it: cut_station_inside counts what crossed a cut)
            os.environ.update(ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET")
            info(f"two hosts: this process, the graph and its recorder in {self.hosts.rig}, the workstation's "
                 f"recorder in {self.hosts.station}; DDS discovery on {SUBNET}.0/24")
        else:
            info(f"no DDS cut: {self.cut_skipped}")
        kinds = kinds if self.hosts is not None else tuple(k for k in kinds if k != "dds_cut")
        self.plan = fault_plan(seed, duration, kinds)
        self.hog = hog_seconds(fault_spacing(duration, len(self.plan)))
        self.next = 0
        self.hogs: list[subprocess.Popen] = []
        self.hog_end = math.inf
        self.cut_end = math.inf
        self.recorder_due = math.inf
        self.next_supervise = 0.0
        self.station: subprocess.Popen | None = None
        self.gone: set[str] = set()  # graph processes that exited for good
        self.recorder_starts = 1  # the recorder's, so far (each logs "Recording /rig/samples" once recording)
        self.last_fault = -math.inf
        self.min_gap = 0.5 * fault_spacing(duration, len(self.plan))

    def graph_options(self, graph_file: Path) -> dict:
        """Graph's options for respawn: every node of ``graph_file``, after RESPAWN_DELAY."""
        from torque_estimator.graph.runner import graph_nodes

        return {"respawn": graph_nodes(graph_file), "respawn_delay": RESPAWN_DELAY}

    def start_station(self) -> None:
        """The workstation's recorder (two hosts only), started once the graph runs."""
        if self.hosts is None:
            return
        from worm_model.ros.ament import find_executable

        self.station = subprocess.Popen(
            ["ip", "netns", "exec", self.hosts.station, str(find_executable("recorder")), "--ros-args",
             "-p", f"output:={self.work / 'station_bag'}", "-p", "topics:=[/rig/samples,/torque_estimate]"],
            stdout=open(self.work / "station_recorder.log", "wb"), stderr=subprocess.STDOUT)

    def due(self) -> tuple[float, ...]:
        """[s] of the next thing to do (a fault, a hog's or a cut's end, a recorder's respawn, supervise)."""
        fault = self.plan[self.next][0] if self.next < len(self.plan) else math.inf
        return fault, self.hog_end, self.cut_end, self.recorder_due, self.next_supervise

    @staticmethod
    def event(record: dict, now: float, kind: str, **more) -> None:
        record["events"].append({"t": now, "ns": time.time_ns(), "kind": kind, **more})

    def ready(self, now: float, recorder: subprocess.Popen | None) -> bool:
        """Whether the next fault may come: half the faults' spacing after the last one, and the recorder
        recording /rig/samples (a fault while it starts again would go unrecorded: its start took 2-18 s on a
        busy 2-core machine), else the fault waits."""
        if now - self.last_fault < self.min_gap or recorder is None or recorder.poll() is not None:
            return False
        log = self.work / "recorder.log"
        return log.exists() and log.read_text(errors="replace").count("Recording /rig/samples ") >= self.recorder_starts

    def tick(self, now: float, graph, recorder: subprocess.Popen | None, record: dict) -> subprocess.Popen | None:
        """Supervise the graph, end a hog or a cut, respawn the recorder, inject the fault that is due;
        returns the recorder running now."""
        if now >= self.next_supervise:
            for key, code in graph.failed().items():  # for good (it refused its input): counted stuck at the end
                if key not in self.gone:
                    self.gone.add(key)
                    self.event(record, now, "exited", key=key, code=code)
                    info(f"{now:.1f} s: {key} exited with {code} and is not respawned; logs in {self.work}")
            for key in graph.supervise():
                self.event(record, now, "respawn", key=key, pid=graph.processes[key].pid)
                info(f"{now:.1f} s: {key} respawned")
            self.next_supervise = now + SUPERVISE_PERIOD
        if now >= self.hog_end:
            for hog in self.hogs:
                hog.kill()
                hog.wait()
            self.hogs, self.hog_end = [], math.inf
            self.event(record, now, "cpu_hog_end")
        if now >= self.cut_end:
            self.event(record, now, "dds_cut_end")  # the time taken before the link is back: from inside
            self.hosts.connect()
            self.cut_end = math.inf
        if recorder is not None and recorder.poll() is not None and now >= self.recorder_due:
            # the same command: the recorder leaves the bag it was killed writing as it is and records
            # beside it, into the first free bag.1, bag.2, ... (worm_rig_driver.recording.bag_folder)
            name = f"{record['bags'][0]}.{len(record['bags'])}"
            recorder = self.start_recorder(self.work / record["bags"][0], self.work / "recorder.log")
            record["bags"].append(name)
            self.recorder_starts += 1
            self.recorder_due = math.inf
            self.event(record, now, "respawn", key=RECORDER, pid=recorder.pid, bag=name)
            info(f"{now:.1f} s: recorder respawned into {name}")
        if self.next < len(self.plan) and now >= self.plan[self.next][0] and self.ready(now, recorder):
            kind = self.plan[self.next][1]
            self.last_fault = now
            self.next += 1
            if kind in ("kill_control", "kill_rig"):
                key = CONTROL if kind == "kill_control" else RIG
                proc = graph.processes[key]
                self.event(record, now, kind, key=key, pid=proc.pid)  # the time taken just before the kill
                proc.send_signal(signal.SIGKILL)
            elif kind == "kill_recorder" and recorder is not None:
                self.event(record, now, kind, key=RECORDER, pid=recorder.pid, bag=record["bags"][-1])
                recorder.send_signal(signal.SIGKILL)
                recorder.wait()
                self.recorder_due = now + RESPAWN_DELAY
            elif kind == "cpu_hog":
                self.hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"],
                                              env={**os.environ, "_ROS_WHEELS_BOOTSTRAP_COMPLETE": "1"})
                             for _ in range(HOG_PROCESSES)]
                self.hog_end = now + self.hog
                self.event(record, now, kind, processes=HOG_PROCESSES, seconds=self.hog)
            elif kind == "dds_cut":
                self.hosts.cut()
                self.event(record, now, kind, seconds=CUT)  # the time taken after the link is down: from inside
                self.cut_end = now + CUT
            info(f"{now:.1f} s: {kind}")
        return recorder

    def finish(self, now: float, graph, recorder: subprocess.Popen | None, record: dict) -> None:
        """At the run's end, before anything is stopped: what runs, and what has stopped for good."""
        record["alive_at_end"] = {key: proc.poll() is None for key, proc in graph.processes.items()}
        record["alive_at_end"][RECORDER] = recorder is not None and recorder.poll() is None
        record["cut_skipped"] = self.cut_skipped

    def close(self) -> None:
        """Stop the hogs, the workstation's recorder, and remove the namespaces (always)."""
        for hog in self.hogs:
            hog.kill()
            hog.wait()
        if self.station is not None and self.station.poll() is None:
            self.station.send_signal(signal.SIGINT)
            try:
                self.station.wait(60)
            except subprocess.TimeoutExpired:
                self.station.kill()
        if self.hosts is not None:
            self.hosts.remove()


# --- the figures ------------------------------------------------------------------------------------------------

def first_after(stamps: list[int], ns: int) -> int | None:
    """The first of sorted ``stamps`` at or after ``ns`` (None: none)."""
    i = bisect.bisect_left(stamps, ns)
    return stamps[i] if i < len(stamps) else None


def last_before(stamps: list[int], ns: int) -> int | None:
    """The last of sorted ``stamps`` before ``ns`` (None: none)."""
    i = bisect.bisect_left(stamps, ns)
    return stamps[i - 1] if i else None


def stamp_ns(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def read_streams(work: Path, record: dict) -> dict:
    """From every bag: sorted stamps [ns] of each output, the stamps of the rig samples the watchdog stopped,
    and per bag its first and last receive time [ns], its message counts, what reading it found damaged,
    and the seqs missing inside it per sample stream (a rig's restart, its seq going back, is no loss)."""
    from worm_model.bags.reader import BagReader
    from worm_msgs.msg import RigSample

    stamps: dict[str, list[int]] = {t: [] for t in ("/rig/samples", "/torque_estimate", "/rig/speed_command",
                                                    "/gearbox/forces")}
    stopped: list[int] = []
    bags: dict[str, dict] = {}
    for name in record["bags"]:
        path = work / name
        if not path.exists():
            continue
        lost = {"/rig/samples": 0, "/sim/truth_samples": 0}
        last: dict[str, int] = {}
        first_rx = last_rx = None
        with BagReader(path, allow_truncated=True) as reader:
            counts = reader.count_messages()
            for message in reader.messages([t for t in (*stamps, *lost) if t in reader.topics]):
                m = message.decoded
                first_rx = message.timestamp if first_rx is None else first_rx
                last_rx = message.timestamp
                ns = stamp_ns(m.header)
                if message.topic in stamps:
                    stamps[message.topic].append(ns)
                if message.topic in lost:
                    first, n = int(m.first_seq), len(m.tau_load)
                    before = last.get(message.topic)
                    if before is not None and first > before + 1:
                        lost[message.topic] += first - before - 1
                    last[message.topic] = first + n - 1
                if message.topic == "/rig/samples":
                    period = int(round(m.sample_period * 1e9))
                    stopped += [ns + k * period for k, bits in enumerate(m.status)
                                if bits & RigSample.STATUS_WATCHDOG_STOP]
            damage = list(reader.damage)
        bags[name] = {"lost": lost, "first_rx": first_rx, "last_rx": last_rx, "counts": counts, "damage": damage}
    for values in stamps.values():
        values.sort()
    stopped.sort()
    station: list[int] = []
    if (work / "station_bag").exists():
        with BagReader(work / "station_bag", allow_truncated=True) as reader:
            if "/rig/samples" in reader.topics:
                station = sorted(stamp_ns(m.decoded.header) for m in reader.messages(["/rig/samples"]))
    return {"stamps": stamps, "stopped": stopped, "bags": bags, "station": station}


def received_not_written(log: str, bags: dict[str, dict]) -> tuple[str, int] | None:
    """(bag, messages) the recorder stopped at the end said it received and its bag does not hold, read from
    its closing lines ("Closed bag <path>: ...", then "<topic>: <n> received from ..."); None if it said
    nothing (killed)."""
    closed = log.rfind("Closed bag ")
    if closed < 0:
        return None
    path = log[closed + len("Closed bag "):].split(":", 1)[0]
    bag = bags.get(Path(path).name)
    if bag is None:
        return None
    received = {m[1]: int(m[2]) for m in re.finditer(r"\]: (/\S+): (\d+) received from", log[closed:])}
    return Path(path).name, sum(max(0, n - bag["counts"].get(topic, 0)) for topic, n in received.items())


def chaos_figures(record: dict, work: Path, recorder_said_lost: float) -> tuple[dict[str, tuple[float, str]],
                                                                                list[str]]:
    """The chaos run's figures {metric: (value, unit)} and its verdict lines; each fault's outcome on stderr."""
    events = record["events"]
    streams = read_streams(work, record)
    stamps, stopped, bags = streams["stamps"], streams["stopped"], streams["bags"]
    samples = stamps["/rig/samples"]
    figures: dict[str, tuple[float, str]] = {}
    for kind in KINDS:
        figures[f"chaos_faults_{kind}"] = (float(sum(e["kind"] == kind for e in events)), "")

    def recorded(ns: int, seconds: float) -> bool:
        """Whether a bag was recording over [ns, ns + seconds] (its first to last message)."""
        return any(b["first_rx"] is not None and b["first_rx"] <= ns and b["last_rx"] >= ns + seconds * 1e9
                   for b in bags.values())

    # the watchdog: a kill of controller_node's process -> the first rig sample stopped, on the rig's stamps
    delays, unmeasured = [], 0
    for e in (e for e in events if e["kind"] == "kill_control"):
        before = last_before(samples, e["ns"])
        if before is None or e["ns"] - before > 0.1e9 or not recorded(e["ns"], 1.0):
            unmeasured += 1  # no recorder at the time (its own respawn)
            info(f"{e['t']:.1f} s kill_control: the rig's samples were not being recorded; not measured")
            continue
        stop = first_after(stopped, e["ns"])
        delays.append((stop - e["ns"]) / 1e9 if stop is not None and stop - e["ns"] < 5e9 else math.inf)
        info(f"{e['t']:.1f} s kill_control: the rig stopped driving {1e3 * delays[-1]:.0f} ms after the kill")
    late_watchdog = sum(d > WATCHDOG_LIMIT for d in delays)
    figures["chaos_watchdog_stop_max"] = (1e3 * max(delays) if delays else math.nan, "ms")
    figures["chaos_watchdog_late"] = (float(late_watchdog), "")
    figures["chaos_watchdog_unmeasured"] = (float(unmeasured), "")

    # respawns: the nodes' /diagnostics, the outputs, the recorder's new bag
    heard = record["diagnostics"]
    respawns = [e for e in events if e["kind"] == "respawn"]
    longest: dict[str, float] = {}
    late_resume = 0
    diagnostics_back: list[float] = []
    unmeasured_respawns = 0
    for e in respawns:
        key, waits = e["key"], {}
        if key == RECORDER:
            first = bags.get(e.get("bag", ""), {}).get("first_rx")
            waits["its bag"] = (first - e["ns"]) / 1e9 if first is not None else math.inf
        elif recorded(e["ns"], RESUME_LIMIT + 1.0):
            for topic in OUTPUTS.get(key, ()):
                first = first_after(stamps[topic], e["ns"])
                waits[topic] = (first - e["ns"]) / 1e9 if first is not None else math.inf
        else:
            unmeasured_respawns += 1
            info(f"{e['t']:.1f} s respawn of {key}: its outputs were not being recorded; not measured")
        for node in NODES.get(key, ()):  # its first report: the 1 Hz timer's first tick after its start
            after = [t for t in heard.get(node, []) if t >= e["t"]]
            diagnostics_back.append(min(after) - e["t"] if after else math.inf)
        if not waits:
            continue
        worst = max(waits.values())
        longest[key] = max(longest.get(key, 0.0), worst)
        late_resume += worst > RESUME_LIMIT
        info(f"{e['t']:.1f} s respawn of {key}: " + ", ".join(
            f"{what} after {w:.2f} s" if math.isfinite(w) else f"{what} not back before the run ended"
            for what, w in waits.items()))
    figures["chaos_respawns"] = (float(len(respawns)), "")
    for key in (CONTROL, RIG, RECORDER):
        figures[f"chaos_resume_max_{key.replace('+', '__')}"] = (longest.get(key, math.nan), "s")
    figures["chaos_resume_late"] = (float(late_resume), "")
    figures["chaos_resume_unmeasured"] = (float(unmeasured_respawns), "")
    figures["chaos_diagnostics_back_max"] = (max(diagnostics_back, default=math.nan), "s")
    kills = [e for e in events if e["kind"].startswith("kill_")]
    unanswered = sum(not any(r["key"] == k["key"] and r["t"] > k["t"] for r in respawns) for k in kills)

    # the recorder: every bag read back whole, no sample missing inside one, what a kill took with it
    gaps = sum(b["lost"]["/rig/samples"] for b in bags.values())
    truth_gaps = sum(b["lost"]["/sim/truth_samples"] for b in bags.values())
    damaged = sum(bool(b["damage"]) for b in bags.values())
    unflushed = [(e["ns"] - bags[e["bag"]]["last_rx"]) / 1e9 for e in events
                 if e["kind"] == "kill_recorder" and bags.get(e["bag"], {}).get("last_rx") is not None]
    log_path = work / "recorder.log"
    log = log_path.read_text(errors="replace") if log_path.exists() else record.get("recorder_log", "")
    unwritten = received_not_written(log, bags)
    figures["chaos_recorder_bags"] = (float(len(bags)), "")
    figures["chaos_recorder_damaged_bags"] = (float(damaged), "")
    figures["chaos_recorder_lost_samples"] = (float(gaps), "")
    figures["chaos_recorder_truth_gaps"] = (float(truth_gaps), "")
    figures["chaos_recorder_unflushed_max"] = (max(unflushed) if unflushed else math.nan, "s")
    figures["chaos_recorder_received_not_written"] = (float(unwritten[1]) if unwritten else math.nan, "")
    figures["chaos_recorder_said_lost"] = (recorder_said_lost, "")

    # nobody stuck: /diagnostics at 1 Hz to the end, but around its own process's kill
    end = max((r["t"] for r in record["resources"]), default=0.0)
    silent_max, stuck = 0.0, 0
    for key, nodes in NODES.items():
        own = [k["t"] for k in kills if k["key"] == key]
        for node in nodes:
            marks = [0.0, *sorted(heard.get(node, [])), end]
            spans = [b - a for a, b in zip(marks, marks[1:]) if not any(a <= kill <= b for kill in own)]
            silent = max(spans, default=math.inf)
            silent_max = max(silent_max, silent)
            stuck += silent > SILENT_LIMIT
            if silent > SILENT_LIMIT:
                info(f"{node} was silent on /diagnostics for {silent:.1f} s (not its process's kill)")
    not_running = [key for key, alive in record.get("alive_at_end", {}).items() if not alive]
    stuck += len(not_running)
    figures["chaos_silent_max"] = (silent_max, "s")
    figures["chaos_stuck"] = (float(stuck), "")

    recorder_ok = bags and not damaged and gaps == 0 and unwritten is not None and unwritten[1] == 0
    verdicts = [
        f"verdict watchdog: {'PASS' if delays and not late_watchdog else 'FAIL'} (after each of {len(delays)} "
        f"kills of controller_node's process the rig stopped driving within {1e3 * WATCHDOG_LIMIT:.0f} ms of the "
        f"kill: longest {figures['chaos_watchdog_stop_max'][0]:.0f} ms, {late_watchdog} late; {unmeasured} "
        "more while no recorder ran)",
        f"verdict respawn: {'PASS' if respawns and not late_resume and not unanswered else 'FAIL'} "
        f"({len(respawns)} respawns for {len(kills)} kills, {unanswered} never respawned; its outputs back within "
        f"{RESUME_LIMIT:g} s: longest " + ", ".join(f"{k} {v:.2f} s" for k, v in longest.items())
        + f"; {late_resume} late, {unmeasured_respawns} while no recorder ran)",
        f"verdict recorder: {'PASS' if recorder_ok else 'FAIL'} ({len(bags)} bags read back, {damaged} damaged, "
        f"{gaps:g} rig samples missing inside them; the recorder stopped at the end wrote all it received but "
        f"{unwritten[1] if unwritten else 'nan'}; a killed one lost its last "
        f"{figures['chaos_recorder_unflushed_max'][0]:.2f} s at most, unflushed)",
        f"verdict stuck: {'PASS' if not stuck else 'FAIL'} (every node on /diagnostics to the end, silent "
        f"{silent_max:.2f} s at most outside its own process's kills; {stuck} stuck or not running at the end"
        + (f": {', '.join(not_running)}" if not_running else "") + ")",
    ]

    cuts = [e for e in events if e["kind"] == "dds_cut"]
    ends = [e for e in events if e["kind"] == "dds_cut_end"]
    if cuts and ends:
        resumes, rig_stops, inside = [], 0, 0
        for cut, back in zip(cuts, ends):
            first = first_after(streams["station"], back["ns"])
            resumes.append((first - back["ns"]) / 1e9 if first is not None else math.inf)
            rig_stops += sum(cut["ns"] <= s <= back["ns"] for s in stopped)
            # batches stamped well inside the cut (0.1 s in from either end: the times are taken from inside)
            inside += sum(cut["ns"] + 0.1e9 < s < back["ns"] - 0.1e9 for s in streams["station"])
            info(f"{cut['t']:.1f} s dds_cut: the workstation's samples back {resumes[-1]:.2f} s after the link")
        figures["chaos_cut_station_resume_max"] = (max(resumes), "s")
        figures["chaos_cut_rig_stops"] = (float(rig_stops), "")
        figures["chaos_cut_station_inside"] = (float(inside), "")
        ok = not rig_stops and not inside and all(r <= RESUME_LIMIT for r in resumes)
        verdicts.append(f"verdict cut: {'PASS' if ok else 'FAIL'} ({len(cuts)} cuts of {CUT:g} s: the rig drove "
                        f"on ({rig_stops} samples stopped by its watchdog during them), the workstation had "
                        f"{inside} batches stamped inside them and its samples back within {max(resumes):.2f} s of "
                        "the link)")
    else:
        verdicts.append(f"verdict cut: SKIPPED ({record.get('cut_skipped') or 'no cut in this run'})")
    return figures, verdicts
