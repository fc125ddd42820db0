"""Property-based: every executable refuses bad options and damaged files the same way.

For each executable, hypothesis generates bad option values (non-finite, out of the physical
range, not numbers) and damaged input files (binary, cut short, duplicate keys, values far
beyond the rig), and every run must end with: exit code 2, exactly one stderr line
``tool: where: what`` naming the problem, no traceback, nothing left behind in the working
folder, and the inputs untouched.

The command-line tools run in this process (their ``main(argv)``, as the console scripts call
it), so an example costs milliseconds; only the nodes' bad parameters need a process each
(rclpy reads them), and get few examples. tools/probe_bad_input.py runs issue 17's cases
against the installed executables (tests/test_bad_input_probe.py).
"""
from __future__ import annotations

import hashlib
import json
import math
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from worm_model.cli.options import check_number
from worm_model.ros.ament import find_executable

from in_process import run_main

EXAMPLES = settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
FEW = settings(max_examples=3, deadline=None, suppress_health_check=list(HealthCheck))


# --- what a refusal must look like --------------------------------------------------------------------

def _digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(folder.rglob("*"))}


def assert_refused(tool: str, code: int, err: str, before: dict[str, str], folder: Path, names: str = "") -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err, err
    assert code == 2, f"exit {code}: {err}"
    assert len(lines) == 1 and lines[0].startswith(f"{tool}:") and lines[0].count(":") >= 2, lines
    if names:
        assert names in lines[0], lines[0]
    assert _digest(folder) == before, "a file was left behind or an input was changed"


def refuse(tool: str, main: Callable[[list[str]], int], argv: Sequence[str], folder: Path, names: str = "") -> None:
    """Run and check one refusal in ``folder`` (inputs live there too, so they are checked untouched)."""
    before = _digest(folder)
    code, _out, err = run_main(main, argv, folder)
    assert_refused(tool, code, err, before, folder, names)


# --- what is bad ---------------------------------------------------------------------------------------

def outside(low: float | None, high: float | None) -> st.SearchStrategy[str]:
    """Option text that is no finite number inside [low, high]."""
    numbers = st.floats(allow_nan=True, allow_infinity=True).filter(
        lambda x: not math.isfinite(x) or (low is not None and x < low) or (high is not None and x > high))
    words = st.sampled_from(["nan", "inf", "-inf", "1e309", "abc", "", "0x10", "1,5", "--"])
    return st.one_of(numbers.map(repr), words)


def damaged_text(good: bytes, cut: bool = False) -> st.SearchStrategy[bytes]:
    """A good text file with a non-UTF-8 byte put in, or binary noise; with ``cut``, also cut short
    (only for formats a cut always breaks: JSON, MCAP)."""
    flipped = st.integers(0, max(0, len(good) - 1)).map(lambda i: good[:i] + b"\xff" + good[i + 1:])
    noise = st.binary(min_size=0, max_size=256).map(lambda b: b"\x80" + b)
    cuts = st.integers(0, max(0, len(good) - 3)).map(lambda n: good[:n])
    return st.one_of(flipped, noise, cuts) if cut else st.one_of(flipped, noise)


def damaged_csv(good: bytes) -> st.SearchStrategy[bytes]:
    """Rig data with one bad row: a word, a non-finite value or 1e300 in a required column, or a cell too many."""
    rows = good.decode().splitlines()

    def spoil(row: int, column: int, bad: str) -> bytes:
        cells = rows[row].split(",")
        cells[column] = bad if bad != "extra" else cells[column] + ",1"
        return "\n".join([*rows[:row], ",".join(cells), *rows[row + 1:]]).encode() + b"\n"
    return st.one_of(damaged_text(good),
                     st.builds(spoil, st.integers(1, len(rows) - 1), st.integers(1, 4),
                               st.sampled_from(["abc", "nan", "inf", "1e300", "-1e300", "extra", ""])))


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """Good input files, as bytes: a small calibration, rig data CSV, a bag file, an effects file."""
    import numpy as np

    from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
    from torque_estimator.estimation.database import save_database
    from worm_model.physics.parameters import default_rig_path, load_rig
    from worm_model.rig_data.bags import measured_to_bag
    from worm_model.rig_data.schema import MeasuredData, write_rig_csv

    folder = tmp_path_factory.mktemp("inputs")
    rig = load_rig()
    save_database(calibrate_simulated(rig, CalibrationGrid.paper(rig, 2, 3)), folder / "cal.json")
    n = 600
    t = np.arange(n) * 1e-3
    data = MeasuredData(t=t, current_drive=np.full(n, 0.2), omega_worm=np.full(n, 150.0),
                        theta_worm=150.0 * t, tau_load=np.full(n, 0.1))
    write_rig_csv(folder / "run.csv", data)
    measured_to_bag(data, folder / "bag")
    (mcap,) = (folder / "bag").glob("*.mcap")
    return _Files({"cal.json": (folder / "cal.json").read_bytes(), "run.csv": (folder / "run.csv").read_bytes(),
            "run.mcap": mcap.read_bytes(), "rig.yaml": default_rig_path().read_bytes(),
            "effects.yaml": b"format: worm_rig_effects\nversion: 1\neffects:\n  viscous_drag: {}\n"})


class _Files(dict):
    """The good inputs; shown by name only when hypothesis reports a failing example."""

    def __repr__(self) -> str:
        return f"inputs({', '.join(self)})"


@pytest.fixture()
def work(tmp_path_factory: pytest.TempPathFactory) -> Callable[[dict[str, bytes]], Path]:
    """A fresh folder holding the given files (hypothesis reuses a fixture across examples: make one each)."""
    def make(files: dict[str, bytes]) -> Path:
        folder = tmp_path_factory.mktemp("case")
        for name, content in files.items():
            (folder / name).write_bytes(content)
        return folder
    return make


# --- the command-line tools -----------------------------------------------------------------------------

CALC_OPTIONS = {"--r-worm": (0.0, 10.0), "--lead-angle-deg": (0.0, 90.0), "--tau-in": (-1e6, 1e6),
                "--omega": (-1e5, 1e5), "--worm-inertia": (0.0, 1e4), "--mu": (0.0, 9.4)}


@EXAMPLES
@given(option=st.sampled_from(sorted(CALC_OPTIONS)), data=st.data())
def test_worm_calc(option: str, data: st.DataObject, work) -> None:
    from worm_model.calc.worm_calc import main
    value = data.draw(outside(*CALC_OPTIONS[option]))
    base = ["--mu", "0.05"] if option in ("--r-worm", "--lead-angle-deg", "--mu") else ["--tau-in", "0.1",
                                                                                      "--tau-load", "0.2"]
    if option == "--mu":
        base = []
    refuse("worm_calc", main, [*base, f"{option}={value}"], work({}))


@EXAMPLES
@given(damage=st.data())
def test_report_damaged_calibration(damage: st.DataObject, inputs, work) -> None:
    from worm_model.figures.report import main
    folder = work({"cal.json": damage.draw(damaged_text(inputs["cal.json"], cut=True))})
    refuse("report", main, ["cal.json", "--out", "figs"], folder)


@EXAMPLES
@given(option=st.sampled_from(["--holdout-fraction", "--block", "--min-speed", "--min-improvement",
                               "--alpha-filter", "--confidence", "--max-effects"]), data=st.data())
def test_residuals_bad_options(option: str, data: st.DataObject, inputs, work) -> None:
    from worm_model.residuals.cli import main
    ranges = {"--holdout-fraction": (0, 1), "--block": (0, 3600), "--min-speed": (0, 1e4),
              "--min-improvement": (0, 1), "--alpha-filter": (0, 10), "--confidence": (0, 1),
              "--max-effects": (0, 13)}
    value = data.draw(outside(*ranges[option]))
    refuse("residuals", main, ["run.csv", "--out", "res", "--quiet", f"{option}={value}"],
           work({"run.csv": inputs["run.csv"]}), names=option)


@EXAMPLES
@given(data=st.data())
def test_residuals_damaged_data(data: st.DataObject, inputs, work) -> None:
    from worm_model.residuals.cli import main
    folder = work({"run.csv": data.draw(damaged_csv(inputs["run.csv"]))})
    refuse("residuals", main, ["run.csv", "--out", "res", "--quiet"], folder)


@EXAMPLES
@given(option=st.sampled_from(["--settle-time", "--timeout", "--window", "--speed-max", "--seed",
                               "--speeds", "--torque-fraction"]), data=st.data())
def test_calibrate_bad_options(option: str, data: st.DataObject, work) -> None:
    from torque_estimator.calibration.calibrate import main
    ranges = {"--settle-time": (0, 600), "--timeout": (0, 600), "--window": (0, 600), "--speed-max": (20, 436.4),
              "--seed": (0, 2**63 - 1), "--speeds": (1, 200), "--torque-fraction": (0, 1)}
    value = data.draw(outside(*ranges[option]))
    refuse("calibrate", main, ["--out", "cal.json", "--quiet", f"{option}={value}"], work({}))


def test_calibrate_never_replaces_a_file_and_refuses_a_bad_journal(inputs, work) -> None:
    from torque_estimator.calibration.calibrate import main
    refuse("calibrate", main, ["--out", "cal.json", "--quiet", "--speeds", "1", "--torques", "2"],
           work({"cal.json": inputs["cal.json"]}), names="--force")
    journal = {"format": "worm_torque_calibration_journal", "version": 1, "started": "2024-01-01T00:00:00+00:00",
               "settings": {}, "points": {"plan_index": [0], **{c: [None] for c in (
                   "omega_worm", "omega_std", "current_drive", "current_std", "tau_load", "tau_std", "samples",
                   "settled")}}}
    refuse("calibrate", main, ["--out", "new.json", "--quiet", "--speeds", "1", "--torques", "2", "--resume"],
           work({"new.json.partial": json.dumps(journal).encode()}), names="--drop-bad-points")


@EXAMPLES
@given(data=st.data())
def test_evaluate_damaged_calibration(data: st.DataObject, inputs, work) -> None:
    from torque_estimator.evaluation.evaluate import main
    good = json.loads(inputs["cal.json"])
    huge = data.draw(st.sampled_from(["omega_worm", "current_drive", "tau_load"]))
    good["points"][huge][data.draw(st.integers(0, len(good["points"][huge]) - 1))] = data.draw(
        st.sampled_from([1e300, -1e300, 1e6, -5e4]))
    content = data.draw(st.one_of(damaged_text(inputs["cal.json"], cut=True), st.just(json.dumps(good).encode())))
    refuse("evaluate", main, ["--calibration", "cal.json", "--out", "ev", "--no-sweeps", "--no-transient",
                              "--quiet"], work({"cal.json": content}))


@EXAMPLES
@given(data=st.data())
def test_bag_damaged_files(data: st.DataObject, inputs, work) -> None:
    from worm_rig_driver.recording.bag_cli import main
    command = data.draw(st.sampled_from(["echo", "export", "import"]))
    if command == "import":
        folder = work({"run.csv": data.draw(damaged_csv(inputs["run.csv"]))})
        argv = ["import", "run.csv", "--out", "newbag"]
    else:
        raw = inputs["run.mcap"]
        cut = data.draw(st.integers(16, len(raw) // 2))  # inside the one chunk of messages
        folder = work({"run.mcap": raw[:cut]})
        argv = ["echo", "run.mcap", "/rig/sample"] if command == "echo" else ["export", "run.mcap", "--out", "x.csv"]
    before = _digest(folder)
    code, _out, err = run_main(main, argv, folder)
    assert_refused(f"bag {command}", code, err, before, folder)


@EXAMPLES
@given(start=outside(0, 2**31 - 1))
def test_bag_import_bad_start(start: str, inputs, work) -> None:
    from worm_rig_driver.recording.bag_cli import main
    refuse("bag import", main, ["import", "run.csv", "--out", "newbag", f"--start={start}"],
           work({"run.csv": inputs["run.csv"]}), names="--start")


@EXAMPLES
@given(data=st.data())
def test_worm_effects_damaged_files(data: st.DataObject, inputs, work) -> None:
    from worm_rig_driver.sim.effects import main
    kind = data.draw(st.sampled_from(["damaged", "duplicate", "huge"]))
    if kind == "damaged":
        content = data.draw(damaged_text(inputs["effects.yaml"]))
    elif kind == "duplicate":
        content = inputs["effects.yaml"] + b"  viscous_drag: {enabled: false}\n"
    else:
        value = data.draw(st.sampled_from(["1e300", "-1e300", "1e9", ".inf", ".nan"]))
        content = b"format: worm_rig_effects\nversion: 1\neffects:\n  bearing_coulomb:\n    worm_torque: " \
                  + value.encode() + b"\n"
    refuse("worm_effects", main, ["--check", "effects.yaml"], work({"effects.yaml": content}))


def test_worm_effects_template_never_replaces_a_file(work) -> None:
    from worm_rig_driver.sim.effects import main
    refuse("worm_effects", main, ["--template", "mine.yaml"], work({"mine.yaml": b"# edited by hand\n"}),
           names="--force")


@EXAMPLES
@given(data=st.data())
def test_virtual_rig_bad_options(data: st.DataObject, work) -> None:
    from worm_rig_driver.sim.virtual_rig import main
    option = data.draw(st.sampled_from(["--duration", "--seed", "--substeps", "--link"]))
    value = {"--duration": outside(0, 1e7), "--seed": outside(0, 2**32 - 1), "--substeps": outside(1, 1000),
             "--link": st.just("/nonexistent/dir/link")}[option]
    refuse("virtual_rig", main, [f"{option}={data.draw(value)}"], work({}), names=option)


@EXAMPLES
@given(data=st.data())
def test_run_graph_damaged_files(data: st.DataObject, inputs, work) -> None:
    from torque_estimator.graph.run_graph import main
    from torque_estimator.graph.runner import default_graph_file
    good = default_graph_file().read_bytes()
    content = data.draw(st.one_of(damaged_text(good), st.just(good + b"\nmodel_node:\n  ros__parameters: {}\n")))
    refuse("run_graph", main, ["graph.yaml"], work({"graph.yaml": content}))


@settings(max_examples=8, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_replay_bad_input(data: st.DataObject, inputs, work) -> None:
    from torque_estimator.offline.replay import main
    kind = data.draw(st.sampled_from(["set", "warmup", "bag"]))
    files = {"cal.json": inputs["cal.json"], "run.mcap": inputs["run.mcap"]}
    argv = ["run.mcap", "--set", "estimator_node.calibration_file=cal.json", "--quiet", "--estimators", "knn"]
    if kind == "set":
        name = data.draw(st.sampled_from(["nosuch", "k", "method", "use_acceleration"]))
        node = "model_node" if name == "use_acceleration" else "estimator_node"
        value = {"nosuch": "1", "k": "abc", "method": "3", "use_acceleration": "1.5"}[name]
        argv += ["--set", f"{node}.{name}={value}"]
    elif kind == "warmup":
        argv += [f"--warmup={data.draw(outside(0, 1e6))}"]
    else:
        files["run.mcap"] = inputs["run.mcap"][: data.draw(st.integers(16, len(inputs["run.mcap"]) // 2))]
    refuse("replay", main, argv, work(files))


@EXAMPLES
@given(seed=outside(0, 2**32 - 2))
def test_demo_bad_options(seed: str, work) -> None:
    from torque_estimator.demo.demo import main
    refuse("demo", main, [f"--seed={seed}", "--out", "demo"], work({}), names="--seed")


# --- the nodes --------------------------------------------------------------------------------------------

NODES = {
    "sim_node": "worm_rig_driver.nodes.sim_node:SimNode",
    "model_node": "worm_model.nodes.model_node:ModelNode",
    "estimator_node": "torque_estimator.nodes.estimator_node:EstimatorNode",
    "controller_node": "torque_estimator.nodes.controller_node:ControllerNode",
    "driver_node": "worm_rig_driver.nodes.driver_node:DriverNode",
    "recorder": "worm_rig_driver.nodes.recorder_node:RecorderNode",
}


def _node_class(node: str):
    import importlib
    module, name = NODES[node].split(":")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize("node", sorted(NODES))
def test_node_help_lists_every_parameter_and_starts_nothing(node: str, work) -> None:
    import importlib
    from worm_model.ros.parameters import declared_parameters
    module = importlib.import_module(NODES[node].split(":")[0])
    folder = work({})
    code, out, err = run_main(lambda argv: module.main(argv), [node, "--help"], folder)
    assert code == 0 and "Traceback" not in err, err
    declared = declared_parameters(_node_class(node))
    assert declared, "no parameters recorded"
    for p in declared:
        assert f"  {p.name} (" in out, p.name
    assert _digest(folder) == {}, "help wrote a file"


REAL_PARAMETERS = """
import importlib, json, sys
import rclpy
module, name = sys.argv[1].split(":")
rclpy.init(args=["node", "--ros-args", *sys.argv[2:]])
node = getattr(importlib.import_module(module), name)()
print(json.dumps(sorted(node._parameters)))
node.destroy_node()
rclpy.try_shutdown()
"""


@pytest.mark.parametrize("node", sorted(NODES))
def test_help_knows_every_parameter_the_node_declares(node: str, ros_env, work) -> None:
    """What --help lists (and the check for undeclared parameters before a node starts uses) is every
    parameter the built node has, but rclpy's own: a name declared after the first call into rcl would
    otherwise be refused as undeclared."""
    import json
    from worm_model.ros.parameters import ROS_PARAMETERS, declared_parameters
    folder = work({})
    extra = {"driver_node": ["-p", "port:=/nonexistent/tty"], "recorder": ["-p", "output:=bag"]}.get(node, [])
    if node == "estimator_node":  # its default method (knn) does not start without a calibration
        from torque_estimator.calibration.batch import CalibrationGrid, calibrate_simulated
        from torque_estimator.estimation.database import save_database
        from worm_model.physics.parameters import load_rig
        rig = load_rig()
        save_database(calibrate_simulated(rig, CalibrationGrid.paper(rig, 3, 4), seed=0), folder / "cal.json")
        extra = ["-p", f"calibration_file:={folder / 'cal.json'}"]
    done = subprocess.run([sys.executable, "-c", REAL_PARAMETERS, NODES[node], *extra], cwd=folder, env=ros_env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    real = set(json.loads(done.stdout.strip().splitlines()[-1])) - ROS_PARAMETERS
    assert real == {p.name for p in declared_parameters(_node_class(node))}


def _bad_value(p) -> st.SearchStrategy[str]:
    if p.type in ("integer", "double") and p.range.startswith("["):
        low, high = (float(x) for x in p.range.split(";")[0].strip("[]").split(","))
        return st.one_of(st.sampled_from([str(int(low) - 1) if p.type == "integer" else repr(low - 1.0),
                                          str(int(high) + 1) if p.type == "integer" else repr(high * 2 + 1.0)]),
                         st.just("'text'"))
    return st.just("[1, 2]") if p.type != "bool" else st.just("'maybe'")


@pytest.mark.parametrize("node", sorted(NODES))
@FEW
@given(data=st.data())
def test_node_bad_parameter_is_one_line(node: str, data: st.DataObject, ros_env, work) -> None:
    from worm_model.ros.parameters import declared_parameters
    numeric = [p for p in declared_parameters(_node_class(node)) if p.type in ("integer", "double") and p.range]
    p = data.draw(st.sampled_from(numeric))
    value = data.draw(_bad_value(p))
    folder = work({})
    before = _digest(folder)
    extra = ["-p", "port:=/nonexistent/tty"] if node == "driver_node" else []
    done = subprocess.run([str(find_executable(node)), "--ros-args", "-p", f"{p.name}:={value}", *extra],
                          cwd=folder, env=ros_env, capture_output=True, text=True, timeout=60)
    assert_refused(node, done.returncode, done.stderr, before, folder, names=p.name)


def test_check_number_agrees_with_the_option_types() -> None:
    """Files and options share one check: the same values pass and fail with the same words."""
    from worm_model.errors import InputError
    from worm_model.cli.options import number
    import argparse
    for text in ("nan", "inf", "-1", "2", "abc"):
        try:
            check_number(text, "x", "s", 0, 1)
            file_ok = True
        except InputError:
            file_ok = False
        try:
            number("s", 0, 1)(text)
            option_ok = True
        except argparse.ArgumentTypeError:
            option_ok = False
        assert file_ok == option_ok, text


# --- one property per mechanism ----------------------------------------------------------------------------
#
# The tests above refuse bad values one option at a time; these hold the three policies as properties: any
# combination of inputs, output and --force loses no byte of an input; any unit slip of a valid log is
# refused; any YAML, however nested or aliased, ends in a result or one refusal, never a hang or a crash.

#: where a careless user might point --out, relative to the working folder ``work/sub``: the inputs
#: themselves, the folders holding them, a place inside the bag, nothing, here, above, the user's own files
TARGETS = ("../d/run.csv", "../d", "../d/bag", "../d/bag/x", "../d/bag/bag_0.mcap", "", ".", "..",
           "notes.txt", "mine", "new", "new.csv", "earlier")
WRITERS = {
    "bag export": (["export", "../d/bag"], "worm_rig_driver.recording.bag_cli"),
    "bag import": (["import", "../d/run.csv"], "worm_rig_driver.recording.bag_cli"),
    "estimate": (["../d/run.csv", "--method", "extended_model", "--quiet"], "torque_estimator.offline.estimate"),
    "worm_effects": ([], "worm_rig_driver.sim.effects"),
}


def _writer_main(tool: str):
    import importlib
    return importlib.import_module(WRITERS[tool][1]).main


def _user_folder(inputs, work) -> Path:
    """work/: d/run.csv and d/bag/ (the inputs), sub/ (the working folder) with the user's notes.txt and
    mine/thesis.tex."""
    from worm_model.rig_data.bags import measured_to_bag
    from worm_model.rig_data.schema import read_rig_csv
    folder = work({})
    (folder / "d").mkdir()
    (folder / "d" / "run.csv").write_bytes(inputs["run.csv"])
    measured_to_bag(read_rig_csv(folder / "d" / "run.csv"), folder / "d" / "bag")
    (folder / "sub" / "mine").mkdir(parents=True)
    (folder / "sub" / "notes.txt").write_text("my notes\n")
    (folder / "sub" / "mine" / "thesis.tex").write_text("years of work\n")
    return folder


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
@given(tool=st.sampled_from(sorted(WRITERS)), target=st.sampled_from(TARGETS), force=st.booleans(),
       earlier_force=st.booleans())
def test_no_combination_of_inputs_output_and_force_loses_a_byte(tool, target, force, earlier_force, inputs,
                                                                 work) -> None:
    """Whatever --out (or --template) names and whether --force is given, every input and every file the user
    made is byte for byte what it was; the run either writes its output or is refused in one line (exit 2);
    no temporary file is left. "earlier" is the tool's own output of a first run: --force may replace it."""
    folder = _user_folder(inputs, work)
    sub, main = folder / "sub", _writer_main(tool)
    option = "--template" if tool == "worm_effects" else "--out"
    base = WRITERS[tool][0]
    if target == "earlier":
        code, _out, err = run_main(main, [*base, option, "earlier"], sub)
        assert code == 0, err
    before = _digest(folder)
    argv = [*base, option, target, *(["--force"] if force else [])]
    code, _out, err = run_main(main, argv, sub)
    after = _digest(folder)
    output = (sub / target).resolve()
    for name, digest in before.items():
        path = (folder / name).resolve()
        if code == 0 and target == "earlier" and (path == output or output in path.parents):
            continue  # the tool's own earlier output, replaced with --force: the one thing that may change
        assert after.get(name) == digest, f"{name} changed or vanished: {tool} {argv}: {err}"
    assert "Traceback" not in err and code in (0, 2), (code, err)
    if code == 2:
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].count(":") >= 2, lines
    else:
        assert target not in ("", ".", "..") and (force or target != "earlier" or not earlier_force), argv
    assert not [n for n in after if n.rsplit("/", 1)[-1].endswith(".tmp")], sorted(after)


#: the unit slips a log gets: column -> (factor range [low, high] of detectable slips, what is named)
SLIPS = {  # (the angle check names theta_worm when t or the speed is off by a factor the envelope allows)
    "t": ((1.5, 1e9), ("t", "theta_worm")),  # ms, us, ns, or any step the angle cannot follow
    "current_drive": ((200.0, 1e6), ("current_drive",)),  # mA and beyond: past the stall current
    "omega_worm": ((1.5, 1e4), ("omega_worm", "theta_worm")),  # rpm, deg/s
    "theta_worm": ((1.5, 1e6), ("theta_worm",)),  # degrees, encoder counts
    "voltage_drive": ((5.0, 1e6), ("voltage_drive",)),  # mV
}


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(column=st.sampled_from(sorted(SLIPS)), exponent=st.floats(0.0, 1.0), smaller=st.booleans())
def test_every_unit_slip_of_a_valid_log_is_refused(column, exponent, smaller, tmp_path_factory) -> None:
    """A valid 1 kHz log with one column scaled by a factor a unit slip makes (log-uniform over the column's
    detectable range; for t and the angles also the inverse) is refused by the one rig-data reader, naming
    the column; the log itself passes."""
    import numpy as np

    from worm_model.rig_data.reader import read_rig_data
    from worm_model.rig_data.schema import MeasuredData, write_rig_csv
    from worm_model.errors import RigDataError

    (low, high), named = SLIPS[column]
    factor = low * (high / low) ** exponent
    if smaller and column in ("t", "theta_worm", "omega_worm"):
        factor = 1.0 / factor
    n = 2000
    t = np.arange(n) * 1e-3
    omega = 150.0 + 0.5 * np.sin(7 * t)
    columns = {"t": t, "current_drive": np.full(n, 0.2), "omega_worm": omega, "theta_worm": np.cumsum(omega) * 1e-3,
               "tau_load": np.full(n, 0.1), "voltage_drive": np.full(n, 12.0)}
    folder = tmp_path_factory.mktemp("slip")
    write_rig_csv(folder / "good.csv", MeasuredData(**columns))
    read_rig_data(folder / "good.csv")
    columns[column] = columns[column] * factor
    write_rig_csv(folder / "slip.csv", MeasuredData(**columns))
    with pytest.raises(RigDataError) as info:
        read_rig_data(folder / "slip.csv")
    assert any(f"column '{name}'" in str(info.value) for name in named), (column, factor, str(info.value))


def _yaml_texts() -> st.SearchStrategy[str]:
    """YAML a careless user or a corrupted file makes: random structures, deep nesting of random kinds, alias
    chains of random depth and fan-out, anchors and merge keys, the bundled rig with a subtree replaced."""
    import yaml

    from worm_model.physics.parameters import default_rig_path
    scalars = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True), st.text(max_size=8))
    trees = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                          st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                         max_leaves=30)
    plain = trees.map(lambda tree: yaml.safe_dump(tree))

    def nested(depth: int, kind: str) -> str:
        opening, closing = {"flow list": ("[", "]"), "flow map": ("{a: ", "}")}.get(kind, ("", ""))
        if kind == "block":
            return "".join("  " * k + "k:\n" for k in range(depth)) + "  " * depth + "v\n"
        return "a: " + opening * depth + "1" + closing * depth + "\n"

    deep = st.builds(nested, st.integers(1, 3000), st.sampled_from(["flow list", "flow map", "block"]))

    def chain(levels: int, fan_out: int, merge: bool) -> str:
        lines = ["l0: &l0 {a: 1, b: 2}" if merge else "l0: &l0 [x]"]
        for k in range(1, levels):
            lines.append(f"l{k}: &l{k} " + ("{<<: *l%d, c%d: 1}" % (k - 1, k) if merge else
                                             f"[{', '.join([f'*l{k - 1}'] * fan_out)}]"))
        return "\n".join(lines) + "\n"

    bombs = st.builds(chain, st.integers(1, 30), st.integers(1, 12), st.booleans())
    rig = default_rig_path().read_text(encoding="utf-8")
    spliced = st.builds(lambda key, text: rig.replace(f"\n{key}:", f"\n{key}: {text}\nold_{key}:", 1),
                        st.sampled_from(["gearbox", "friction", "sensors", "load_motor"]),
                        st.one_of(deep, bombs, plain).map(lambda t: "\n  " + t.replace("\n", "\n  ")))
    return st.one_of(plain, deep, bombs, spliced, st.binary(max_size=64).map(lambda b: b.decode("latin-1")))


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(text=_yaml_texts(), reader=st.sampled_from(["rig", "effects", "graph", "parameters"]))
def test_no_yaml_hangs_or_crashes_a_reader(text, reader, work) -> None:
    """Every YAML reader ends in a value or one refusal (the project's ValueError with the file named), never
    in a RecursionError, a MemoryError or an expansion that does not end; the tools alike (one line, exit 2)."""
    from torque_estimator.graph.run_graph import main as run_graph
    from worm_model.calc.worm_calc import main as worm_calc
    from worm_model.files.reading import load_parameter_file
    from worm_model.physics.parameters import load_rig
    from worm_rig_driver.sim.effects import load_effects, main as worm_effects

    folder = work({"f.yaml": text.encode("utf-8", errors="surrogateescape")})
    load = {"rig": load_rig, "effects": load_effects, "graph": load_parameter_file,
            "parameters": load_parameter_file}[reader]
    try:
        load(folder / "f.yaml")
    except ValueError as err:
        assert "f.yaml" in str(err), str(err)
    tool = {"rig": ("worm_calc", worm_calc, ["--rig", "f.yaml", "--mu", "0.05"]),
            "effects": ("worm_effects", worm_effects, ["--check", "f.yaml"]),
            "graph": ("run_graph", run_graph, ["f.yaml", "--set", "estimator_node.k=abc"]),
            "parameters": ("run_graph", run_graph, ["f.yaml", "--set", "nosuch_node.k=1"])}[reader]
    before = _digest(folder)
    code, _out, err = run_main(tool[1], tool[2], folder)
    if code != 0:
        assert_refused(tool[0], code, err, before, folder)
