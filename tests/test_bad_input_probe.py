"""The careless-user probe: every case of tools/probe_bad_input.py ends the way bad input must.

Runs the installed executables (as `ros2 run` finds them) on bad options, damaged files, outputs that
are inputs, FIFOs, YAML bombs, logs in the wrong unit, misspelt parameters and Ctrl-C in the middle of
long runs (the probe's groups: options, out, in, units, params, ctrl-c): 0 tracebacks, 0 silently wrong
results, 0 hangs, 0 lost user files, nothing left behind (files or processes), one-line refusals. About
270 cases; 3 minutes with two at a time on a 2-core machine shared with other work.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

PROBE = Path(__file__).resolve().parents[1] / "tools" / "probe_bad_input.py"


@pytest.mark.slow
def test_every_probe_case_is_refused_cleanly(ros_env) -> None:
    spec = importlib.util.spec_from_file_location("probe_bad_input", PROBE)
    probe = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = probe  # dataclasses look their module up there
    spec.loader.exec_module(probe)
    results = probe.probe(probe.cases(), jobs=2, timeout=60.0, verbose=False)
    failed = {verdict: cases for verdict, cases in results.items() if verdict != "ok" and cases}
    assert not failed, probe.tally_line(results) + "\n" + "\n".join(
        f"{verdict}: {name}: {detail}" for verdict, cases in failed.items() for name, detail in cases)
