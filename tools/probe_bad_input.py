#!/usr/bin/env python3
"""Probe every executable with the bad inputs of issue 17 and print the tally.

    tools/run.sh python tools/probe_bad_input.py [-j 2] [-k NAME_PART] [--timeout 20]

Each case runs the installed executable (where `ros2 run` finds it) in a fresh
working folder, with damaged files and bad options built here, and is judged:

  ok          the expected exit code (2 for bad input, 0 for --help); for bad input
              exactly one stderr line ``tool: ...``; no traceback; nothing left behind
  traceback   a Python traceback reached the user
  silent      exit 0 on bad input (a wrong result presented as a right one)
  hang        still running after the timeout (killed)
  lost        a file the user had (input, earlier output, journal) was changed or removed
  leftover    a file or folder was left behind by a refused run
  message     refused, but not with one ``tool: where: what`` line (or the wrong exit code)

The last line is ``probe: <n> cases: ok=.. traceback=.. silent=.. hang=.. lost=.. leftover=.. message=..``;
the exit code is 0 when every case is ok. tests/test_bad_input_probe.py runs it.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

VERDICTS = ("ok", "traceback", "silent", "hang", "lost", "leftover", "message")


@dataclass
class Case:
    """One probe: ``argv`` (executable first) with ``{name}`` replaced by fixture paths."""

    name: str
    argv: list[str]
    expect: int = 2
    #: for --help: a text stdout must contain
    stdout_has: str = ""
    #: for bad input: a text the one stderr line must contain (the problem named)
    stderr_has: str = ""
    #: files put into the working folder first (name -> fixture name): the user's own, must stay as they are
    user_files: dict[str, str] = field(default_factory=dict)
    timeout: float | None = None


def cases() -> list[Case]:
    """Issue 17's findings, one case each (and a few of their siblings)."""
    nodes = {"sim_node": "seed", "model_node": "acceleration_filter", "estimator_node": "calibration_file",
             "controller_node": "kp", "driver_node": "max_drive_voltage", "recorder": "storage"}
    c = [
        # --- tracebacks ---
        Case("worm_calc --rig binary", ["worm_calc", "--rig", "{binary}", "--mu", "0.05"]),
        Case("report binary", ["report", "{binary}", "--out", "figs"]),
        Case("residuals --params binary", ["residuals", "{csv}", "--out", "res", "--params", "{binary}", "--quiet"]),
        Case("worm_effects --check binary", ["worm_effects", "--check", "{binary}"]),
        Case("run_graph binary", ["run_graph", "{binary}"]),
        Case("calibrate --settle-time inf", ["calibrate", "--out", "cal.json", "--settle-time", "inf", "--quiet"]),
        Case("calibrate --seed -1", ["calibrate", "--out", "cal.json", "--seed", "-1", "--speeds", "1",
                                     "--torques", "2", "--quiet"]),
        Case("calibrate --out <dir>", ["calibrate", "--out", "adir", "--speeds", "1", "--torques", "2", "--quiet"],
             user_files={"adir/keep.txt": "text"}),
        Case("residuals --confidence 1.5", ["residuals", "{csv}", "--out", "res", "--confidence", "1.5",
                                            "--no-plots", "--quiet", "--candidates", "viscous_drag"]),
        Case("bag import --start -5", ["bag", "import", "{csv}", "--out", "newbag", "--start", "-5"]),
        Case("bag import negative t", ["bag", "import", "{csv_negative_t}", "--out", "newbag"]),
        Case("virtual_rig --link /nonexistent/x", ["virtual_rig", "--link", "/nonexistent/x", "--duration", "1"]),
        Case("estimator_node -p k:=-1", ["estimator_node", "--ros-args", "-p", "k:=-1"]),
        Case("sim_node -p feedforward_estimator:=kalman", ["sim_node", "--ros-args", "-p", "feedforward_estimator:=kalman"],
             stderr_has="feedforward_estimator"),
        Case("sim_node feedforward_calibration binary", ["sim_node", "--ros-args", "-p", "feedforward_estimator:=observer",
                                                         "-p", "feedforward_calibration:={binary}"],
             stderr_has="feedforward_calibration"),
        Case("driver_node -p max_drive_voltage:=-5.0", ["driver_node", "--ros-args", "-p",
                                                        "max_drive_voltage:=-5.0", "-p", "port:=/nonexistent"]),
        Case("replay current 1e300", ["replay", "{bag_huge_current}", "--set",
                                      "estimator_node.calibration_file={cal}", "--estimators", "knn", "--quiet"],
             stderr_has="current_drive"),
        # --- silently wrong ---
        Case("evaluate load 1e300", ["evaluate", "--calibration", "{cal_huge_load}", "--out", "ev", "--no-sweeps",
                                     "--no-transient", "--quiet"]),
        Case("evaluate one point", ["evaluate", "--calibration", "{cal_one_point}", "--out", "ev", "--no-sweeps",
                                    "--no-transient", "--quiet"]),
        Case("worm_calc --mu 20", ["worm_calc", "--mu", "20"]),
        Case("worm_calc --tau-in 1e308", ["worm_calc", "--tau-in", "1e308", "--tau-load", "0.3", "--json"]),
        Case("residuals --alpha-filter -1", ["residuals", "{csv}", "--out", "res", "--alpha-filter", "-1",
                                             "--no-plots", "--quiet", "--candidates", "viscous_drag"]),
        Case("residuals --max-effects -1", ["residuals", "{csv}", "--out", "res", "--max-effects", "-1",
                                            "--no-plots", "--quiet", "--candidates", "viscous_drag"]),
        Case("residuals --min-improvement -1", ["residuals", "{csv}", "--out", "res", "--min-improvement", "-1",
                                                "--no-plots", "--quiet", "--candidates", "viscous_drag"]),
        Case("bag info metadata version 99", ["bag", "info", "{bag_v99}"]),
        Case("bag echo truncated mcap", ["bag", "echo", "{mcap_cut_half}", "/rig/sample"], stderr_has="truncated"),
        Case("bag export tail-truncated mcap", ["bag", "export", "{mcap_cut_tail}", "--out", "run.csv"],
             stderr_has="truncated"),
        Case("replay truncated mcap", ["replay", "{mcap_cut_half}", "--set",
                                       "estimator_node.calibration_file={cal}", "--quiet"], stderr_has="truncated"),
        Case("report calibration without rig", ["report", "{cal_no_rig}", "--out", "figs"]),
        Case("replay --set unknown parameter", ["replay", "{bag}", "--set", "estimator_node.calibration_file={cal}",
                                                "--set", "estimator_node.nosuchparam=1", "--quiet"]),
        Case("worm_effects --check duplicate keys", ["worm_effects", "--check", "{effects_duplicate}"]),
        Case("worm_effects --check 1e300 N m", ["worm_effects", "--check", "{effects_huge}"]),
        Case("bag import current 1e300", ["bag", "import", "{csv_huge_current}", "--out", "newbag"]),
        # --- never ending ---
        *[Case(f"{node} --help", [node, "--help"], expect=0, stdout_has=param) for node, param in nodes.items()],
        Case("virtual_rig --duration nan", ["virtual_rig", "--link", "link", "--duration", "nan"]),
        Case("calibrate --speed-max 1e9 --timeout 1e5", ["calibrate", "--out", "cal.json", "--speed-max", "1e9",
                                                         "--timeout", "1e5", "--quiet"]),
        # --- lost work ---
        Case("calibrate --resume journal with NaN", ["calibrate", "--out", "cal.json", "--speeds", "1", "--torques",
                                                     "4", "--batch-size", "2", "--resume", "--quiet"],
             user_files={"cal.json.partial": "journal_nan"}),
        Case("worm_effects --template over a user's file", ["worm_effects", "--template", "effects.yaml"],
             user_files={"effects.yaml": "effects_user"}),
        Case("residuals --out over a report", ["residuals", "{csv}", "--out", "res", "--no-plots", "--quiet",
                                               "--candidates", "viscous_drag"],
             user_files={"res/report.json": "text"}),
    ]
    return c


# --- fixtures ----------------------------------------------------------------------------------------

def build_fixtures(folder: Path) -> dict[str, Path]:
    """Every damaged (and one good) input file the cases name, in ``folder``."""
    import numpy as np

    from worm_model.physics.parameters import load_rig
    from worm_model.rig_data.bags import measured_to_bag
    from worm_model.rig_data.schema import MeasuredData, write_rig_csv
    from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
    from torque_estimator.estimation.database import save_database

    f: dict[str, Path] = {}
    folder.mkdir(parents=True, exist_ok=True)

    def put(name: str, content: bytes | str) -> Path:
        path = folder / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        f[name.split(".")[0]] = path
        return path

    put("binary.bin", bytes(range(256)) * 8)
    put("text.txt", "a file the user made\n")
    rig = load_rig()
    # rig data: constant speed against a constant load, ~the rig's current, a little noise
    n = 8000
    rng = np.random.default_rng(1)
    t = np.arange(n) * 1e-3
    omega = 150.0 + rng.normal(0, 0.5, n)
    tau = np.where((t % 2.0) < 1.0, 0.1, 0.3)
    current = 0.05 + 0.12 * tau + 3e-4 * omega + rng.normal(0, 0.002, n)
    data = MeasuredData(t=t, current_drive=current, omega_worm=omega, theta_worm=np.cumsum(omega) * 1e-3,
                        tau_load=tau, voltage_drive=np.full(n, 12.0))
    write_rig_csv(folder / "run.csv", data)
    f["csv"] = folder / "run.csv"
    negative = MeasuredData(**{**{k: getattr(data, k) for k in data.names}, "t": data.t - 1.0})
    write_rig_csv(folder / "negative_t.csv", negative)
    f["csv_negative_t"] = folder / "negative_t.csv"
    huge = MeasuredData(**{k: getattr(data, k).copy() for k in data.names})
    huge.current_drive[1234] = 1e300
    write_rig_csv(folder / "huge_current.csv", huge)
    f["csv_huge_current"] = folder / "huge_current.csv"
    measured_to_bag(data, folder / "bag")
    f["bag"] = folder / "bag"
    measured_to_bag(huge, folder / "bag_huge_current")
    f["bag_huge_current"] = folder / "bag_huge_current"
    shutil.copytree(folder / "bag", folder / "bag_v99")
    meta = folder / "bag_v99" / "metadata.yaml"
    text = meta.read_text()
    meta.write_text(text.replace("  version: ", "  version: 99\n  _old_version: ", 1))
    f["bag_v99"] = folder / "bag_v99"
    (mcap,) = (folder / "bag").glob("*.mcap")
    raw = mcap.read_bytes()
    put("cut_half.mcap", raw[: len(raw) // 2])
    f["mcap_cut_half"] = folder / "cut_half.mcap"
    put("cut_tail.mcap", raw[: int(len(raw) * 0.9)])
    f["mcap_cut_tail"] = folder / "cut_tail.mcap"

    grid = CalibrationGrid.paper(rig, 3, 4)
    db = calibrate_simulated(rig, grid, seed=0)
    save_database(db, folder / "cal.json")
    f["cal"] = folder / "cal.json"
    doc = json.loads((folder / "cal.json").read_text())
    huge_doc = json.loads(json.dumps(doc))
    huge_doc["points"]["tau_load"][3] = 1e300
    put("cal_huge_load.json", json.dumps(huge_doc))
    save_database(db.subset(np.arange(1)), folder / "cal_one_point.json")
    f["cal_one_point"] = folder / "cal_one_point.json"
    no_rig = json.loads(json.dumps(doc))
    del no_rig["rig"]
    put("cal_no_rig.json", json.dumps(no_rig))

    # a journal of `calibrate --speeds 1 --torques 4 --batch-size 2`: first batch done, one NaN in it
    journal = folder / "journal_full.partial"
    calibrate_simulated(rig, CalibrationGrid.paper(rig, 1, 4), seed=0, batch_size=2, journal=journal)
    jdoc = json.loads(journal.read_text())
    keep = [i for i, index in enumerate(jdoc["points"]["plan_index"]) if index < 2]
    for name, values in jdoc["points"].items():
        jdoc["points"][name] = [values[i] for i in keep]
    jdoc["points"]["current_drive"][1] = None
    journal.unlink()
    put("journal_nan.partial", json.dumps(jdoc, indent=1))

    put("effects_duplicate.yaml", "format: worm_rig_effects\nversion: 1\neffects:\n  viscous_drag: {}\n"
                                  "  viscous_drag: {enabled: false}\n")
    put("effects_huge.yaml", "format: worm_rig_effects\nversion: 1\neffects:\n  bearing_coulomb:\n"
                             "    worm_torque: {value: 1e300, unit: N m}\n")
    put("effects_user.yaml", "# my effects, edited by hand\nformat: worm_rig_effects\nversion: 1\neffects: {}\n")
    return f


# --- running -----------------------------------------------------------------------------------------

def _digest(path: Path) -> str:
    if path.is_dir():
        return ";".join(f"{p.relative_to(path)}={_digest(p)}" for p in sorted(path.rglob("*")) if p.is_file())
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.exists() else "absent"


def _listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _executable(name: str) -> str:
    from worm_model.ros.ament import find_executable
    return str(find_executable(name))


def run_case(case: Case, fixtures: dict[str, Path], work: Path, timeout: float) -> tuple[str, str]:
    """(verdict, detail) of one case, run in its own folder under ``work``."""
    cwd = Path(tempfile.mkdtemp(prefix="case_", dir=work))
    for rel, fixture in case.user_files.items():
        target = cwd / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(fixtures[fixture], target)
    argv = [_executable(case.argv[0])] + [a.format(**{k: str(v) for k, v in fixtures.items()})
                                          for a in case.argv[1:]]
    inputs = {name: _digest(path) for name, path in fixtures.items()}
    users = {rel: _digest(cwd / rel) for rel in case.user_files}
    before = _listing(cwd)
    env = {**os.environ, "ROS_DOMAIN_ID": str(random.randint(100, 230)),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    process = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               stdin=subprocess.DEVNULL, start_new_session=True)
    try:
        out, err = process.communicate(timeout=case.timeout or timeout)
        hung = False
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        out, err = process.communicate()
        hung = True
    out_text, err_text = out.decode(errors="replace"), err.decode(errors="replace")
    lines = [line for line in err_text.splitlines() if line.strip()]
    changed = [name for name, digest in inputs.items() if _digest(fixtures[name]) != digest]
    changed += [rel for rel, digest in users.items() if _digest(cwd / rel) != digest]
    left = sorted(_listing(cwd) - before)
    first = lines[0] if lines else "(nothing on stderr)"
    if hung:
        return "hang", f"still running after {case.timeout or timeout:g} s"
    if "Traceback (most recent call last)" in out_text + err_text:
        tail = [line for line in (err_text or out_text).splitlines() if line.strip()][-1:]
        return "traceback", tail[0] if tail else ""
    if changed:
        return "lost", f"changed: {', '.join(changed)}"
    if process.returncode != case.expect:
        if process.returncode == 0:
            return "silent", f"exit 0; stdout: {out_text.strip().splitlines()[-1:] or ''}"
        return "message", f"exit {process.returncode}, expected {case.expect}: {first}"
    if left and case.expect != 0 or case.expect == 0 and left:
        return "leftover", ", ".join(left)
    if case.expect == 0:
        if case.stdout_has and case.stdout_has not in out_text:
            return "message", f"stdout lacks {case.stdout_has!r}"
        return "ok", (out_text.strip().splitlines() or [""])[0]
    tool = case.argv[0] + (f" {case.argv[1]}" if case.argv[0] == "bag" else "")  # bag's subcommands
    if len(lines) != 1 or not lines[0].startswith(f"{tool}:") or lines[0].count(":") < 2:
        return "message", f"{len(lines)} stderr line(s): {' | '.join(lines[:3])}"
    if case.stderr_has not in lines[0]:
        return "message", f"does not name {case.stderr_has!r}: {lines[0]}"
    return "ok", lines[0]


def probe(selected: list[Case], jobs: int = 2, timeout: float = 30.0, verbose: bool = True
          ) -> dict[str, list[tuple[str, str]]]:
    """Run the cases; returns verdict -> [(case name, detail)]."""
    work = Path(tempfile.mkdtemp(prefix="probe_bad_input_"))
    try:
        fixtures = build_fixtures(work / "fixtures")
        results: dict[str, list[tuple[str, str]]] = {v: [] for v in VERDICTS}
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = [(case, pool.submit(run_case, case, fixtures, work, timeout)) for case in selected]
            for case, future in futures:
                verdict, detail = future.result()
                results[verdict].append((case.name, detail))
                if verbose:
                    print(f"{verdict:<9} {case.name}: {detail}", flush=True)
        return results
    finally:
        shutil.rmtree(work, ignore_errors=True)


def tally_line(results: dict[str, list[tuple[str, str]]]) -> str:
    n = sum(len(v) for v in results.values())
    return f"probe: {n} cases: " + " ".join(f"{v}={len(results[v])}" for v in VERDICTS)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="probe_bad_input", description=__doc__.split("\n\n")[0])
    parser.add_argument("-j", "--jobs", type=int, default=2, help="cases run at once (default 2)")
    parser.add_argument("-k", default="", help="only the cases whose name contains this")
    parser.add_argument("--timeout", type=float, default=30.0, help="a case still running after this [s] hangs")
    args = parser.parse_args(argv)
    selected = [c for c in cases() if args.k in c.name]
    results = probe(selected, args.jobs, args.timeout)
    print(tally_line(results))
    return 0 if len(results["ok"]) == len(selected) else 1


if __name__ == "__main__":
    sys.exit(main())
