"""Every file a tool writes, every tool reads: the round trip over the tools, on the bundled rigs and the T-RO rig.

The writers run once (one module-scoped fixture), as a user runs them: their installed executables.

* ``identify --from`` a 20 s excitation recorded on each bundled bench rig (nmrv030, nmrv030_i15, nmrv040; the
  simulated drive off its rig file by mu x1.3 and drags x2, as a datasheet's stand-ins are off), and on the T-RO
  drive's real EPOS exports (docs/real-data.md's load options);
* ``residuals`` on the nmrv030 recording and on the T-RO exports (its ``extended_rig.yaml``);
* ``rig_from_datasheet`` (the bundled drive template) with the T-RO drive's catalogue numbers and with foreign30's
  (evaluation.foreign: a drive the project did not make, simulated by a plant of its own equations), and
  ``identify`` on each of those two files (the T-RO exports; a recording of foreign30).

Each of those ten files is then read by every reader, with a log of its drive:

* ``estimate`` (extended_model, momentum, and the observer where the log has a voltage): exit 0, the estimate CSV
  written with estimates in it, some of extended_model's trusted (momentum and the observer read the file's rig, not
  its effects); ``worm_calc --rig``; ``health_check --dry-run`` on a run held at speeds and
  loads; ``residuals --rig`` and ``identify --rig`` (whose outputs must load again). These run as
  ``main(argv)`` in this process, as the console scripts call it: the same code, without a Python start for each of
  some sixty runs.
* The nodes, as processes: ``estimator_node`` with the file as its ``model_file`` (a plain rig file: ``rig_file``),
  method extended_model, one per file in a namespace of its own, fed a steady stream of rig samples at a load the
  file's own model gives the current for, must estimate that load; one ``estimator_node`` per other method
  (momentum, observer; the observer reads the voltage topics, which momentum ignores) with every file as a joint
  (``input: joint_state``) and one ``model_node`` with every file in its ``rig_files`` must come up; every node
  exits 0 on SIGINT.

The simulator (sim_node's plant) runs a datasheet rig file, and identify fits what it records. On the T-RO
exports a second residuals pass over its own output is refused (one line, exit 2: K_t would run from K_e).

The property (hypothesis) draws the corrections: any valid set (a subset of what identify fitted, each value inside
its tolerance band, else its physical range, else a factor 2 of the fitted value, its confidence interval finite or
not) written through identify's writer (identification.writing.write_identified) loads with load_rig to the drawn
values, is built by the estimators' one builder (estimation.settings.build_estimator) for every model-based method,
and the extended model built from the file inverts the drawn model's current at a load back to that load.

Bad priors and an identify run that can identify nothing: tests/test_prior_bad_input.py.
"""
from __future__ import annotations

import dataclasses
import math
import re
import shutil
import subprocess
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from worm_model.physics.parameters import load_rig
from worm_model.ros.ament import find_executable

from in_process import run_main

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "ros_ws" / "src" / "worm_model" / "worm_model" / "data"
TRO_RIG = DATA / "tro2021_worm_rig.yaml"
TRO_EXPORTS = DATA / "tro2021" / "driveNo3" / "steady_state" / "0.096kg"
#: the load the T-RO exports do not carry (docs/real-data.md): 0.096 kg on a 20 mm pulley, their gravity
TRO_LOAD = ("--load-mass", "0.096", "--pulley-radius", "0.02", "--gravity", "9.812", "--skip-bad-rows")
#: the T-RO exports estimate reads: three clean speeds each way (the whole folder: 23000 samples)
TRO_SHORT = ("4", "20", "100", "n4", "n20", "n100")
#: the T-RO drive's catalogue and motor numbers (docs/real-data.md: 60:1, one start, worm diameter 10 mm, lead
#: 2.8625 deg, thread angle 40 deg; the Maxon's K_t 4.78 mN m/A and nominal torque 9.84 mN m; R a placeholder)
TRO_DATASHEET = ("--name", "T-RO drive No. 3 from its datasheet", "--source", "Mablekos-Alexiou et al., T-RO 2021",
                 "--ratio", "60", "--worm-diameter-mm", "10", "--lead-angle-deg", "2.8625", "--pressure-angle-deg",
                 "20", "--torque-constant", "0.00478", "--resistance", "2.0", "--rotor-inertia-gcm2", "6.5",
                 "--rated-current", "2.0585774", "--max-voltage", "24")
BENCH_RIGS = ("nmrv030", "nmrv030_i15", "nmrv040")
RECORD_S, SHORT_S = 20.0, 5.0  # [s] identify's record of a bench rig; estimate's log
FOREIGN = "foreign30"
#: the reduction the catalogue gives rig_from_datasheet (TRO_DATASHEET; evaluation.foreign's FOREIGN30)
CATALOGUE_RATIO = {"datasheet_tro": 60, f"datasheet_{FOREIGN}": 30}

#: file -> (writer, drive): the ten files the writers write
WRITTEN = {
    **{f"identify_{rig}": ("identify", rig) for rig in BENCH_RIGS},
    "residuals_nmrv030": ("residuals", "nmrv030"),
    "identify_tro": ("identify", "tro"),
    "residuals_tro": ("residuals", "tro"),
    "datasheet_tro": ("rig_from_datasheet", "tro"),
    "identify_datasheet_tro": ("identify", "tro"),
    f"datasheet_{FOREIGN}": ("rig_from_datasheet", FOREIGN),
    f"identify_datasheet_{FOREIGN}": ("identify", FOREIGN),
}

def keys(bugs: dict[str, pytest.MarkDecorator] | None = None) -> list:
    """The written files' keys for parametrize, with the marks of known bugs."""
    return [pytest.param(key, marks=(bugs or {})[key]) if key in (bugs or {}) else key for key in WRITTEN]


@dataclass(frozen=True)
class Logs:
    """A drive's logs: what identify and residuals fit (``run``), what estimate reads (``short``), a run held at
    speeds and loads for health_check (``held``), the options giving EPOS exports their load, and whether the logs
    carry the drive voltage (the observer's input)."""

    run: Path
    short: Path
    held: Path
    load: tuple[str, ...] = ()
    voltage: bool = True


@dataclass(frozen=True)
class Written:
    """One written file, the tool that wrote it, its drive's logs and the rig file it started from."""

    key: str
    path: Path
    writer: str
    logs: Logs
    base: Path

    @property
    def model(self) -> bool:
        """An extended rig file (identify's, residuals'): the estimators' model_file; else a rig file (rig_file)."""
        return self.writer != "rig_from_datasheet"

    def estimate_option(self) -> list[str]:
        return ["--model-file" if self.model else "--rig", str(self.path)]


# --- running the tools ----------------------------------------------------------------------------------------

def executable(name: str) -> str:
    return str(find_executable(name))


def run_tools(commands: Sequence[tuple[str, Sequence[str]]], cwd: Path, env: dict[str, str]
              ) -> list[subprocess.CompletedProcess]:
    """The executables with their arguments, two at a time (the machine's cores), in ``cwd``."""
    def one(command: tuple[str, Sequence[str]]) -> subprocess.CompletedProcess:
        name, args = command
        return subprocess.run([executable(name), *args], cwd=cwd, env=env, capture_output=True, text=True,
                              timeout=600)
    with ThreadPoolExecutor(max_workers=2) as pool:
        return list(pool.map(one, commands))


def last_line(text: str) -> str:
    lines = text.strip().splitlines()
    return lines[-1] if lines else ""


# --- the logs and the written files ---------------------------------------------------------------------------

def off_by_a_datasheet(rig_file: Path, out: Path) -> Path:
    """The drive as it is: its rig file with mu x1.3 and the drags x2 (what a rig file's stand-ins get wrong)."""
    doc = yaml.safe_load(rig_file.read_text(encoding="utf-8"))
    doc["friction"]["scale"]["value"] *= 1.3
    for motor in ("drive_motor", "load_motor"):
        for drag in ("viscous_drag", "coulomb_drag"):
            doc[motor][drag]["value"] *= 2.0
    out.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return out


def first_seconds(csv: Path, seconds: float, out: Path) -> Path:
    """The first ``seconds`` of a rig-data CSV of a 1 kHz record."""
    lines = csv.read_text(encoding="utf-8").splitlines(keepends=True)
    out.write_text("".join(lines[:1 + int(round(seconds * 1000.0))]), encoding="utf-8")
    return out


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Logs]:
    """Each drive's logs (Logs): the bench rigs recorded on the simulator, foreign30 on its own plant, the T-RO
    drive's real exports (for health_check, read once and written as rig data: it reads no EPOS export)."""
    from torque_estimator.evaluation.foreign.drives import DRIVES
    from torque_estimator.evaluation.foreign.recordings import excitation, validation, write_csv
    from torque_estimator.health.reference import reference_run
    from torque_estimator.identification.excitation import default_excitation
    from torque_estimator.identification.simulated import record_on_simulator
    from worm_model.rig_data.epos_options import EposSettings, hanging_load
    from worm_model.rig_data.reader import read_rig_data
    from worm_model.rig_data.schema import write_rig_csv

    folder = tmp_path_factory.mktemp("logs")
    out: dict[str, Logs] = {}
    for rig in BENCH_RIGS:
        true = load_rig(off_by_a_datasheet(DATA / f"{rig}_rig.yaml", folder / f"true_{rig}.yaml"))
        write_rig_csv(folder / f"{rig}_run.csv", record_on_simulator(true, default_excitation(true, RECORD_S), seed=3))
        write_rig_csv(folder / f"{rig}_held.csv", record_on_simulator(true, reference_run(true), seed=4))
        out[rig] = Logs(folder / f"{rig}_run.csv",
                        first_seconds(folder / f"{rig}_run.csv", SHORT_S, folder / f"{rig}_short.csv"),
                        folder / f"{rig}_held.csv")
    drive = DRIVES[FOREIGN]
    write_csv(folder / f"{FOREIGN}_run.csv", excitation(drive, 2 * RECORD_S, 1))
    write_csv(folder / f"{FOREIGN}_held.csv", validation(drive, RECORD_S, 2))
    out[FOREIGN] = Logs(folder / f"{FOREIGN}_run.csv",
                        first_seconds(folder / f"{FOREIGN}_held.csv", SHORT_S, folder / f"{FOREIGN}_short.csv"),
                        folder / f"{FOREIGN}_held.csv")
    short = folder / "tro_short"
    short.mkdir()
    for name in TRO_SHORT:
        shutil.copy(TRO_EXPORTS / f"{name}.csv", short / f"{name}.csv")
    rig = load_rig(TRO_RIG)
    exports = read_rig_data(TRO_EXPORTS, rig=rig, epos=EposSettings(
        load_torque=hanging_load(0.096, 0.02, 9.812), nominal_current=rig.drive_motor.rated_current,
        skip_bad_rows=True))
    write_rig_csv(folder / "tro_held.csv", exports)
    out["tro"] = Logs(TRO_EXPORTS, short, folder / "tro_held.csv", TRO_LOAD, voltage=False)
    return out


@pytest.fixture(scope="module")
def written(logs: dict[str, Logs], tmp_path_factory: pytest.TempPathFactory,
            ros_env: dict[str, str]) -> dict[str, Written]:
    """The ten files (WRITTEN), each written by its tool's executable; each must exit 0 and leave a file."""
    from torque_estimator.evaluation.foreign.drives import DRIVES, datasheet_args

    folder = tmp_path_factory.mktemp("written")
    paths = {key: folder / f"{key}.yaml" for key in WRITTEN}
    paths["residuals_nmrv030"] = folder / "residuals_nmrv030" / "extended_rig.yaml"
    paths["residuals_tro"] = folder / "residuals_tro" / "extended_rig.yaml"
    bases = {**{f"identify_{rig}": DATA / f"{rig}_rig.yaml" for rig in BENCH_RIGS},
             "residuals_nmrv030": DATA / "nmrv030_rig.yaml", "identify_tro": TRO_RIG, "residuals_tro": TRO_RIG,
             "datasheet_tro": DATA / "drive_template.yaml", "identify_datasheet_tro": paths["datasheet_tro"],
             f"datasheet_{FOREIGN}": DATA / "drive_template.yaml",
             f"identify_datasheet_{FOREIGN}": paths[f"datasheet_{FOREIGN}"]}

    def identify(key: str) -> tuple[str, list[str]]:
        drive = logs[WRITTEN[key][1]]
        return "identify", ["--from", str(drive.run), "--rig", str(bases[key]), *drive.load,
                            "--out", str(paths[key]), "--quiet"]

    first = [identify(f"identify_{rig}") for rig in BENCH_RIGS] + [
        identify("identify_tro"),
        ("residuals", [str(logs["nmrv030"].run), "--rig", str(bases["residuals_nmrv030"]),
                       "--out", str(paths["residuals_nmrv030"].parent), "--no-plots", "--quiet"]),
        ("residuals", [str(TRO_EXPORTS), "--rig", str(TRO_RIG), *TRO_LOAD, "--min-speed", "0.05",
                       "--out", str(paths["residuals_tro"].parent), "--no-plots", "--quiet"]),
        ("rig_from_datasheet", ["--out", str(paths["datasheet_tro"]), *TRO_DATASHEET]),
        ("rig_from_datasheet", ["--out", str(paths[f"datasheet_{FOREIGN}"]), "--name", FOREIGN,
                                "--source", f"{FOREIGN} catalogue", *datasheet_args(DRIVES[FOREIGN])]),
    ]
    second = [identify("identify_datasheet_tro"), identify(f"identify_datasheet_{FOREIGN}")]
    for batch in (first, second):
        for (name, args), done in zip(batch, run_tools(batch, folder, ros_env)):
            assert done.returncode == 0, f"{name} {' '.join(args)}: exit {done.returncode}\n{done.stderr[-3000:]}"
    out = {}
    for key, (writer, drive) in WRITTEN.items():
        assert paths[key].is_file(), f"{writer} wrote no {paths[key]}"
        load_rig(paths[key])
        out[key] = Written(key, paths[key], writer, logs[drive], bases[key])
    return out


def test_each_writer_marks_what_it_wrote(written: dict[str, Written]) -> None:
    """identify's files carry their identification: section (the estimators' ranges), residuals' their effects:,
    rig_from_datasheet's a source: on the datasheet's numbers; each is its drive's (the geometry as declared)."""
    for key, case in written.items():
        document = yaml.safe_load(case.path.read_text(encoding="utf-8"))
        if case.writer == "identify":
            assert {"identification", "free", "effects"} <= set(document), key
        elif case.writer == "residuals":
            assert "effects" in document and "identification" not in document, key
        else:
            assert "source" in document["drive_motor"]["torque_constant"], key
        ratio = 1.0 / CATALOGUE_RATIO[key] if case.writer == "rig_from_datasheet" else load_rig(case.base).gearbox.ratio
        assert load_rig(case.path).gearbox.ratio == pytest.approx(ratio, rel=1e-6), key


# --- the command-line readers ---------------------------------------------------------------------------------

@pytest.mark.parametrize("key", keys())
def test_estimate_reads_it(key: str, written: dict[str, Written], tmp_path: Path) -> None:
    from torque_estimator.offline.estimate import main

    case = written[key]
    methods = ("extended_model", "momentum") + (("observer",) if case.logs.voltage else ())
    for method in methods:
        out = tmp_path / f"{method}.csv"
        code, stdout, err = run_main(main, [str(case.logs.short), "--method", method, *case.estimate_option(),
                                        *case.logs.load, "--out", str(out), "--quiet"], tmp_path)
        assert code == 0, f"estimate --method {method} {' '.join(case.estimate_option())}: {err}"
        header, *rows = out.read_text(encoding="utf-8").splitlines()
        column = header.split(",").index("tau_estimate")
        assert any(math.isfinite(float(row.split(",")[column])) for row in rows), f"{method}: no estimate"
        line = last_line(stdout)
        assert line.startswith(f"estimate: method={method} "), line
        if method == "extended_model":  # the one estimator that reads the whole file (the others: its rig)
            trusted = float(re.search(r"trusted_pct=(\S+)", line).group(1))
            assert trusted > 0.0, f"no estimate trusted with {case.path.name}: {line}"


@pytest.mark.parametrize("key", keys())
def test_worm_calc_reads_it(key: str, written: dict[str, Written], tmp_path: Path) -> None:
    from worm_model.calc.worm_calc import main

    code, stdout, err = run_main(main, ["--rig", str(written[key].path), "--mu", "0.05"], tmp_path)
    assert code == 0, err
    assert "self-locking" in stdout, stdout


@pytest.mark.parametrize("key", keys())
def test_health_check_reads_it(key: str, written: dict[str, Written], tmp_path: Path) -> None:
    from torque_estimator.health.health_check import main

    case = written[key]
    trend = tmp_path / "gearbox.jsonl"
    code, stdout, err = run_main(main, ["--trend", str(trend), "--rig", str(case.path), "--from",
                                        str(case.logs.held), "--dry-run", "--quiet"], tmp_path)
    assert code == 0, err
    assert last_line(stdout).startswith("health_check: level="), stdout[-2000:]
    assert not trend.exists()  # a dry run


@pytest.mark.parametrize("key", keys())
def test_residuals_reads_it(key: str, written: dict[str, Written], tmp_path: Path) -> None:
    """residuals reads every file; what it writes loads. On the T-RO exports (a torque channel) K_t is held at its
    declared value, said in a note: a second pass over its own output once let K_t run 72-fold from K_e."""
    from worm_model.residuals.cli import main

    case = written[key]
    speed = ["--min-speed", "0.05"] if case.logs.load else []  # docs/real-data.md's command on the exports
    code, stdout, err = run_main(main, [str(case.logs.run), "--rig", str(case.path), *case.logs.load, *speed,
                                    "--out", str(tmp_path / "res"), "--no-plots", "--quiet"], tmp_path)
    assert code == 0, err
    if key.endswith("_tro"):
        assert "drive_motor.torque_constant held at its declared value" in stdout
    assert last_line(stdout).startswith("found: "), stdout[-2000:]
    load_rig(tmp_path / "res" / "extended_rig.yaml")


@pytest.mark.parametrize("key", keys())
def test_identify_reads_it(key: str, written: dict[str, Written], tmp_path: Path) -> None:
    from torque_estimator.identification.identify import main

    case = written[key]
    out = tmp_path / "again.yaml"
    code, stdout, err = run_main(main, ["--from", str(case.logs.run), "--rig", str(case.path), *case.logs.load,
                                    "--out", str(out), "--quiet"], tmp_path)
    assert code == 0, err
    assert last_line(stdout).startswith("identify: rig_time_s="), stdout[-2000:]
    assert load_rig(out).name == load_rig(case.path).name


def test_the_simulator_runs_a_datasheet_rig(written: dict[str, Written], tmp_path: Path) -> None:
    """sim_node's plant (SimulatedRig, through identification.simulated) takes the file rig_from_datasheet wrote: a
    recording of identify's excitation on it is one identify fits."""
    from torque_estimator.identification.excitation import default_excitation
    from torque_estimator.identification.identify import main
    from torque_estimator.identification.simulated import record_on_simulator
    from worm_model.rig_data.schema import write_rig_csv

    case = written[f"datasheet_{FOREIGN}"]
    rig = load_rig(case.path)
    write_rig_csv(tmp_path / "run.csv", record_on_simulator(rig, default_excitation(rig, 10.0), seed=3))
    code, _stdout, err = run_main(main, ["--from", str(tmp_path / "run.csv"), "--rig", str(case.path),
                                     "--out", str(tmp_path / "identified.yaml"), "--quiet"], tmp_path)
    assert code == 0, err


# --- the nodes ------------------------------------------------------------------------------------------------

def operating_point(path: Path) -> tuple[float, float, float, float]:
    """(omega_worm [rad/s], load [N m], the current [A] the file's model gives there, the load range [N m]): half
    the file's speed range, three quarters up its load range (lifting: + rotation, + load)."""
    from torque_estimator.estimation.extended_model import model_ranges
    from worm_model.residuals.extended import ExtendedModel

    model = ExtendedModel.load(path)
    omega_max, low, high, _where = model_ranges(path, None, model.rig)
    omega, load = 0.5 * omega_max, low + 0.75 * (high - low)
    current = model.current(model.signals(np.array([omega]), np.array([0.0]), np.array([load]), np.array([0.0])))
    return omega, load, float(current[0]), high - low


def joint_state_parameters(written: dict[str, Written], node: str, method: str | None) -> str:
    """A parameter file: ``node`` with every written file as a joint's (model_files / rig_files)."""
    names = list(written)
    models = [str(c.path) if c.model else "" for c in written.values()]
    rigs = [str(c.path) if not c.model else "" for c in written.values()]
    section: dict = {"input": "joint_state", "joint_names": names}
    if node == "model_node":
        section["rig_files"] = [str(c.path) for c in written.values()]
    else:
        section.update({"method": method, "model_files": models, "rig_files": rigs})
        # the observer reads the voltage (momentum does not: test_momentum_on_a_joint_state_needs_no_voltage)
        section["voltage_topics"] = [f"voltage/{name}" for name in names]
    return yaml.safe_dump({"/**": {"ros__parameters": section}})


def test_the_nodes_take_every_file(written: dict[str, Written], ros_env: dict[str, str], tmp_path: Path) -> None:
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from worm_msgs.msg import RigSamples, TorqueEstimate

    from worm_model.ros.testing import probe_node, rig_samples, spin_until, stop_process

    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500, reliability=ReliabilityPolicy.BEST_EFFORT)
    # name -> (command, the topics it must come to publish)
    nodes: dict[str, tuple[list[str], list[str]]] = {}
    for key, case in written.items():
        nodes[f"estimator_node_{key}"] = (
            [executable("estimator_node"), "--ros-args", "-r", f"__ns:=/{key}", "-p", "method:=extended_model",
             "-p", f"{'model_file' if case.model else 'rig_file'}:={case.path}"], [f"/{key}/torque_estimate"])
    for node, method, topic in (("estimator_node", "momentum", "torque_estimate"),
                                ("estimator_node", "observer", "torque_estimate"),
                                ("model_node", None, "gearbox/forces")):
        params = tmp_path / f"{node}_{method}.yaml"
        params.write_text(joint_state_parameters(written, node, method), encoding="utf-8")
        nodes[f"{node}_joints_{method}"] = (
            [executable(node), "--ros-args", "-r", f"__ns:=/joints_{method}", "--params-file", str(params)],
            [f"/joints_{method}/{topic}/{key}" for key in written])
    points = {key: operating_point(case.path) for key, case in written.items()}
    logs = {name: tmp_path / f"{name}.log" for name in nodes}
    processes = {name: subprocess.Popen(argv, env=ros_env, stdout=logs[name].open("w"), stderr=subprocess.STDOUT)
                 for name, (argv, _topics) in nodes.items()}
    got: dict[str, list] = {key: [] for key in written}
    codes: dict[str, int] = {}
    try:
        with probe_node("round_trip_probe") as (node, executor):
            publishers = {key: node.create_publisher(RigSamples, f"/{key}/rig/samples", qos) for key in written}
            for key in written:
                node.create_subscription(TorqueEstimate, f"/{key}/torque_estimate", got[key].append, qos)

            def up() -> bool:
                for name, process in processes.items():
                    assert process.poll() is None, f"{name} exited {process.returncode}: {logs[name].read_text()}"
                return (all(node.count_publishers(topic) for _argv, topics in nodes.values() for topic in topics)
                        and all(p.get_subscription_count() for p in publishers.values()))

            assert spin_until(executor, up, 240.0, 0.1), {  # a safety net: what never came up
                name: [t for t in topics if not node.count_publishers(t)] for name, (_argv, topics) in nodes.items()}
            for first in range(0, 1500, 5):  # 1.5 s of one steady operating point per file, in the rig's batches
                stamp = node.get_clock().now().to_msg()
                for key, (omega, load, current, _span) in points.items():
                    publishers[key].publish(rig_samples(first, 5, stamp, omega_worm=omega, current_drive=current,
                                                        tau_load=load, theta_worm=0.0, voltage_drive=0.0))
                executor.spin_once(timeout_sec=0.002)
            # until each node has estimated the second second of its stream (a busy node lags: a safety deadline)
            spin_until(executor, lambda: all(sum(m.seq >= 1000 for m in ms) >= 20 for ms in got.values()), 60.0)
    finally:
        for name, process in processes.items():
            codes[name] = stop_process(process)
    assert all(code == 0 for code in codes.values()), {n: (c, logs[n].read_text()[-2000:]) for n, c in codes.items()
                                                        if c != 0}
    for key, (_omega, load, _current, span) in points.items():
        settled = [m.torque for m in got[key] if m.seq >= 1000]
        assert settled and all(m.method == "extended_model" for m in got[key]), (key, len(got[key]))
        print(f"{key}: {len(got[key])} estimates, {np.mean(settled):.6g} N m at {load:.6g} N m")
        assert np.mean(settled) == pytest.approx(load, abs=0.01 * span), key


def test_momentum_on_a_joint_state_needs_no_voltage(written: dict[str, Written], ros_env: dict[str, str],
                                                    tmp_path: Path) -> None:
    """estimator_node on a robot's JointState with method momentum and an identified file, no voltage topics: it
    must come up (publish the joint's estimate topic) as extended_model does; momentum reads current and speed."""
    from worm_model.cli.errors import EXIT_INTERRUPTED
    from worm_model.ros.testing import probe_node, spin_until, stop_process

    case = written["identify_nmrv030"]
    log = tmp_path / "estimator_node.log"
    process = subprocess.Popen([executable("estimator_node"), "--ros-args", "-r", "__ns:=/momentum_alone",
                                "-p", "input:=joint_state", "-p", "joint_names:=[elbow]", "-p", "method:=momentum",
                                "-p", f"model_file:={case.path}"],
                               env=ros_env, stdout=log.open("w"), stderr=subprocess.STDOUT)
    try:
        with probe_node("momentum_probe") as (node, executor):
            # up: its estimate topic offered and its start-up done (it logs the joints it estimates last)
            up = spin_until(executor, lambda: process.poll() is not None
                            or (node.count_publishers("/momentum_alone/torque_estimate/elbow") > 0
                                and "estimators for joints" in log.read_text()), 120.0, 0.1)
            assert up and process.poll() is None, f"exit {process.poll()}: {log.read_text()}"
    finally:
        code = stop_process(process)
    # SIGINT between that log line and the first spin stops it as an interrupted start (130), after: 0
    assert code in (0, EXIT_INTERRUPTED), f"exit {code}: {log.read_text()}"


# --- the property: any valid correction, written, read back ---------------------------------------------------

@pytest.fixture(scope="module")
def identifications(logs: dict[str, Logs]) -> dict[str, tuple]:
    """identify's fit (in this process) of the nmrv030 recording (the time-series road) and of the T-RO exports
    (the steady-point road: a support's rise among its leaves), with the rig file each started from."""
    from torque_estimator.identification.fit import identify
    from worm_model.rig_data.epos_options import EposSettings, hanging_load
    from worm_model.rig_data.reader import read_rig_data

    bench = DATA / "nmrv030_rig.yaml"
    rig = load_rig(TRO_RIG)
    exports = read_rig_data(TRO_EXPORTS, rig=rig, epos=EposSettings(
        load_torque=hanging_load(0.096, 0.02, 9.812), nominal_current=rig.drive_motor.rated_current,
        skip_bad_rows=True))
    return {"nmrv030": (identify(read_rig_data(logs["nmrv030"].run, rig=load_rig(bench)), bench), bench),
            "tro": (identify(exports, TRO_RIG), TRO_RIG)}


def valid_range(ident, name: str) -> tuple[float, float]:
    """Where a correction of ``name`` is valid [SI]: its tolerance band around the declared value, else its
    physical range, else half to twice what identify fitted; never below 0 where the parameter has that bound."""
    from worm_model.residuals.free import LOWER_BOUNDS, TOLERANCES, get_value

    declared, fitted = ident.corrections[name][0], get_value(ident.model.rig, name)
    tolerance = TOLERANCES.get(name)
    low, high = tolerance.band(declared, ident.declared) if tolerance else (None, None)
    if low is None or high is None:
        hard = tolerance.hard_range(declared) if tolerance else None
        low, high = hard if hard else sorted((0.5 * fitted, 2.0 * fitted))
    if name in LOWER_BOUNDS or "stribeck" in name:
        low = max(low, 0.0)
    return low, high


@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_any_valid_correction_is_written_and_read_back(data: st.DataObject, identifications: dict[str, tuple],
                                                       tmp_path_factory: pytest.TempPathFactory) -> None:
    from torque_estimator.estimation.settings import EstimatorSettings, build_estimator
    from torque_estimator.identification.writing import write_identified
    from worm_model.residuals.extended import ExtendedModel
    from worm_model.residuals.free import get_value, set_values

    ident, rig_file = identifications[data.draw(st.sampled_from(sorted(identifications)), label="road")]
    order = data.draw(st.permutations(ident.fitted), label="fitted, in the order drawn")
    names = order[:data.draw(st.integers(1, len(order)), label="how many corrected")]
    values: dict[str, float] = {}
    for name in names:
        low, high = valid_range(ident, name)
        values[name] = data.draw(st.floats(low, high) if low > 0 else st.one_of(
            st.just(0.0), st.floats(max(high * 1e-6, low), high)), label=name)
    halves = {name: data.draw(st.one_of(st.just(math.nan), st.just(math.inf), st.floats(1e-4, 2.0).map(
        lambda f, v=value: f * abs(v))), label=f"{name} 95 % half-width") for name, value in values.items()}
    # the drawn model: the corrections drawn, the rest of the fitted parameters as declared (the writer leaves a
    # parameter it is not told was fitted at its declared leaf)
    others = [n for n in ident.fitted if n not in values]
    rig = set_values(ident.model.rig, others, [get_value(ident.declared, n) for n in others])
    model = dataclasses.replace(ident.model, rig=set_values(rig, list(values), list(values.values())))
    drawn = dataclasses.replace(ident, model=model, fitted=list(names), corrections={
        n: (ident.corrections[n][0], v, halves[n]) for n, v in values.items()})
    path = tmp_path_factory.mktemp("drawn") / "identified.yaml"
    write_identified(path, rig_file, drawn, "a drawn correction")

    read = load_rig(path)
    for name, value in values.items():
        assert get_value(read, name) == pytest.approx(value, rel=1e-5, abs=1e-300), name
    for name in others:
        assert get_value(read, name) == pytest.approx(get_value(ident.declared, name), rel=1e-5, abs=1e-300), name
    built = {method: build_estimator(EstimatorSettings(method, model_file=str(path)))
             for method in ("extended_model", "observer", "momentum")}
    assert all(b.rig.gearbox.ratio == read.gearbox.ratio for b in built.values())
    # the file is what the extended model inverts: the drawn model's current at a load gives that load back
    low, high = ident.torque_range
    omega = data.draw(st.floats(0.2, 0.8), label="speed share") * ident.speed_max
    load = low + data.draw(st.floats(0.55, 0.95), label="load share") * (high - low)
    current = float(ExtendedModel(model.rig, model.effects, model.alpha_time_constant).current(
        model.signals(np.array([omega]), np.array([0.0]), np.array([load]), np.array([0.0])))[0])
    rate = read.sensors.sample_rate_hz
    live = built["extended_model"].live(1.0 / rate)
    for k in range(2000):
        estimate = live.update(omega, current, voltage_drive=math.nan, theta_worm=omega * k / rate)
    assert estimate.torque == pytest.approx(load, abs=0.01 * (high - low)), (values, estimate)

