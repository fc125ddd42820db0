"""The soak benchmark (bench/soak_bench.py, `make soak`): its command profile and its reading of the recorded
stream.

The benchmark prints and never asserts; these tests check that it measures what it says: the profile a seed
makes and the seq and command accounting it does on the rig's batches (against worm_model's own
command_latencies). No timing figure is asserted here.
"""
from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace


from worm_model.rig_data.samples import command_latencies

REPO = Path(__file__).resolve().parents[1]
BENCH = REPO / "bench"
sys.path.insert(0, str(BENCH))
try:
    import soak_bench  # noqa: E402 - bench/ is a folder of scripts
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


def test_bad_options_are_one_line_and_exit_2(tmp_path: Path) -> None:
    for args, named in ((["--minutes", "0"], "--minutes"), (["--window", "5"], "--window"),
                        (["--work", str(tmp_path)], "--work"), (["--analyse", str(tmp_path)], "--analyse")):
        done = subprocess.run([sys.executable, str(BENCH / "soak_bench.py"), *args], capture_output=True,
                              text=True, timeout=60)
        assert done.returncode == 2 and named in done.stderr and "Traceback" not in done.stderr, (args, done.stderr)
