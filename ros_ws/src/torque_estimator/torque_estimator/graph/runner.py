"""Start a node graph from one ROS 2 parameter file (no ROS import: processes only).

`ros2 launch` is not always available (it is not on PyPI); this starts every
node named in a standard parameter file as its own process, exactly as
`ros2 run <pkg> <node> --ros-args [-r __ns:=<namespace>] --params-file <file>`
would, and stops them all cleanly (SIGINT, then SIGKILL after a grace period).
A node is a section with ``ros__parameters``, named by its executable; in a
namespace, by its full name (``/arm/joint2/sim_node:``) or nested in it
(``arm: {joint2: {sim_node: {ros__parameters: ...}}}``), both forms ROS 2's
parameter files take. Such a node runs with ``-r __ns:=/arm/joint2``, and is
named ``/arm/joint2/sim_node`` here (in ``--set``, groups, process names).
Nodes named in a group (``together``) share one process and executor instead
(nodes.composed), with the same parameters; a group's nodes share one namespace.
Executables are found where `ros2 run` finds them: <prefix>/lib/<pkg>/<exe>
for every prefix of AMENT_PREFIX_PATH.

Respawn, as launch's ``respawn``/``respawn_delay``/``respawn_max_retries``: the
process of a node named in ``respawn`` is started again when it exits on its own
(a crash, ``kill -9``), once ``respawn_delay`` has passed, by :meth:`Graph.supervise`,
which the owner calls periodically; not one that refused its input (exit code 2:
it would refuse it again), nor after ``respawn_max`` restarts.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from worm_model.cli.options import nearest
from worm_model.errors import InputError
from worm_model.files.reading import load_parameter_file, load_yaml
from worm_model.physics.parameters import load_rig
from worm_model.ros.ament import ament_prefixes, find_executable
from worm_rig_driver.drive.realtime import realtime_permitted
from torque_estimator.errors import GraphError


def default_graph_file() -> Path:
    """The installed sim_graph.yaml (share/torque_estimator/config), else the source tree's."""
    for prefix in ament_prefixes():
        candidate = prefix / "share" / "torque_estimator" / "config" / "sim_graph.yaml"
        if candidate.is_file():
            return candidate
    return Path(__file__).resolve().parents[2] / "config" / "sim_graph.yaml"


def split_name(node: str) -> tuple[str, str]:
    """(namespace, executable) of a graph node's name: "sim_node" -> ("/", "sim_node"),
    "/arm/joint2/sim_node" -> ("/arm/joint2", "sim_node")."""
    namespace, _, name = node.rpartition("/")
    return (namespace or "/"), name


def graph_sections(params_file: Path) -> dict[str, dict[str, Any]]:
    """{node: {parameter: value}} of a ROS 2 parameter file, read as rcl reads it in every node
    (worm_model.files.reading.load_parameter_file: no YAML anchors, a ros__parameters section per node),
    each node by its name here: ``sim_node``, or ``/arm/joint2/sim_node`` for one in a namespace (written
    flat or nested); ``/**`` sections left out.

    Raises:
        GraphError: unreadable file, or a section that is neither a node nor a namespace of nodes.
    """
    try:
        sections = load_parameter_file(params_file)
    except InputError as err:
        raise GraphError(f"graph file {err}") from None
    named = {}
    for name, values in sections.items():
        if "*" in name:
            continue  # parameters for every node (of a namespace), not a node
        inner = name.strip("/")
        named["/" + inner if "/" in inner else inner] = values
    if not named:
        raise GraphError(f"graph file {params_file}: expected node names at the top level")
    return named


def batch_size(params_file: Path, node: str = "sim_node") -> int:
    """Samples per rig/samples message of a graph's rig node (its ``batch_size``, which the graph file must set)."""
    return int(graph_sections(params_file)[node]["batch_size"])


def batch_rate(params_file: Path, node: str = "sim_node") -> float:
    """[Hz] of the rig/samples messages a graph's rig node publishes, which is also the rate of the rig's
    estimates (one per batch): the rig's sample rate (its ``sample_rate``, else its rig file's) over its
    :func:`batch_size`."""
    params = graph_sections(params_file)[node]
    rate = float(params.get("sample_rate", 0.0)) or load_rig(params.get("rig_file") or None).sensors.sample_rate_hz
    return rate / batch_size(params_file, node)


def graph_nodes(params_file: Path) -> list[str]:
    """The graph's nodes (graph_sections' names: the executable's, after their namespace if any)."""
    return list(graph_sections(params_file))


def check_graph(params_file: Path, overrides: dict[str, list[str]], nodes: list[str]) -> None:
    """Refuse, before anything starts, what the graph would refuse once started: a node with no executable,
    a parameter a node does not declare (a misspelling; the closest name given), a value of the wrong type,
    out of range or not one of its choices, in the file's section of a node of this project or in an
    override.

    Raises:
        GraphError: naming the node, the parameter and the problem.
    """
    from torque_estimator.nodes.composed import NODE_CLASSES, node_class  # rclpy: only for run_graph
    from worm_model.ros.parameters import declared_parameters, parameters_problem, ros_value

    sections = graph_sections(params_file)
    for node in nodes:
        executable = split_name(node)[1]
        if executable not in NODE_CLASSES:
            try:
                find_executable(executable)  # another package's node: it checks its own parameters
            except FileNotFoundError as err:
                raise GraphError(str(err)) from None
            continue
        values = dict(sections.get(node, {}))
        values.update({name: ros_value(text) for name, _, text in
                       (a.partition(":=") for a in overrides.get(node, []))})
        try:
            declared = declared_parameters(node_class(executable), values)
        except Exception:  # noqa: BLE001 - the node refuses these values itself at start, in its own words
            continue
        refused = parameters_problem(node, declared, values)
        if refused:
            name, problem = refused
            if any(a.startswith(name + ":=") for a in overrides.get(node, [])):
                raise GraphError(f"--set {node}.{name}: {problem}")
            raise GraphError(f"graph file {params_file}: {node}: parameter {name}: {problem}")


#: SCHED_FIFO priority of a rig computer's graph process (below the rig loop thread's 50)
RIG_COMPUTER_PRIORITY = 40


#: The rig's own nodes: each keeps a process, and so an interpreter lock, to itself (rig_computer).
RIG_NODES = ("sim_node", "driver_node")


def rig_computer(params_file: Path) -> dict:
    """Graph options of a rig computer: each rig's node (RIG_NODES) in a process of its own, every other
    node of the file together in one per namespace, all at RIG_COMPUTER_PRIORITY (``run_graph FILE
    --together <the others> --priority 40``); what the demo and the graph benchmark run.

    Why the rig alone: its sample thread runs the speed loop and, for the feedforward at the rig, an
    estimator on every sample (~0.3 core of Python); in one process with the other nodes all of that waits
    on one interpreter lock. Measured with an estimator_node in the graph as well (~0.5 core more): the
    lock sat near saturation, and in 4 demo runs on an idle machine the executor fell behind the rig by up
    to 1 s in every one (2 failed the live error bound); with the rig in its own process, 7 runs (3 under
    a CPU hog) saw at most one late estimate, at start-up. The model node in a process of its own costs
    ~0.14 core more and shortens no latency."""
    groups: dict[str, list[str]] = {}
    for node in graph_nodes(params_file):
        namespace, name = split_name(node)
        if name not in RIG_NODES:
            groups.setdefault(namespace, []).append(node)
    return {"together": list(groups.values()), "priority": RIG_COMPUTER_PRIORITY}


def process_file_name(unit: list[str]) -> str:
    """A file name for the process of ``unit`` (its nodes' names joined by "+", a namespace's "/" as "__"):
    ``sim_node``, ``model_node+controller_node``, ``arm__joint2__sim_node``."""
    return "+".join(n.strip("/").replace("/", "__") for n in unit)


def parse_overrides(items: list[str]) -> dict[str, list[str]]:
    """'node.param=value' strings -> {node: ['param:=value', ...]} for --ros-args -p."""
    overrides: dict[str, list[str]] = {}
    for item in items:
        target, sep, value = item.partition("=")
        node, dot, param = target.partition(".")
        if not (sep and dot and node and param):
            raise GraphError(f"--set {item}: not of the form node.param=value")
        overrides.setdefault(node, []).append(f"{param}:={value}")
    return overrides


#: Exit code of a node that refused its input (worm_model.cli.errors): respawning it would not help.
REFUSED_INPUT = 2


@dataclass
class Graph:
    """The processes of one graph; a context manager that always stops them."""

    params_file: Path
    overrides: dict[str, list[str]] = field(default_factory=dict)
    log_dir: Path | None = None
    processes: dict[str, subprocess.Popen] = field(default_factory=dict)
    together: list[list[str]] = field(default_factory=list)
    """Groups of nodes that run in one process each; a group's process is keyed "a+b+..."."""
    priority: int = 0
    """SCHED_FIFO priority (1-99) for every process of the graph (``chrt -f``); 0: normal scheduling."""
    respawn: list[str] = field(default_factory=list)
    """Nodes (graph_nodes' names) whose process :meth:`supervise` starts again when it exits on its own; a
    process of several nodes (``together``) if any of them is named."""
    respawn_delay: float = 1.0
    """[s] from a respawnable process's exit to its restart."""
    respawn_max: int | None = None
    """Restarts per process at most (None: no limit); an exit after the last one is final (:meth:`failed`)."""
    restarts: dict[str, int] = field(default_factory=dict, init=False)
    """Process key -> restarts so far."""
    last_exit: dict[str, tuple[int, float]] = field(default_factory=dict, init=False)
    """Process key -> (exit code, [s] from the exit to the restart) of its latest restart."""
    _commands: dict[str, list[str]] = field(default_factory=dict, init=False, repr=False)
    _env: dict[str, str] = field(default_factory=dict, init=False, repr=False)
    _exited_at: dict[str, float] = field(default_factory=dict, init=False, repr=False)
    _stopping: bool = field(default=False, init=False, repr=False)

    def command(self, node: str) -> list[str]:
        namespace, name = split_name(node)
        try:
            executable = find_executable(name)
        except FileNotFoundError as err:
            raise GraphError(str(err)) from None
        cmd = [str(executable), "--ros-args"] + (["-r", f"__ns:={namespace}"] if namespace != "/" else [])
        cmd += ["--params-file", str(self.params_file)]
        for assignment in self.overrides.get(node, []):
            cmd += ["-p", assignment]
        return cmd

    def composed_command(self, group: list[str]) -> list[str]:
        """One process for ``group`` (one namespace): the overrides are merged into a parameter file of its
        own, every node's section under its full name."""
        namespaces = {split_name(n)[0] for n in group}
        if len(namespaces) > 1:
            raise GraphError(f"a group's nodes share one namespace; {group} span {sorted(namespaces)}")
        namespace = namespaces.pop()
        raw = load_yaml(self.params_file, "graph parameter file")
        data = {key: body for key, body in raw.items() if str(key).endswith("**")}  # every node's parameters
        data.update({"/" + n.lstrip("/"): {"ros__parameters": body}
                     for n, body in graph_sections(self.params_file).items()})
        for node, assignments in self.overrides.items():
            section = data.setdefault("/" + node.lstrip("/"), {}).setdefault("ros__parameters", {})
            for assignment in assignments:
                name, _, value = assignment.partition(":=")
                section[name] = yaml.safe_load(value)
        merged = (self.log_dir or Path(tempfile.mkdtemp(prefix="graph_"))) / f"{process_file_name(group)}.params.yaml"
        merged.parent.mkdir(parents=True, exist_ok=True)
        merged.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        return [sys.executable, "-m", "torque_estimator.nodes.composed", "--params-file", str(merged),
                *(["--namespace", namespace] if namespace != "/" else []), *(split_name(n)[1] for n in group)]

    def start(self) -> "Graph":
        nodes = graph_nodes(self.params_file)
        unknown = set(self.overrides) - set(nodes)
        if unknown:
            raise GraphError(f"overrides name nodes not in {self.params_file}: {sorted(unknown)}")
        if stray := sorted(set(self.respawn) - set(nodes)):
            raise GraphError(f"respawn names nodes not in {self.params_file}: {stray}{nearest(stray[0], nodes)} "
                             f"(its nodes: {', '.join(nodes)})")
        check_graph(self.params_file, self.overrides, nodes)
        grouped = [n for group in self.together for n in group]
        if stray := sorted(set(grouped) - set(nodes)):
            raise GraphError(f"groups name nodes not in {self.params_file}: {stray}")
        if len(grouped) != len(set(grouped)):
            raise GraphError(f"a node is in more than one group: {self.together}")
        units = [group for group in self.together if group] + [[n] for n in nodes if n not in grouped]
        if self.priority and not realtime_permitted(self.priority):
            print(f"graph: SCHED_FIFO {self.priority} is not permitted here (needs CAP_SYS_NICE or an rtprio "
                  "limit): the nodes run at normal priority", file=sys.stderr)
            self.priority = 0
        # every command first: a node that cannot be found is refused before any other has started
        commands = {"+".join(unit): self.command(unit[0]) if len(unit) == 1 else self.composed_command(unit)
                    for unit in units}
        prefix = ["chrt", "-f", str(self.priority)] if self.priority else []
        self._commands = {name: [*prefix, *command] for name, command in commands.items()}
        # numpy's BLAS with one thread in every node: see torque_estimator/__init__.py
        self._env = {**os.environ, "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS", "1")}
        try:
            for name in self._commands:
                self._spawn(name, "wb")
                self.restarts[name] = 0
        except BaseException:  # no node left running when the graph could not start whole
            self.stop()
            raise
        return self

    def _spawn(self, name: str, mode: str) -> None:
        """Start process ``name`` with its command and environment, its output into its log (``mode`` "wb":
        a new log, "ab": appended to), or this terminal without a log_dir."""
        out = None
        if self.log_dir is not None:
            self.log_dir.mkdir(parents=True, exist_ok=True)
            out = open(self.log_dir / f"{process_file_name(name.split('+'))}.log", mode)
        try:
            self.processes[name] = subprocess.Popen(self._commands[name], stdout=out,
                                                    stderr=subprocess.STDOUT if out else None, env=self._env)
        finally:
            if out is not None:
                out.close()  # the child has its own descriptor

    def respawnable(self, name: str) -> bool:
        """Whether process ``name`` is to be started again once it has exited: one of its nodes is in
        ``respawn``, it has not used up ``respawn_max``, and it did not refuse its input (exit code 2)."""
        nodes = set(name.split("+"))
        return (bool(nodes & set(self.respawn)) and self.processes[name].returncode != REFUSED_INPUT
                and (self.respawn_max is None or self.restarts.get(name, 0) < self.respawn_max))

    def supervise(self) -> list[str]:
        """Start again every exited respawnable process once respawn_delay has passed since it exited (as
        first seen here: call this every few tenths of a second), with the same command, environment and
        priority, its log appended to; never once :meth:`stop` has begun. Returns the keys restarted now."""
        restarted: list[str] = []
        now = time.monotonic()
        for name, proc in list(self.processes.items()):
            if self._stopping:
                break
            if proc.poll() is None or not self.respawnable(name):
                continue
            exited = self._exited_at.setdefault(name, now)
            if now - exited < self.respawn_delay:
                continue
            self._spawn(name, "ab")
            del self._exited_at[name]
            self.restarts[name] = self.restarts.get(name, 0) + 1
            self.last_exit[name] = (proc.returncode, now - exited)
            restarted.append(name)
        return restarted

    def failed(self) -> dict[str, int]:
        """Processes that have exited and are not respawnable (:meth:`respawnable`), with their exit codes."""
        return {n: p.returncode for n, p in self.processes.items() if p.poll() is not None
                and not self.respawnable(n)}

    def stop(self, grace: float = 10.0) -> dict[str, int]:
        """SIGINT every node, wait up to grace [s], SIGKILL what is left (after SIGUSR1, which makes a
        node print its threads' stacks to its log); returns exit codes. Nothing is respawned from here on."""
        self._stopping = True
        for proc in self.processes.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + grace
        for proc in self.processes.values():
            try:
                proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.send_signal(signal.SIGUSR1)  # run_node prints where it is stuck into its log
                try:
                    proc.wait(1.0)
                except subprocess.TimeoutExpired:
                    pass
                proc.kill()
                proc.wait()
        return {n: p.returncode for n, p in self.processes.items()}

    def __enter__(self) -> "Graph":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
