"""The soak benchmark (bench/soak_bench.py, `make soak`, and its faults, bench/soak_chaos.py): its command
profile and fault plan, its reading of the recorded stream, and short runs end to end.

The benchmark prints and never asserts; these tests check that it measures what it says: the profile and the
faults a seed makes, the seq and command accounting it does on the rig's batches (against worm_model's own
command_latencies), the recorder's closing lines read against its bag, and that a short run (and one with
faults) prints every figure and one verdict per target. No timing figure is asserted here.
"""
from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest


from worm_model.rig_data.samples import command_latencies
from worm_model.ros.testing import local_domain

REPO = Path(__file__).resolve().parents[1]
BENCH = REPO / "bench"
sys.path.insert(0, str(BENCH))
try:
    import soak_bench  # noqa: E402 - bench/ is a folder of scripts
    import soak_chaos  # noqa: E402
finally:
    sys.path.remove(str(BENCH))

FIGURE = re.compile(r"^(soak_\w+): (\S+)(?: (.+))?$")
VERDICTS = ("rss_growth", "latency_p99", "lost_samples", "estimate_error")


def test_the_profile_is_the_seeds_and_opens_every_window_with_the_reference_hold() -> None:
    steps = soak_bench.command_profile(7, 3600.0, 600.0)
    assert steps == soak_bench.command_profile(7, 3600.0, 600.0)
    assert steps != soak_bench.command_profile(8, 3600.0, 600.0)
    references = [s for s in steps if s.kind == "reference"]
    assert [s.at for s in references] == [600.0 * k for k in range(6)]
    assert all((s.speed, s.load) == (soak_bench.REF_SPEED, soak_bench.REF_LOAD) for s in references)
    assert [s.at for s in steps] == sorted(s.at for s in steps) and steps[-1].at < 3600.0
    kinds = {s.kind for s in steps}
    assert kinds == {"reference", "setpoint", "load", "reversal", "idle"}, kinds
    for before, step in zip(steps, steps[1:]):
        # a load opposes the rotation (or there is none); the worm stands without load when idle
        assert step.load == 0.0 or math.copysign(1, step.load) == math.copysign(1, step.speed), step
        if step.kind == "idle":
            assert (step.speed, step.load) == (0.0, 0.0)
        if step.kind == "reversal":
            assert (step.speed, step.load) == (-before.speed, -before.load)
        if step.kind != "reference":
            assert step.at - before.at >= soak_bench.HOLD[0] or before.kind == "reference"


def batches(seqs_and_commands: list[tuple[int, int]], size: int = 10) -> list[SimpleNamespace]:
    """RigSamples-like batches of (seq, command_seq) samples, consecutive seqs within a batch."""
    out, run = [], []
    for seq, command in seqs_and_commands:
        if run and (seq != run[-1][0] + 1 or len(run) == size):
            out.append(SimpleNamespace(first_seq=run[0][0], command_seq=[c for _, c in run]))
            run = []
        run.append((seq, command))
    out.append(SimpleNamespace(first_seq=run[0][0], command_seq=[c for _, c in run]))
    return out


def test_the_stream_accounting_agrees_with_command_latencies_and_counts_gaps_not_restarts() -> None:
    # (first seq driven, source seq) of each command: in force 1, 2, 1 and 3 periods after its sample
    changes = [(0, 0), (5, 3), (22, 19), (46, 44), (70, 66)]
    stream = [(seq, next(c for k, c in reversed(changes) if k <= seq)) for seq in range(90) if not 30 <= seq < 35]
    before_restart = len(stream)
    stream += [(seq, 0 if seq < 3 else 2) for seq in range(10)]  # the rig restarted: seqs from 0 again
    window = soak_bench.Window()
    for batch in batches(stream):
        soak_bench._add_batch(window, batch)
    assert window.lost == 5 and window.restarts == 1 and window.samples == len(stream)
    samples = [SimpleNamespace(seq=seq, command_seq=c) for seq, c in stream[:before_restart]]
    assert command_latencies(samples) == [1, 2, 1, 3]
    assert soak_bench.latencies_ms(window) == [1.0, 2.0, 1.0, 3.0, 0.0]


def test_the_recorders_own_word_on_what_it_lost() -> None:
    assert soak_bench.recorder_lost("... recorder: lost nothing (12 topics)") == 0.0
    assert soak_bench.recorder_lost("recorder: LOST 3 messages\nrecorder: lost nothing") == 3.0
    assert math.isnan(soak_bench.recorder_lost("killed before it said anything"))


def figures_and_verdicts(stdout: str) -> tuple[dict[str, float], dict[str, str]]:
    figures = {m[1]: float(m[2]) for line in stdout.splitlines() if (m := FIGURE.match(line))}
    verdicts = {m[1]: m[2] for m in re.finditer(r"^verdict (\w+): (PASS|FAIL) \(.+\)$", stdout, re.M)}
    return figures, verdicts


def test_the_fault_plan_is_the_seeds_one_of_each_kind_per_ten_minutes_spaced() -> None:
    plan = soak_chaos.fault_plan(3, 3600.0)
    assert plan == soak_chaos.fault_plan(3, 3600.0) and plan != soak_chaos.fault_plan(4, 3600.0)
    assert sorted(kind for _, kind in plan) == sorted(soak_chaos.KINDS * 6)
    times = [t for t, _ in plan]
    assert times == sorted(times) and soak_chaos.SPACING <= times[0] and times[-1] <= 3600.0 - soak_chaos.SPACING
    assert min(b - a for a, b in zip(times, times[1:])) >= soak_chaos.SPACING
    short = soak_chaos.fault_plan(3, 120.0, ("kill_rig", "cpu_hog"))
    assert sorted(kind for _, kind in short) == ["cpu_hog", "kill_rig"]
    spacing = soak_chaos.fault_spacing(120.0, 2)
    assert spacing == 40.0 and short[0][0] >= spacing and short[1][0] - short[0][0] >= spacing
    assert soak_chaos.hog_seconds(spacing) <= spacing / 2


def test_what_the_stopped_recorder_received_is_read_against_its_bag() -> None:
    log = ("[INFO] [1.0] [recorder]: Closed bag /w/bag.2: 30 messages (/a: 20, /b: 10)\n"
           "[WARN] [1.0] [recorder]: /a: 20 received from 1 publisher(s), 0 missing in their DDS sequence numbers\n"
           "[WARN] [1.0] [recorder]: /b: 12 received from 2 publisher(s), 1 missing in their DDS sequence numbers\n")
    assert soak_chaos.received_not_written(log, {"bag.2": {"counts": {"/a": 20, "/b": 10}}}) == ("bag.2", 2)
    assert soak_chaos.received_not_written(log, {"bag.2": {"counts": {"/a": 20, "/b": 12}}}) == ("bag.2", 0)
    assert soak_chaos.received_not_written("killed, it said nothing", {}) is None


@pytest.mark.slow
def test_a_short_soak_prints_every_figure_and_a_verdict_per_target(tmp_path: Path) -> None:
    """One minute in 20 s windows, the graph and the recorder as processes over DDS."""
    env = {**os.environ, **local_domain()}
    done = subprocess.run([sys.executable, str(BENCH / "soak_bench.py"), "--minutes", "1", "--window", "20",
                           "--work", str(tmp_path / "run")], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    figures, verdicts = figures_and_verdicts(done.stdout)
    processes = ("sim_node", "model_node__controller_node", "recorder")
    for k in (1, 2, 3):
        expected = [f"soak_{name}_w{k}" for name in ("latency_p50", "latency_p99", "lost_samples",
                                                       "sim_skipped_samples", "bag_growth", "estimate_error",
                                                       "estimate_spread", "estimate_error_all", "host_cpu")]
        expected += [f"soak_{what}_{p}_w{k}" for what in ("rss", "cpu") for p in processes]
        assert not [name for name in expected if name not in figures], done.stdout
    expected = [f"soak_rss_growth_{p}" for p in processes] + [
        "soak_latency_p99_rise", "soak_lost_samples", "soak_estimate_error_change", "soak_recorder_lost_messages",
        *(f"soak_diagnostics_gap_{n}" for n in ("sim_node", "model_node", "controller_node"))]
    assert not [name for name in expected if name not in figures], done.stdout
    assert not [name for name, value in figures.items() if not math.isfinite(value)], done.stdout
    assert sorted(verdicts) == sorted(VERDICTS), done.stdout
    assert done.stdout.count("| 0:") == 3  # a table row per window
    # the run's record is enough to print the same figures again
    again = subprocess.run([sys.executable, str(BENCH / "soak_bench.py"), "--analyse", str(tmp_path / "run")],
                           env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr[-3000:]
    assert figures_and_verdicts(again.stdout) == (figures, verdicts)


def test_bad_options_are_one_line_and_exit_2(tmp_path: Path) -> None:
    for args, named in ((["--minutes", "0"], "--minutes"), (["--window", "5"], "--window"),
                        (["--recorder-priority", "100"], "--recorder-priority"),
                        (["--work", str(tmp_path)], "--work"), (["--analyse", str(tmp_path)], "--analyse")):
        done = subprocess.run([sys.executable, str(BENCH / "soak_bench.py"), *args], capture_output=True,
                              text=True, timeout=60)
        assert done.returncode == 2 and named in done.stderr and "Traceback" not in done.stderr, (args, done.stderr)


@pytest.mark.slow
def test_a_short_chaos_run_kills_and_respawns_and_prints_a_verdict_per_target(tmp_path: Path) -> None:
    """Two minutes in 40 s windows with one fault of each kind: every graph process and the recorder
    killed and started again, a CPU hog, and the link cut where this machine makes network namespaces."""
    env = {**os.environ, **local_domain()}
    done = subprocess.run([sys.executable, str(BENCH / "soak_bench.py"), "--minutes", "2", "--window", "40",
                           "--chaos", "--seed", "2", "--work", str(tmp_path / "run")],
                          env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    story = chaos_story(done, tmp_path / "run")
    figures = {m[1]: float(m[2]) for line in done.stdout.splitlines()
               if (m := re.match(r"^(chaos_\w+): (\S+)", line))}
    verdicts = dict(re.findall(r"^verdict (\w+): (PASS|FAIL|SKIPPED) \(.+\)$", done.stdout, re.M))
    assert sorted(verdicts) == sorted((*VERDICTS, "watchdog", "respawn", "recorder", "stuck", "cut")), story
    cut = verdicts["cut"] != "SKIPPED"
    for kind in soak_chaos.KINDS:
        assert figures[f"chaos_faults_{kind}"] == (0 if kind == "dds_cut" and not cut else 1), story
    # each kill answered by a respawn, each recorder kill by a new bag beside the old one
    assert figures["chaos_respawns"] >= 3 and figures["chaos_recorder_bags"] == 2, story
    assert (tmp_path / "run" / "bag.1").is_dir(), sorted(p.name for p in (tmp_path / "run").iterdir())
    for name in ("chaos_watchdog_stop_max", "chaos_recorder_lost_samples", "chaos_recorder_received_not_written",
                 "chaos_silent_max", "chaos_stuck",
                 *(("chaos_cut_station_resume_max", "chaos_cut_rig_stops") if cut else ())):
        assert math.isfinite(figures[name]), (name, story)
    # measured, not timed: inf is "not back before the run ended" (a loaded machine may start a process slowly;
    # the respawn verdict then fails), nan would be "never measured"
    for name in ("chaos_resume_max_sim_node", "chaos_resume_max_recorder"):
        assert not math.isnan(figures[name]), (name, story)


def chaos_story(done: subprocess.CompletedProcess, run: Path) -> str:
    """What a failed chaos run's assertion shows: the faults and what followed each, the verdicts, and the
    last lines of each graph process's log (a start-up that crashed or hung says so there)."""
    lines = [line for line in done.stderr.splitlines() if line.startswith("[soak chaos]")]
    lines += [line for line in done.stdout.splitlines() if line.startswith("verdict ")]
    for log in sorted((run / "logs").glob("*.log")) if (run / "logs").is_dir() else ():
        lines += [f"--- {log.name}", *log.read_text(errors="replace").splitlines()[-8:]]
    return "\n".join(lines)
