#!/usr/bin/env python3
"""Probe every executable with careless users' inputs and print the tally.

    tools/run.sh python tools/probe_bad_input.py [-j 2] [-k NAME_PART] [--timeout 30]

Each case runs the installed executable (where `ros2 run` finds it) in a fresh
working folder, with damaged files and bad options built here, and is judged:

  ok          the expected exit code (2 for bad input, 0 for a run that must work, 130 or 0
              after Ctrl-C); for bad input exactly one stderr line ``tool: ...``; no traceback;
              nothing left behind
  traceback   a Python traceback (or an "internal error") reached the user
  silent      exit 0 on bad input (a wrong result presented as a right one)
  hang        still running after the timeout (killed), or after Ctrl-C
  lost        a file the user had (input, earlier output, journal, the working folder's
              files) was changed or removed
  leftover    a file or folder was left behind by a refused or interrupted run
  message     refused, but not with one ``tool: where: what`` line (or the wrong exit code)

The cases, by mechanism (their names start with the group):
  options   bad options and damaged files
  out       the output policy: an output that is an input, holds one or lies inside one; --force
            over the user's own file or folder; empty paths, `.`, `..`, the home folder;
            unwritable places; --force over the tool's own earlier output (must work)
  in        the input policy: FIFOs, devices and folders where a file is expected, byte-order
            marks (must work), YAML bombs and deep nesting, ROS parameter files rcl cannot read
  units     logs and calibrations in the wrong unit (t in ms, mA, rpm, degrees), implausible rig
            files, worm_calc's energy balance
  params    parameters no node declares, named files a node cannot use, values run_graph must
            refuse before starting anything, the recorder's refusals
  ctrl-c    Ctrl-C (SIGINT to the process group, as a terminal sends it) in the middle of long
            runs: ends promptly, partial work cleaned up or journaled as the tool documents

The last line is ``probe: <n> cases: ok=.. traceback=.. silent=.. hang=.. lost=.. leftover=.. message=..``;
the exit code is 0 when every case is ok. tests/test_bad_input_probe.py runs it.
"""
from __future__ import annotations

import argparse
import fnmatch
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
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from worm_model.cli.errors import restore_ctrl_c

VERDICTS = ("ok", "traceback", "silent", "hang", "lost", "leftover", "message")


@dataclass
class Case:
    """One probe: ``argv`` (executable first) with ``{name}`` replaced by fixture paths (``{case}``: the
    case's folder)."""

    name: str
    argv: list[str]
    expect: int | tuple[int, ...] = 2
    #: for --help: a text stdout must contain
    stdout_has: str = ""
    #: for bad input: a text the one stderr line must contain (the problem named)
    stderr_has: str = ""
    #: files or folders put into the case's folder first (name -> fixture name): the user's own, must stay
    user_files: dict[str, str] = field(default_factory=dict)
    timeout: float | None = None
    #: FIFOs made in the case's folder (a careless user's named pipe where a file should be)
    fifos: tuple[str, ...] = ()
    #: working folder, relative to the case's folder (made first)
    cwd: str = ""
    #: HOME for the run, relative to the case's folder ("" leaves HOME alone)
    home: str = ""
    #: Ctrl-C: SIGINT to the process group once this glob matches in the case's folder (or after
    #: ``interrupt_after`` seconds for a server that runs until stopped); then the run must end
    interrupt_when: str = ""
    interrupt_after: float = 0.0
    #: globs of what a run may leave in the case's folder (an output that must be written, a journal)
    may_leave: tuple[str, ...] = ()


def options_cases() -> list[Case]:
    """Issue 17's findings, one case each (and a few of their siblings)."""
    nodes = {"sim_node": "seed", "model_node": "acceleration_filter", "estimator_node": "calibration_file",
             "controller_node": "kp", "driver_node": "max_drive_voltage", "recorder": "storage"}
    c = [
        # --- tracebacks ---
        Case("worm_calc --rig binary", ["worm_calc", "--rig", "{binary}", "--mu", "0.05"]),
        Case("report binary", ["report", "{binary}", "--out", "figs"]),
        Case("residuals --rig binary", ["residuals", "{csv}", "--out", "res", "--rig", "{binary}", "--quiet"]),
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
        Case("sim_node -p feedforward_estimator:=kalman",
             ["sim_node", "--ros-args", "-p", "feedforward_estimator:=kalman"],
             stderr_has="feedforward_estimator"),
        Case("sim_node feedforward_calibration binary",
             ["sim_node", "--ros-args", "-p", "feedforward_estimator:=observer",
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
        Case("bag import --topic 'not a topic'", ["bag", "import", "{csv}", "--out", "newbag", "--topic",
                                                  "not a topic"], stderr_has="not a valid topic name"),
        Case("worm_effects --check low_speed_gain 1e6", ["worm_effects", "--check", "{effects_gain}"],
             stderr_has="low_speed_gain"),
        Case("run_graph --log-dir a file", ["run_graph", "--log-dir", "{text}"], stderr_has="--log-dir"),
        Case("estimator_node -p method:=knn without a calibration", _node("estimator_node", "-p", "method:=knn"),
             stderr_has="calibration_file"),
        Case("driver_node -p port:=a folder", ["driver_node", "--ros-args", "-p", "port:=/tmp"],
             stderr_has="not a serial"),
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
    for case in c:
        case.name = f"options: {case.name}"
    return c


def cases() -> list[Case]:
    """Every case: the first probe's and one group per mechanism (module docstring)."""
    return [*options_cases(), *output_cases(), *input_cases(), *unit_cases(), *parameter_cases(),
            *interrupt_cases()]


QUICK_RESIDUALS = ["--no-plots", "--quiet", "--candidates", "viscous_drag"]
QUICK_EVALUATE = ["--no-sweeps", "--no-transient", "--no-residuals", "--quiet"]
GRID = ["--speeds", "1", "--torques", "2", "--quiet"]
#: what importing matplotlib may make in a fresh home folder (its font cache), not the tool's doing
HOME_CACHES = ("home/.cache*", "home/.config*")
NODES = ("sim_node", "model_node", "estimator_node", "controller_node", "driver_node", "recorder")
#: what a node needs besides the case's parameters to get as far as checking them
NODE_BASE = {"driver_node": ["-p", "port:=/nonexistent/tty"]}


def _node(node: str, *ros_args: str) -> list[str]:
    return [node, "--ros-args", *ros_args, *NODE_BASE.get(node, [])]


def output_cases() -> list[Case]:
    """The output policy: nothing a user hands a tool is lost, --force only over the tool's own output."""
    keep = {"keep.txt": "text"}
    c = [
        # an output that is an input, holds one, lies inside one
        Case("residuals --out the folder of its data --force", ["residuals", "d/run.csv", "--out", "d", "--force",
             *QUICK_RESIDUALS], user_files={"d/run.csv": "csv"}, stderr_has="input"),
        Case("residuals --out its --rig file --force", ["residuals", "run.csv", "--rig", "rig.yaml", "--out",
             "rig.yaml", "--force", *QUICK_RESIDUALS], user_files={"run.csv": "csv", "rig.yaml": "rig"}),
        Case("residuals --out its bag --force", ["residuals", "b", "--out", "b", "--force", *QUICK_RESIDUALS],
             user_files={"b": "bag"}),
        Case("residuals --out inside its bag", ["residuals", "b", "--out", "b/res", *QUICK_RESIDUALS],
             user_files={"b": "bag"}, stderr_has="inside"),
        Case("report --out the folder of its calibration --force", ["report", "d/cal.json", "--out", "d", "--force"],
             user_files={"d/cal.json": "cal"}),
        Case("report --out its calibration --force", ["report", "cal.json", "--out", "cal.json", "--force"],
             user_files={"cal.json": "cal"}),
        Case("evaluate --out the folder of its calibration --force", ["evaluate", "--calibration", "d/cal.json",
             "--out", "d", "--force", *QUICK_EVALUATE], user_files={"d/cal.json": "cal"}),
        Case("demo --out its graph file --force", ["demo", "--graph", "g.yaml", "--out", "g.yaml", "--force"],
             user_files={"g.yaml": "graph"}),
        Case("calibrate --out its --rig file --force", ["calibrate", "--rig", "rig.yaml", "--out", "rig.yaml",
             "--force", *GRID], user_files={"rig.yaml": "rig"}),
        Case("estimate --out its log", ["estimate", "run.csv", "--method", "observer", "--out", "run.csv"],
             user_files={"run.csv": "csv"}),
        Case("estimate --out its log --force", ["estimate", "run.csv", "--method", "observer", "--out", "run.csv",
             "--force"], user_files={"run.csv": "csv"}),
        Case("estimate --out inside its bag", ["estimate", "b", "--method", "observer", "--out", "b/e.csv"],
             user_files={"b": "bag"}),
        Case("identify --out its --rig file", ["identify", "--rig", "rig.yaml", "--out", "rig.yaml", "--from",
             "{csv}"], user_files={"rig.yaml": "rig"}),
        Case("identify --out its --from log --force", ["identify", "--from", "run.csv", "--out", "run.csv",
             "--force"], user_files={"run.csv": "csv"}),
        Case("bag export --out its bag file --force", ["bag", "export", "run.mcap", "--out", "run.mcap", "--force"],
             user_files={"run.mcap": "mcap"}),
        Case("bag export --out inside its bag", ["bag", "export", "b", "--out", "b/run.csv"],
             user_files={"b": "bag"}),
        Case("bag import --out its CSV", ["bag", "import", "run.csv", "--out", "run.csv"],
             user_files={"run.csv": "csv"}),
        Case("worm_effects --template its --check file --force", ["worm_effects", "--check", "e.yaml",
             "--template", "e.yaml", "--force"], user_files={"e.yaml": "effects_user"}),
        Case("virtual_rig --link its --rig file", ["virtual_rig", "--rig", "rig.yaml", "--link", "rig.yaml",
             "--duration", "1"], user_files={"rig.yaml": "rig"}),
        # --force over what the user made
        Case("residuals --force over the user's folder", ["residuals", "{csv}", "--out", "res", "--force",
             *QUICK_RESIDUALS], user_files={"res/thesis.tex": "text"}, stderr_has="not a folder written by"),
        Case("report --force over the user's folder", ["report", "{cal}", "--out", "figs", "--force"],
             user_files={"figs/thesis.tex": "text"}),
        Case("evaluate --force over the user's folder", ["evaluate", "--calibration", "{cal}", "--out", "ev",
             "--force", *QUICK_EVALUATE], user_files={"ev/thesis.tex": "text"}),
        Case("demo --force over the user's folder", ["demo", "--out", "mine", "--force"],
             user_files={"mine/thesis.tex": "text"}),
        Case("calibrate --force over the user's file", ["calibrate", "--out", "notes.txt", "--force", *GRID],
             user_files={"notes.txt": "text"}),
        Case("estimate over an earlier file, no --force", ["estimate", "run.csv", "--method", "observer"],
             user_files={"run.csv": "csv", "run_observer.csv": "text"}, stderr_has="--force"),
        Case("estimate --force over the user's file", ["estimate", "run.csv", "--method", "observer", "--force"],
             user_files={"run.csv": "csv", "run_observer.csv": "text"}),
        Case("identify over the user's file, no --force", ["identify", "--from", "{csv}", "--out", "mine.yaml"],
             user_files={"mine.yaml": "text"}, stderr_has="--force"),
        Case("identify --force over the user's rig file", ["identify", "--from", "{csv}", "--out", "mine.yaml",
             "--force"], user_files={"mine.yaml": "rig"}),
        Case("bag export --force over the user's text", ["bag", "export", "{bag}", "--out", "notes.txt", "--force"],
             user_files={"notes.txt": "text"}),
        Case("bag import --force over the user's folder", ["bag", "import", "{csv}", "--out", "mine", "--force"],
             user_files={"mine/thesis.tex": "text"}),
        Case("worm_effects --template --force over the user's rig file", ["worm_effects", "--template",
             "rig.yaml", "--force"], user_files={"rig.yaml": "rig"}),
        Case("recorder output over the user's folder", _node("recorder", "-p", "output:=mine"),
             user_files={"mine/thesis.tex": "text"}),
        Case("recorder output over the user's file", _node("recorder", "-p", "output:=notes.txt"),
             user_files={"notes.txt": "text"}),
        # empty paths (--out "$UNSET"), the working folder, above it, home
        *[Case(f"{tool} --out '' --force", [*argv, "--out", "", "--force"], user_files=keep, stderr_has="empty")
          for tool, argv in (("residuals", ["residuals", "{csv}", *QUICK_RESIDUALS]), ("report", ["report", "{cal}"]),
                             ("evaluate", ["evaluate", "--calibration", "{cal}", *QUICK_EVALUATE]),
                             ("demo", ["demo"]), ("calibrate", ["calibrate", *GRID]),
                             ("estimate", ["estimate", "{csv}", "--method", "observer"]),
                             ("identify", ["identify", "--from", "{csv}"]),
                             ("bag export", ["bag", "export", "{bag}"]), ("bag import", ["bag", "import", "{csv}"]))],
        Case("worm_effects --template ''", ["worm_effects", "--template", ""], user_files=keep, stderr_has="empty"),
        Case("virtual_rig --link ''", ["virtual_rig", "--link", "", "--duration", "1"], user_files=keep),
        Case("recorder output:=.", _node("recorder", "-p", "output:=."), user_files=keep),
        *[Case(f"{tool} --out . --force", [*argv, "--out", ".", "--force"], user_files=keep,
               stderr_has="working folder")
          for tool, argv in (("residuals", ["residuals", "{csv}", *QUICK_RESIDUALS]), ("report", ["report", "{cal}"]),
                             ("evaluate", ["evaluate", "--calibration", "{cal}", *QUICK_EVALUATE]),
                             ("demo", ["demo"]))],
        Case("demo --out .. --force", ["demo", "--out", "..", "--force"], cwd="sub", user_files=keep,
             stderr_has="working folder"),
        Case("report --out .. --force", ["report", "{cal}", "--out", "..", "--force"], cwd="sub", user_files=keep),
        Case("demo --out $HOME --force", ["demo", "--out", "{case}/home", "--force"], home="home",
             user_files={"home/keep.txt": "text"}, stderr_has="home", may_leave=HOME_CACHES),
        Case("residuals --out $HOME --force", ["residuals", "{csv}", "--out", "{case}/home", "--force",
             *QUICK_RESIDUALS], home="home", user_files={"home/keep.txt": "text"}, may_leave=HOME_CACHES),
        # unwritable places: one line naming --out, exit 2, no temporary file named
        *[Case(f"{tool} --out unwritable", [*argv, "--out", "/proc/worm_probe_out"], stderr_has="--out")
          for tool, argv in (("residuals", ["residuals", "{csv}", *QUICK_RESIDUALS]), ("report", ["report", "{cal}"]),
                             ("calibrate", ["calibrate", *GRID]),
                             ("estimate", ["estimate", "{csv}", "--method", "observer"]),
                             ("identify", ["identify", "--from", "{csv}"]),
                             ("bag export", ["bag", "export", "{bag}"]), ("bag import", ["bag", "import", "{csv}"]))],
        Case("virtual_rig --link unwritable", ["virtual_rig", "--link", "/proc/worm_probe_link", "--duration", "1"],
             stderr_has="--link"),
        Case("calibrate --journal unwritable", ["calibrate", "--out", "c.json", "--journal", "/proc/j.partial", *GRID],
             stderr_has="--journal"),
        Case("estimate --out a name too long", ["estimate", "{csv}", "--method", "observer", "--out", "x" * 300],
             stderr_has="too long"),
        # --force over the tool's own earlier output: must work (make demo and make evaluate do it on reruns)
        Case("report --force over its own output", ["report", "{cal}", "--out", "figs", "--force"], expect=0,
             user_files={"figs": "report_out"}, may_leave=("figs", "figs/*")),
        Case("report --force over its own output from before markers", ["report", "{cal}", "--out", "figs", "--force"],
             expect=0, user_files={"figs": "report_out_unmarked"}, may_leave=("figs", "figs/*")),
        Case("calibrate --force over a calibration", ["calibrate", "--out", "cal.json", "--force", *GRID], expect=0,
             user_files={"cal.json": "cal"}, may_leave=("cal.json",)),
        Case("estimate --force over its own output", ["estimate", "run.csv", "--method", "observer", "--force"],
             expect=0, user_files={"run.csv": "csv", "run_observer.csv": "estimate_out"},
             may_leave=("run_observer.csv",)),
        Case("bag export --force over a rig-data CSV", ["bag", "export", "{bag}", "--out", "run.csv", "--force"],
             expect=0, user_files={"run.csv": "csv"}, may_leave=("run.csv",)),
        Case("bag import --force over its own bag", ["bag", "import", "{csv}", "--out", "nb", "--force"], expect=0,
             user_files={"nb": "imported_bag"}, may_leave=("nb", "nb/*")),
        Case("worm_effects --template --force over its template", ["worm_effects", "--template", "t.yaml",
             "--force"], expect=0, user_files={"t.yaml": "effects_template"}, may_leave=("t.yaml",)),
    ]
    replaced = {"report --force over its own output": "figs",
                "report --force over its own output from before markers": "figs",
                "calibrate --force over a calibration": "cal.json",
                "estimate --force over its own output": "run_observer.csv",
                "bag export --force over a rig-data CSV": "run.csv", "bag import --force over its own bag": "nb",
                "worm_effects --template --force over its template": "t.yaml"}
    for case in c:
        case.may_leave = (*case.may_leave, *([f"{replaced[case.name]}"] if case.name in replaced else []))
        case.name = f"out: {case.name}"
    return c


def input_cases() -> list[Case]:
    """The input policy: regular files only (a FIFO never opened), BOMs, YAML limits, parameter files."""
    fifo = {"csv": "f.csv", "yaml": "f.yaml", "json": "f.json", "mcap": "f.mcap"}
    c = [
        *[Case(f"{name} a FIFO", [*argv], fifos=(fifo[kind],), stderr_has="FIFO", timeout=40)
          for name, kind, argv in (
              ("residuals", "csv", ["residuals", "f.csv", "--out", "res", *QUICK_RESIDUALS]),
              ("residuals --rig", "yaml", ["residuals", "{csv}", "--rig", "f.yaml", "--out", "res"]),
              ("estimate", "csv", ["estimate", "f.csv", "--method", "observer", "--out", "e.csv"]),
              ("identify --from", "csv", ["identify", "--from", "f.csv", "--out", "x.yaml"]),
              ("bag import", "csv", ["bag", "import", "f.csv", "--out", "nb"]),
              ("bag echo", "mcap", ["bag", "echo", "f.mcap", "/rig/sample"]),
              ("bag info", "mcap", ["bag", "info", "f.mcap"]),
              ("bag export", "mcap", ["bag", "export", "f.mcap", "--out", "x.csv"]),
              ("calibrate --rig", "yaml", ["calibrate", "--rig", "f.yaml", "--out", "c.json"]),
              ("worm_calc --rig", "yaml", ["worm_calc", "--rig", "f.yaml", "--mu", "0.05"]),
              ("worm_effects --check", "yaml", ["worm_effects", "--check", "f.yaml"]),
              ("report", "json", ["report", "f.json", "--out", "figs"]),
              ("evaluate --calibration", "json", ["evaluate", "--calibration", "f.json", "--out", "ev"]),
              ("replay", "mcap", ["replay", "f.mcap"]),
              ("run_graph", "yaml", ["run_graph", "f.yaml"]),
              ("virtual_rig --rig", "yaml", ["virtual_rig", "--rig", "f.yaml", "--duration", "1"]),
              ("sim_node rig_file", "yaml", _node("sim_node", "-p", "rig_file:=f.yaml")),
              ("estimator_node --params-file", "yaml", _node("estimator_node", "--params-file", "f.yaml")),
              ("model_node --params-file", "yaml", _node("model_node", "--params-file", "f.yaml")),
          )],
        Case("worm_calc --rig a character device", ["worm_calc", "--rig", "/dev/null", "--mu", "0.05"],
             stderr_has="device"),
        Case("worm_calc --rig a folder", ["worm_calc", "--rig", "{bag}", "--mu", "0.05"], stderr_has="folder"),
        Case("worm_calc --rig a symlink loop", ["worm_calc", "--rig", "loop.yaml", "--mu", "0.05"],
             user_files={"loop.yaml": "symlink_loop"}, stderr_has="symbolic links"),
        Case("estimate --calibration a folder", ["estimate", "{csv}", "--method", "knn", "--calibration", "{bag}",
             "--out", "e.csv"], stderr_has="folder"),
        # a UTF-8 byte-order mark (what some editors and Excel write) is read like any text
        Case("estimate a CSV with a BOM", ["estimate", "{csv_bom}", "--method", "observer", "--out", "e.csv"],
             expect=0, may_leave=("e.csv",)),
        Case("bag import a CSV with a BOM", ["bag", "import", "{csv_bom}", "--out", "nb"], expect=0,
             may_leave=("nb", "nb/*")),
        Case("worm_calc a rig file with a BOM", ["worm_calc", "--rig", "{rig_bom}", "--mu", "0.05"], expect=0),
        Case("estimate a calibration with a BOM", ["estimate", "{csv}", "--method", "knn", "--calibration",
             "{cal_bom}", "--out", "e.csv"], expect=0, may_leave=("e.csv",)),
        Case("run_graph a graph file with a BOM --set k=abc", ["run_graph", "{graph_bom}", "--set",
             "estimator_node.k=abc"], stderr_has="estimator_node.k"),
        # anchors and merge keys: read in a rig file (the bundled one has them), refused in a ROS parameter file
        Case("worm_calc a rig file with anchors and merge keys", ["worm_calc", "--rig", "{rig}", "--mu", "0.05"],
             expect=0),
        *[Case(f"{tool} a YAML bomb", argv, stderr_has="billion laughs", timeout=40) for tool, argv in (
            ("residuals --rig", ["residuals", "{csv}", "--rig", "{rig_bomb}", "--out", "res"]),
            ("identify --rig", ["identify", "--rig", "{rig_bomb}", "--from", "{csv}", "--out", "x.yaml"]),
            ("worm_calc --rig", ["worm_calc", "--rig", "{rig_bomb}", "--mu", "0.05"]),
            ("calibrate --rig", ["calibrate", "--rig", "{rig_bomb}", "--out", "c.json"]),
            ("worm_effects --check", ["worm_effects", "--check", "{effects_bomb}"]),
            ("virtual_rig --effects", ["virtual_rig", "--effects", "{effects_bomb}", "--duration", "1"]),
            ("sim_node effects_file", _node("sim_node", "-p", "effects_file:={effects_bomb}")),
            )],
        *[Case(f"{tool} a YAML bomb (anchors refused)", argv, stderr_has="anchors", timeout=40) for tool, argv in (
            ("run_graph", ["run_graph", "{graph_bomb}"]),
            ("estimator_node --params-file", _node("estimator_node", "--params-file", "{graph_bomb}")))],
        *[Case(f"{tool} deep YAML", argv, stderr_has="nested", timeout=40) for tool, argv in (
            ("residuals --rig", ["residuals", "{csv}", "--rig", "{yaml_deep}", "--out", "res"]),
            ("identify --rig", ["identify", "--rig", "{yaml_deep}", "--from", "{csv}", "--out", "x.yaml"]),
            ("worm_calc --rig", ["worm_calc", "--rig", "{yaml_deep}", "--mu", "0.05"]),
            ("calibrate --rig", ["calibrate", "--rig", "{yaml_deep}", "--out", "c.json"]),
            ("worm_effects --check", ["worm_effects", "--check", "{yaml_deep}"]),
            ("run_graph", ["run_graph", "{yaml_deep}"]),
            ("evaluate --rig", ["evaluate", "--rig", "{yaml_deep}", "--out", "ev"]),
            ("sim_node rig_file", _node("sim_node", "-p", "rig_file:={yaml_deep}")),
            ("model_node --params-file", _node("model_node", "--params-file", "{yaml_deep}")))],
        *[Case(f"{tool} deep JSON", argv, stderr_has="nested") for tool, argv in (
            ("report", ["report", "{json_deep}", "--out", "figs"]),
            ("evaluate --calibration", ["evaluate", "--calibration", "{json_deep}", "--out", "ev"]),
            ("estimate --calibration", ["estimate", "{csv}", "--method", "knn", "--calibration", "{json_deep}",
                                        "--out", "e.csv"]),
            ("estimator_node calibration_file", _node("estimator_node", "-p", "calibration_file:={json_deep}")))],
        Case("bag info a bag whose metadata.yaml is a bomb", ["bag", "info", "{bag_meta_bomb}"],
             stderr_has="billion laughs"),
        # ROS parameter files rcl cannot read: one line, no RCLError traceback, from every node and tool
        *[Case(f"{node} --params-file {kind}", _node(node, "--params-file", "{" + fixture + "}"), stderr_has=has)
          for node in NODES for kind, fixture, has in (("with an anchor", "graph_anchor", "anchor"),
                                                      ("binary", "binary", "UTF-8"))],
        *[Case(f"estimator_node --params-file {kind}", _node("estimator_node", "--params-file", "{" + fixture + "}"))
          for kind, fixture in (("with a merge key", "graph_merge"), ("not YAML", "graph_not_yaml"),
                                ("with a mixed list", "graph_mixed"), ("with a value beside ros__parameters",
                                                                       "graph_value_beside"))],
        *[Case(f"run_graph {kind}", ["run_graph", "{" + fixture + "}"])
          for kind, fixture in (("with an anchor", "graph_anchor"), ("with a merge key", "graph_merge"),
                                ("not YAML", "graph_not_yaml"), ("with a mixed list", "graph_mixed"),
                                ("with a value beside ros__parameters", "graph_value_beside"))],
        Case("replay --params-file with an anchor", ["replay", "{bag}", "--params-file", "{graph_anchor}"],
             stderr_has="anchor"),
        Case("estimate --params-file with an anchor", ["estimate", "{csv}", "--method", "observer", "--params-file",
             "{graph_anchor}", "--out", "e.csv"], stderr_has="anchor"),
        Case("demo --graph with an anchor", ["demo", "--graph", "{graph_anchor}", "--out", "d"], stderr_has="anchor"),
    ]
    for case in c:
        case.name = f"in: {case.name}"
    return c


def unit_cases() -> list[Case]:
    """Units checked against the rig: a log, a calibration, a rig file, worm_calc's energy balance."""
    logs = {"csv_ms": "milliseconds", "csv_us": "microseconds", "csv_mA": "mA", "csv_deg": "degrees",
            "csv_rpm": "rpm", "csv_rpm_slow": "rpm"}
    tools = {"residuals": lambda f: ["residuals", f, "--out", "res", *QUICK_RESIDUALS],
             "estimate": lambda f: ["estimate", f, "--method", "observer", "--out", "e.csv"],
             "identify --from": lambda f: ["identify", "--from", f, "--out", "x.yaml"],
             "bag import": lambda f: ["bag", "import", f, "--out", "nb"]}
    everywhere = ("csv_ms", "csv_mA", "csv_deg")  # the three unit slips, through every reader; the others through two
    c = [Case(f"{tool} a log with {fixture.split('_', 1)[1]}", argv("{" + fixture + "}"), stderr_has=has)
         for fixture, has in logs.items() for tool, argv in tools.items()
         if fixture in everywhere or tool in ("residuals", "identify --from")]
    calibrations = {"cal_zero_range": "torque range", "cal_identical": "same operating point", "cal_rpm": "rpm",
                    "cal_flipped": "sign opposite"}
    for fixture, has in calibrations.items():
        c += [Case(f"estimate --calibration {fixture}", ["estimate", "{csv}", "--method", "knn", "--calibration",
                                                          "{" + fixture + "}", "--out", "e.csv"], stderr_has=has),
              Case(f"report {fixture}", ["report", "{" + fixture + "}", "--out", "figs"], stderr_has=has),
              Case(f"evaluate --calibration {fixture}", ["evaluate", "--calibration", "{" + fixture + "}",
                                                         "--out", "ev", *QUICK_EVALUATE], stderr_has=has),
              Case(f"estimator_node calibration_file:={fixture}",
                   _node("estimator_node", "-p", "method:=knn", "-p", f"calibration_file:={{{fixture}}}"),
                   stderr_has=has),
              Case(f"sim_node feedforward_calibration:={fixture}",
                   _node("sim_node", "-p", "feedforward_estimator:=knn", "-p",
                         f"feedforward_calibration:={{{fixture}}}"), stderr_has=has)]
    c += [Case("estimate a one-row log", ["estimate", "{csv_one_row}", "--method", "observer", "--out", "e.csv"],
               stderr_has="sample"),
          Case("residuals a one-row log", ["residuals", "{csv_one_row}", "--out", "res"])]
    rigs = {"rig_kt_tiny": "torque_constant", "rig_1MV": "supply_voltage", "rig_lead_rad": "lead_angle"}
    for fixture, has in rigs.items():  # load_rig is one function: K_t through every tool, the others through two
        c += [Case(f"calibrate --rig {fixture}", ["calibrate", "--rig", "{" + fixture + "}", "--out", "c.json"],
                   stderr_has=has),
              Case(f"sim_node rig_file:={fixture}", _node("sim_node", "-p", f"rig_file:={{{fixture}}}"),
                   stderr_has=has)]
        if fixture != "rig_kt_tiny":
            continue
        c += [
              Case(f"worm_calc --rig {fixture}", ["worm_calc", "--rig", "{" + fixture + "}", "--mu", "0.05"],
                   stderr_has=has),
              Case(f"residuals --rig {fixture}", ["residuals", "{csv}", "--rig", "{" + fixture + "}", "--out",
                                                     "res"], stderr_has=has),
              Case(f"identify --rig {fixture}", ["identify", "--rig", "{" + fixture + "}", "--from", "{csv}",
                                                    "--out", "x.yaml"], stderr_has=has),
              Case(f"virtual_rig --rig {fixture}", ["virtual_rig", "--rig", "{" + fixture + "}", "--duration", "1"],
                   stderr_has=has),
              Case(f"bag import --rig {fixture}", ["bag", "import", "{csv}", "--rig", "{" + fixture + "}", "--out",
                                                   "nb"], stderr_has=has)]
    c += [Case("worm_calc 10x more power out than in", ["worm_calc", "--tau-in", "0.001", "--tau-load", "0.3",
                                                        "--omega", "150"], stderr_has="more out than in"),
          Case("worm_calc mu < 0 without a speed", ["worm_calc", "--tau-in", "0.001", "--tau-load", "0.3", "--json"],
               stderr_has="mu"),
          Case("worm_calc the gear putting in less than the worm takes", ["worm_calc", "--tau-in", "-0.02",
               "--tau-load", "-0.3", "--omega", "150"], stderr_has="more out than in"),
          Case("worm_calc a real operating point", ["worm_calc", "--tau-in", "0.02", "--tau-load", "0.3", "--omega",
                                                    "150"], expect=0, stdout_has="resistive"),
          Case("replay a bag whose stamps are milliseconds", ["replay", "{bag_ms}", "--estimators", "observer",
                                                              "--quiet"], stderr_has="milliseconds")]
    for case in c:
        case.name = f"units: {case.name}"
    return c


def parameter_cases() -> list[Case]:
    """Parameters no node declares, files a node cannot use, run_graph checking before it starts anything."""
    c = [
        Case("sim_node -p sampel_rate:=1000", _node("sim_node", "-p", "sampel_rate:=1000"),
             stderr_has="sampel_rate"),
        Case("estimator_node -p methd:=knn", _node("estimator_node", "-p", "methd:=knn"), stderr_has="'method'"),
        Case("estimator_node --params-file with methd:", _node("estimator_node", "--params-file", "{graph_typo}"),
             stderr_has="'method'"),
        Case("model_node -p use_acceleraton:=true", _node("model_node", "-p", "use_acceleraton:=true"),
             stderr_has="'use_acceleration'"),
        Case("controller_node -p kpp:=0.001", _node("controller_node", "-p", "kpp:=0.001"), stderr_has="kpp"),
        Case("recorder -p topic:=[/rig/samples]", _node("recorder", "-p", "topic:=[/rig/samples]"),
             stderr_has="'topics'"),
        Case("driver_node -p max_drive_volts:=5.0", _node("driver_node", "-p", "max_drive_volts:=5.0"),
             stderr_has="max_drive_volts"),
        Case("run_graph --set estimator_node.k=abc", ["run_graph", "{graph}", "--set", "estimator_node.k=abc"],
             stderr_has="estimator_node.k"),
        Case("run_graph --set sim_node.sampel_rate=1000", ["run_graph", "{graph}", "--set",
             "sim_node.sampel_rate=1000"], stderr_has="sampel_rate"),
        Case("run_graph --set estimator_node.method=kalman", ["run_graph", "{graph}", "--set",
             "estimator_node.method=kalman"], stderr_has="kalman"),
        Case("run_graph a graph file with methd:", ["run_graph", "{graph_typo}"], stderr_has="'method'"),
        Case("run_graph a node that does not exist (none started)", ["run_graph", "{graph_unknown_node}"],
             stderr_has="no_such_node"),
        Case("demo --graph a graph file with methd:", ["demo", "--graph", "{graph_typo}", "--out", "d"],
             stderr_has="'method'"),
        Case("replay --params-file with methd:", ["replay", "{bag}", "--params-file", "{graph_typo}"],
             stderr_has="'method'"),
        Case("estimate --params-file with methd:", ["estimate", "{csv}", "--method", "observer", "--params-file",
             "{graph_typo}", "--out", "e.csv"], stderr_has="'method'"),
        Case("estimator_node a missing calibration_file", _node("estimator_node", "-p", "method:=knn", "-p",
             "calibration_file:=/nonexistent/cal.json"), stderr_has="cal.json"),
        Case("estimator_node a missing model_file", _node("estimator_node", "-p", "method:=observer", "-p",
             "model_file:=/nonexistent/model.yaml"), stderr_has="model.yaml"),
        Case("estimator_node a binary rig_file", _node("estimator_node", "-p", "rig_file:={binary}")),
        Case("sim_node a missing effects_file", _node("sim_node", "-p", "effects_file:=/nonexistent/e.yaml"),
             stderr_has="e.yaml"),
        Case("recorder an invalid topic name", _node("recorder", "-p", "topics:=['bad topic']", "-p", "output:=b"),
             stderr_has="bad topic"),
        Case("recorder an invalid excluded topic", _node("recorder", "-p", "exclude:=['/ok', '1bad']", "-p",
             "output:=b"), stderr_has="1bad"),
        Case("recorder an unknown storage", _node("recorder", "-p", "storage:=nosuch", "-p", "output:=b"),
             stderr_has="storage"),
        Case("estimator_node an invalid topic name",
             _node("estimator_node", "-p", "input:=joint_state", "-p", "joint_names:=[elbow]", "-p",
                   "joint_state_topic:=bad topic"),
             stderr_has="bad topic"),
        Case("controller_node an invalid topic name", _node("controller_node", "-p", "feedforward_topic:=1bad"),
             stderr_has="1bad"),
        Case("calibrate --speed-min 0", ["calibrate", "--out", "c.json", "--speed-min", "0"], stderr_has="> 0"),
        Case("replay a CSV", ["replay", "{csv}"], stderr_has="estimate"),
    ]
    for case in c:
        case.name = f"params: {case.name}"
    return c


def interrupt_cases() -> list[Case]:
    """Ctrl-C in the middle of long runs: they end promptly, leaving what they document and nothing else."""
    c = [
        Case("residuals while analysing", ["residuals", "{csv}", "--out", "res", "--quiet"], expect=130,
             interrupt_when=".res.*.tmp", timeout=90),
        Case("evaluate while evaluating", ["evaluate", "--out", "ev", "--quiet", "--no-residuals"], expect=130,
             interrupt_when=".ev.*.tmp", timeout=90),
        Case("demo while calibrating", ["demo", "--out", "d"], expect=130, interrupt_when=".d.*.tmp", timeout=90),
        Case("calibrate (the journal is kept)", ["calibrate", "--out", "c.json", "--quiet"], expect=130,
             interrupt_when="c.json.partial", may_leave=("c.json.partial",), timeout=90),
        Case("run_graph", ["run_graph", "{graph}", "--log-dir", "logs"], expect=0, interrupt_when="logs/*.log",
             interrupt_after=3.0, may_leave=("logs", "logs/*"), timeout=90),
        Case("sim_node", _node("sim_node"), expect=(0, 130), interrupt_after=3.0, timeout=60),
        Case("virtual_rig", ["virtual_rig", "--link", "link"], expect=0, interrupt_when="link", timeout=60),
        Case("recorder", _node("recorder", "-p", "output:=b"), expect=(0, 130), interrupt_when="b/*.mcap",
             interrupt_after=2.0, may_leave=("b", "b/*"), timeout=60),
    ]
    for case in c:
        case.name = f"ctrl-c: {case.name}"
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
    put("effects_gain.yaml", "format: worm_rig_effects\nversion: 1\neffects:\n  speed_dependent_mu:\n"
                             "    low_speed_gain: 1e6\n")
    put("effects_user.yaml", "# my effects, edited by hand\nformat: worm_rig_effects\nversion: 1\neffects: {}\n")
    _policy_fixtures(folder, f, data, doc, put)
    return f


def _bomb(levels: int = 9) -> str:
    """A 'billion laughs' YAML fragment: ``levels`` anchors of 10 aliases each (10^levels values)."""
    lines = ["  l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    lines += [f"  l{k}: &l{k} [{', '.join([f'*l{k - 1}'] * 10)}]" for k in range(1, levels)]
    return "\n".join(lines) + "\n"


def _policy_fixtures(folder: Path, f: dict[str, Path], data, cal_doc: dict, put) -> None:
    """The files of the careless-user cases: wrong units, BOMs, bombs, rcl-unreadable graph files, outputs."""
    import numpy as np

    from worm_model.physics.parameters import default_rig_path
    from worm_model.rig_data.bags import csv_to_bag, measured_to_bag
    from worm_model.rig_data.schema import MeasuredData, write_rig_csv
    from worm_rig_driver.sim.effects import template
    from torque_estimator.graph.runner import default_graph_file

    def log(name: str, **changes) -> None:
        columns = {k: getattr(data, k).copy() for k in data.names}
        columns.update(changes)
        write_rig_csv(folder / f"{name}.csv", MeasuredData(**columns))
        f[name] = folder / f"{name}.csv"

    log("csv_ms", t=data.t * 1e3)
    log("csv_us", t=data.t * 1e6)
    log("csv_mA", current_drive=data.current_drive * 1e3)
    log("csv_deg", theta_worm=np.degrees(data.theta_worm))
    log("csv_rpm", omega_worm=data.omega_worm * 60 / (2 * math.pi))
    slow = data.omega_worm * 20 / 150  # 20 rad/s: 191 rpm is inside the rig's no-load speed; the angle says it
    log("csv_rpm_slow", omega_worm=slow * 60 / (2 * math.pi), theta_worm=np.cumsum(slow) * 1e-3)
    write_rig_csv(folder / "csv_one_row.csv", data.subset(np.arange(1)))
    f["csv_one_row"] = folder / "csv_one_row.csv"
    put("csv_bom.csv", b"\xef\xbb\xbf" + (folder / "run.csv").read_bytes())
    (mcap,) = (folder / "bag").glob("*.mcap")
    f["mcap"] = mcap
    ms = MeasuredData(**{**{k: getattr(data, k) for k in data.names}, "t": data.t * 1e3})
    measured_to_bag(ms, folder / "bag_ms")
    f["bag_ms"] = folder / "bag_ms"
    shutil.copytree(folder / "bag", folder / "bag_meta_bomb")
    meta = folder / "bag_meta_bomb" / "metadata.yaml"
    meta.write_text(meta.read_text() + "bomb:\n" + _bomb())
    f["bag_meta_bomb"] = folder / "bag_meta_bomb"
    csv_to_bag(folder / "run.csv", folder / "imported_bag")  # a bag `bag import` wrote (its marker inside)
    f["imported_bag"] = folder / "imported_bag"

    def calibration(name: str, **columns) -> None:
        doc = json.loads(json.dumps(cal_doc))
        for column, transform in columns.items():
            doc["points"][column] = [transform(v) for v in doc["points"][column]]
        put(f"{name}.json", json.dumps(doc))

    calibration("cal_zero_range", tau_load=lambda v: 0.1)
    first = {c: cal_doc["points"][c][0] for c in ("omega_worm", "current_drive", "tau_load")}
    calibration("cal_identical", **{c: (lambda v, x=x: x) for c, x in first.items()})
    calibration("cal_rpm", omega_worm=lambda v: v * 60 / (2 * math.pi))
    calibration("cal_flipped", tau_load=lambda v: -v)  # a load cell wired the other way
    put("cal_bom.json", b"\xef\xbb\xbf" + (folder / "cal.json").read_bytes())
    put("json_deep.json", "[" * 100_000 + "]" * 100_000)

    rig_text = default_rig_path().read_text(encoding="utf-8")
    f["rig"] = default_rig_path()
    put("rig_bom.yaml", b"\xef\xbb\xbf" + rig_text.encode())
    put("rig_kt_tiny.yaml",
        rig_text.replace("    value: 0.055\n    unit: N m/A", "    value: 1e-12\n    unit: N m/A", 1))
    put("rig_1MV.yaml", rig_text.replace("supply_voltage:\n  value: 24", "supply_voltage:\n  value: 1000000", 1))
    put("rig_lead_rad.yaml",
        rig_text.replace("    value: 5.710593\n    unit: deg", "    value: 0.0996687\n    unit: deg"))
    put("rig_bomb.yaml", rig_text + "free:\n" + _bomb())
    put("effects_bomb.yaml", "format: worm_rig_effects\nversion: 1\neffects: {}\nbomb:\n" + _bomb())
    put("yaml_deep.yaml", "a: " + "[" * 5000 + "]" * 5000 + "\n")
    put("effects_template.yaml", template())

    # the shipped graph with an estimator_node beside the rig's own estimator, as a user adds one
    graph = (default_graph_file().read_text(encoding="utf-8")
             .replace("    publish_estimate: true", "    publish_estimate: false")
             + "estimator_node:\n  ros__parameters:\n    method: observer\n")
    put("graph.yaml", graph)
    put("graph_bom.yaml", b"\xef\xbb\xbf" + graph.encode())
    put("graph_anchor.yaml",
        graph.replace("estimator_node:\n  ros__parameters:", "estimator_node:\n  ros__parameters: &est", 1)
        + "other_estimator:\n  ros__parameters: *est\n")
    put("graph_merge.yaml",
        graph.replace("estimator_node:\n  ros__parameters:", "estimator_node:\n  ros__parameters: &est", 1)
        + "other_estimator:\n  ros__parameters:\n    <<: *est\n    k: 8\n")
    put("graph_typo.yaml", graph.replace("    method: observer", "    methd: observer", 1))
    put("graph_not_yaml.yaml", "estimator_node: {ros__parameters: {k: 4}\nmodel_node: [\n")
    put("graph_mixed.yaml", "estimator_node:\n  ros__parameters:\n    k: 4\n    exclude: [1, two]\n")
    put("graph_value_beside.yaml", "estimator_node:\n  k: 4\n  ros__parameters:\n    method: knn\n")
    put("graph_bomb.yaml", graph + "bomb:\n" + _bomb())
    f["symlink_loop"] = folder / "text.txt"  # made per case as a link to itself (run_case)
    put("graph_unknown_node.yaml", graph + "no_such_node:\n  ros__parameters: {a: 1}\n")

    # earlier outputs of the tools themselves, which --force may replace
    report_out = folder / "report_out"
    report_out.mkdir()
    (report_out / ".written-by").write_text("report\n")
    (report_out / "fig06_normal_force.png").write_bytes(b"\x89PNG earlier")
    f["report_out"] = report_out
    unmarked = folder / "report_out_unmarked"
    unmarked.mkdir()
    (unmarked / "fig06_normal_force.png").write_bytes(b"\x89PNG earlier")
    f["report_out_unmarked"] = unmarked
    put("estimate_out.csv", "t,current_drive,omega_worm,theta_worm,tau_load,tau_estimate,tau_estimate_uncertainty,"
                            "estimate_flags\n0.0,0.1,150.0,0.0,0.1,0.1,0.01,0\n")



# --- running -----------------------------------------------------------------------------------------

def _digest(path: Path) -> str:
    if path.is_symlink() and not path.exists():
        return "dangling link"
    if path.is_dir():
        return ";".join(f"{p.relative_to(path)}={_digest(p)}" for p in sorted(path.rglob("*")) if p.is_file())
    if not path.exists():
        return "absent"
    if not path.is_file():
        return "not a regular file"  # a FIFO: reading it would wait
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _executable(name: str) -> str:
    from worm_model.ros.ament import find_executable
    return str(find_executable(name))


def _matches(rel: str, patterns: tuple[str, ...]) -> bool:
    return any(fnmatch.fnmatch(rel, p) for p in patterns)


def _left_running(session: int) -> list[str]:
    """Command lines of the processes still in ``session`` (the case's: every child it started)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[3]) == session:  # the session id, after state, ppid, pgrp
                found.append((stat.parent / "cmdline").read_bytes().replace(b"\0", b" ").decode().strip())
        except (OSError, ValueError, IndexError):
            continue
    return found


def _interrupt(process: subprocess.Popen, case: Case, folder: Path, deadline: float) -> None:
    """SIGINT to the run's process group (as a terminal's Ctrl-C) once ``case.interrupt_when`` matches in
    ``folder`` and ``case.interrupt_after`` seconds have passed, unless it ended before."""
    start = time.monotonic()
    while process.poll() is None and time.monotonic() < deadline:
        ready = not case.interrupt_when or any(folder.glob(case.interrupt_when))
        if ready and time.monotonic() - start >= case.interrupt_after:
            os.killpg(process.pid, signal.SIGINT)
            return
        time.sleep(0.05)


def run_case(case: Case, fixtures: dict[str, Path], work: Path, timeout: float) -> tuple[str, str]:
    """(verdict, detail) of one case, run in its own folder under ``work``."""
    folder = Path(tempfile.mkdtemp(prefix="case_", dir=work))
    for rel, fixture in case.user_files.items():
        target = folder / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        if fixture == "symlink_loop":
            os.symlink(target.name, target)
        elif fixtures[fixture].is_dir():
            shutil.copytree(fixtures[fixture], target)
        else:
            shutil.copy(fixtures[fixture], target)
    for name in case.fifos:
        os.mkfifo(folder / name)
    cwd = folder / case.cwd
    cwd.mkdir(parents=True, exist_ok=True)
    names = {**{k: str(v) for k, v in fixtures.items()}, "case": str(folder)}
    argv = [_executable(case.argv[0])] + [a.format(**names) for a in case.argv[1:]]
    inputs = {name: _digest(path) for name, path in fixtures.items()}
    users = {rel: _digest(folder / rel) for rel in case.user_files}
    before = _listing(folder)
    env = {**os.environ, "ROS_DOMAIN_ID": str(random.randint(100, 230)),
           "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    if case.home:
        env["HOME"] = str(folder / case.home)
    limit = case.timeout or timeout
    process = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               stdin=subprocess.DEVNULL, start_new_session=True)
    if case.interrupt_when or case.interrupt_after:
        threading.Thread(target=_interrupt, args=(process, case, folder, time.monotonic() + limit),
                         daemon=True).start()
    try:
        out, err = process.communicate(timeout=limit)
        hung = False
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        out, err = process.communicate()
        hung = True
    stray = _left_running(process.pid)
    if stray:  # a node a refused run started and never stopped: stop it, and say so below
        os.killpg(process.pid, signal.SIGKILL)
    out_text, err_text = out.decode(errors="replace"), err.decode(errors="replace")
    lines = [line for line in err_text.splitlines() if line.strip()]
    changed = [name for name, digest in inputs.items() if _digest(fixtures[name]) != digest]
    changed += [rel for rel, digest in users.items()
                if _digest(folder / rel) != digest and not _matches(rel, case.may_leave)]
    left = sorted(rel for rel in _listing(folder) - before if not _matches(rel, case.may_leave))
    first = lines[0] if lines else "(nothing on stderr)"
    expected = case.expect if isinstance(case.expect, tuple) else (case.expect,)
    if hung:
        return "hang", f"still running after {limit:g} s"
    if "Traceback (most recent call last)" in out_text + err_text or "internal error" in err_text:
        tail = [line for line in (err_text or out_text).splitlines() if line.strip()][-1:]
        return "traceback", tail[0] if tail else ""
    if changed:
        return "lost", f"changed: {', '.join(changed)}"
    if process.returncode not in expected:
        if process.returncode == 0:
            return "silent", f"exit 0; stdout: {out_text.strip().splitlines()[-1:] or ''}"
        return "message", f"exit {process.returncode}, expected {case.expect}: {first}"
    if stray:
        return "leftover", f"left running: {stray[0][:120]}"
    if left:
        return "leftover", ", ".join(left)
    if 2 not in expected:  # a run that must work, or end cleanly on Ctrl-C
        if case.stdout_has and case.stdout_has not in out_text:
            return "message", f"stdout lacks {case.stdout_has!r}"
        return "ok", (out_text.strip().splitlines() or [""])[0] if 0 in expected else f"exit {process.returncode}"
    tool = case.argv[0] + (f" {case.argv[1]}" if case.argv[0] == "bag" else "")  # bag's subcommands
    if len(lines) != 1 or not lines[0].startswith(f"{tool}:") or lines[0].count(":") < 2:
        return "message", f"{len(lines)} stderr line(s): {' | '.join(lines[:3])}"
    if case.stderr_has not in lines[0]:
        return "message", f"does not name {case.stderr_has!r}: {lines[0]}"
    return "ok", lines[0]


def _timed(case: Case, fixtures: dict[str, Path], work: Path, timeout: float) -> tuple[str, str, float]:
    start = time.monotonic()
    return (*run_case(case, fixtures, work, timeout), time.monotonic() - start)


def probe(selected: list[Case], jobs: int = 2, timeout: float = 30.0, verbose: bool = True
          ) -> dict[str, list[tuple[str, str]]]:
    """Run the cases; returns verdict -> [(case name, detail)]."""
    restore_ctrl_c()  # the ctrl-c cases run as under a terminal, even if the probe runs in the background
    work = Path(tempfile.mkdtemp(prefix="probe_bad_input_"))
    try:
        fixtures = build_fixtures(work / "fixtures")
        results: dict[str, list[tuple[str, str]]] = {v: [] for v in VERDICTS}
        with ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = [(case, pool.submit(_timed, case, fixtures, work, timeout)) for case in selected]
            for case, future in futures:
                verdict, detail, seconds = future.result()
                results[verdict].append((case.name, detail))
                if verbose:
                    print(f"{verdict:<9} {case.name} [{seconds:.1f} s]: {detail}", flush=True)
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
