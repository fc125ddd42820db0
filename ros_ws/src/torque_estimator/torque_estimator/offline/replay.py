"""replay: run the model and the estimators over a recorded bag, offline, as the live graph did.

    ros2 run torque_estimator replay <bag> [--params-file sim_graph.yaml]
        [--set estimator_node.calibration_file=cal.json] [--estimators knn,...] [--follow-live]

No DDS, no rclpy: the bag's sample stream (/rig/samples, worm_msgs/RigSamples
batches, or /rig/sample, worm_msgs/RigSample) is read with
worm_model.bags.reader and fed, message by message in recorded order,

* to :class:`~worm_model.live.live_model.LiveModel`, the very class model_node
  runs (the internal forces of worm_model, Eqs 21-23, with model_node's
  parameters), and
* to :class:`~torque_estimator.estimation.live.LiveEstimator`, the very class
  estimator_node runs, once per estimator of the registry asked for
  (``--estimators``; default: the graph's live estimator's method).

The graph's live estimator, whose /torque_estimate the bag holds, is estimator_node when the
graph file has one; else the rig's (sim_node or driver_node with ``feedforward_estimator``
and ``publish_estimate``, as the shipped sim_graph.yaml runs it), which is replayed exactly as
the rig builds it (torque_estimator.control.rig_feedforward: the rig file's rig, the
feedforward's step detector). Parameters come from the graph's parameter file (the one the
live run used) plus ``--set`` overrides, with the nodes' defaults for anything missing.

If the bag also holds what the live nodes published (/torque_estimate,
/gearbox/forces), the replay is compared with it, sample by sample (by
``seq``), and the largest differences are printed. They are zero, or at
round-off, except where the live and the replayed input differ:

* The nodes' filters (speed, acceleration, current) carry state from sample
  to sample. A live node that started before the recording saw samples the
  bag lacks; its state differs from the replay's fresh one at first and the
  difference decays with the filter time constant (to round-off after ~40
  time constants: 2 s for the estimator's 0.05 s). ``--warmup`` excludes that
  stretch from the comparison.
* The streams are best effort: a batch the estimator (or model_node) missed
  live, but the recorder got, is one the replay feeds and live did not, and
  vice versa. Each live output answers one received batch (its seq is the
  batch's last sample), so the recorded outputs' seqs tell exactly which
  batches a node saw; ``--follow-live`` feeds each estimator only those. A gap in
  the recording of the outputs themselves (the recorder missed an estimate)
  then makes the replay skip a batch live processed: the comparison reports it.
  model_node's outputs (one per publish_period, for its newest sample) do not
  say which batches it got: it is fed every recorded batch.
  (A stream of single RigSamples counts each sample as its own batch.)

Speed: the replay's wall time against the bag's span of sample time is
printed as ``replay_speed_factor`` (> 1: faster than real time).

Exit code 2 on a bad bag, parameter file or calibration (the message names it).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from worm_model.live.live_model import FIELDS as FORCE_FIELDS
from worm_model.live.live_model import LiveModel
from worm_model.live.model_node_options import MODEL_NODE_JOINT_STATE_OPTIONS, MODEL_NODE_OPTIONS
from worm_model.cli.node_options import defaults
from worm_model.rig_data.joint_states import JOINT_STATE_OPTIONS
from worm_model.cli.errors import run_tool
from worm_model.errors import BagRecordingError, InputError, ParameterError, RigDataError
from worm_model.cli.options import Parser, existing_file, existing_bag, nearest, number
from worm_model.files.reading import load_parameter_file
from worm_model.physics.envelope import Envelope
from worm_model.physics.parameters import load_rig
from worm_model.bags.reader import BagReader
from worm_model.rig_data.bags import find_sample_topic
from worm_model.rig_data.plausibility import sample_rate_problem
from worm_model.rig_data.reader import is_bag
from worm_model.rig_data.samples import samples_of

from torque_estimator.errors import CalibrationError, GraphError, ReplayError
from torque_estimator.estimation.registry import ESTIMATORS
from torque_estimator.estimation.settings import (ALL_OPTIONS, INPUT_OPTIONS, RIG_SAMPLES_OPTIONS, EstimatorSettings,
                                                  build_estimator)
from torque_estimator.joints.settings import JOINT_STATE_ESTIMATOR_OPTIONS
from torque_estimator.graph.runner import default_graph_file, parse_overrides
from worm_rig_driver.drive.rig_node_options import RIG_NODE_OPTIONS
from worm_model.cli.progress import ProgressBar

#: The nodes' parameter defaults, for what the file leaves out: the rows each node declares (model_node:
#: worm_model.live.model_node_options; estimator_node: estimation.settings' and every method's; both: the
#: JointState input's, worm_model.rig_data.joint_states), so a file written for either input is read.
NODE_DEFAULTS: dict[str, dict[str, Any]] = {
    "model_node": defaults(MODEL_NODE_OPTIONS + MODEL_NODE_JOINT_STATE_OPTIONS + JOINT_STATE_OPTIONS),
    "estimator_node": {**{name: option.value for name, option in ALL_OPTIONS.items()},
                       **defaults(INPUT_OPTIONS + RIG_SAMPLES_OPTIONS + JOINT_STATE_OPTIONS
                                  + JOINT_STATE_ESTIMATOR_OPTIONS)},
}
#: The rig nodes whose feedforward estimator may be the graph's live estimator, and what replay reads of them
#: (worm_rig_driver.drive.rig_node_options; their other parameters are ignored here).
RIG_DEFAULTS: dict[str, Any] = defaults(RIG_NODE_OPTIONS)
RIG_NODES = ("sim_node", "driver_node")
#: sample channels checked against the rig's envelope before they reach a core
PLAUSIBLE_CHANNELS = ("omega_worm", "current_drive", "tau_load", "voltage_drive")
ESTIMATE_TOPIC = "/torque_estimate"
FORCES_TOPIC = "/gearbox/forces"
ESTIMATE_FIELDS = ("torque", "uncertainty", "flags", "omega_worm", "current_drive")
#: FORCE_FIELDS (imported above): the GearboxForces fields LiveModel returns and model_node publishes


# --- configuration ---------------------------------------------------------------------------------

def node_parameters(params_file: Path | None, overrides: Sequence[str] = ()) -> dict[str, dict[str, Any]]:
    """model_node's and estimator_node's parameters: defaults < file < ``node.param=value`` overrides.

    Raises:
        ReplayError: Unreadable file or bad override (named).
    """
    params: dict[str, dict[str, Any]] = {node: dict(values) for node, values in NODE_DEFAULTS.items()}
    params.update({node: dict(RIG_DEFAULTS) for node in RIG_NODES})
    document: dict = {}
    if params_file is not None:
        try:
            document = load_parameter_file(params_file)  # read as rcl reads it in the nodes
        except InputError as err:
            raise ReplayError(f"parameter file {err}") from None
        for node in params:
            values = document.get(node, {})
            if node in RIG_NODES:  # the rig's parameters replay does not read (seed, batch_size, ...) are left
                params[node].update({k: v for k, v in values.items() if k in RIG_DEFAULTS})
                continue
            for name in values:  # a misspelt name would leave the node's default in force without a word
                if name not in NODE_DEFAULTS[node]:
                    raise ReplayError(f"parameter file {params_file}: {node}: {node} declares no parameter "
                                      f"{name!r}{nearest(name, NODE_DEFAULTS[node])}")
            params[node].update(values)
    try:
        parsed = parse_overrides(list(overrides))
    except GraphError as err:
        raise ReplayError(str(err)) from None
    for node, assignments in parsed.items():
        if node not in params:
            continue  # another node of the graph (the same --set list serves run_graph)
        for assignment in assignments:
            name, _, text = assignment.partition(":=")
            known = RIG_DEFAULTS if node in RIG_NODES else NODE_DEFAULTS[node]
            if node in RIG_NODES and name not in known:
                continue  # a rig parameter replay does not read (seed, batch_size, ...)
            default = known.get(name)
            if name not in known:
                raise ReplayError(f"--set {node}.{name}={text}: {node} has no parameter {name!r}"
                                  f"{nearest(name, known)} (it has: {', '.join(known)})")
            try:
                value = yaml.safe_load(text) if text else ""
            except yaml.YAMLError:
                value = text
            if not _same_kind(default, value):
                raise ReplayError(f"--set {node}.{name}={text}: expected {type(default).__name__} like the "
                                  f"node's default {default!r}")
            params[node][name] = value
    params["live"] = {"node": live_estimator(document, params)}
    for node in ("model_node", "estimator_node"):
        if params[node]["input"] != "rig_samples":  # replay feeds the nodes a rig's sample stream
            raise ReplayError(f"{node}.input={params[node]['input']}: replay feeds the nodes a rig's samples "
                              "(/rig/samples); a graph reading a robot's JointState is replayed with ros2 bag play")
    return params


def live_estimator(document: Mapping[str, Any], params: Mapping[str, Mapping[str, Any]]) -> str:
    """Which node of the graph published /torque_estimate (module docstring): "estimator_node" when the file
    has it, else the rig node with a feedforward estimator that publishes it, else "estimator_node" (its
    defaults and the overrides)."""
    if "estimator_node" in document:
        return "estimator_node"
    for node in RIG_NODES:
        if node in document and params[node]["feedforward_estimator"] and params[node]["publish_estimate"]:
            return node
    return "estimator_node"


def live_method(params: Mapping[str, Mapping[str, Any]]) -> str:
    """The method of the graph's live estimator."""
    node = params["live"]["node"]
    return str(params[node]["feedforward_estimator"] if node in RIG_NODES else params[node]["method"])


def _same_kind(default: Any, value: Any) -> bool:
    """``value`` has the parameter type of ``default`` (an int is a float too, a bool is not a number)."""
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(default, bool) and isinstance(value, bool)
    if isinstance(default, float):
        return isinstance(value, (int, float))
    return isinstance(value, type(default))


# --- replay ----------------------------------------------------------------------------------------

@dataclass
class Outputs:
    """One core's outputs, one row per sample fed (arrays by field, plus the samples' seq)."""

    seq: list[int] = field(default_factory=list)
    values: dict[str, list[float]] = field(default_factory=dict)

    def add(self, seq: int, row: Mapping[str, float | int]) -> None:
        self.seq.append(seq)
        for name, value in row.items():
            self.values.setdefault(name, []).append(float(value))

    def array(self, name: str) -> np.ndarray:
        return np.asarray(self.values.get(name, []), dtype=float)


@dataclass
class ReplayResult:
    """What a replay produced and how long it took."""

    samples: int
    span: float
    """[s] sample time from the first to the last sample (header stamps)."""
    wall: float
    """[s] wall time of the replay (reading, decoding and computing)."""
    model: Outputs
    estimates: dict[str, Outputs]
    live_seen: dict[str, int] = field(default_factory=dict)
    """With --follow-live: samples each core was fed because live saw them."""

    @property
    def speed_factor(self) -> float:
        """Sample time per wall time: > 1 is faster than real time."""
        return self.span / self.wall if self.wall > 0 else math.inf


def _live_seqs(reader: BagReader, topic: str) -> set[int] | None:
    if topic not in reader.topics:
        return None
    return {int(m.decoded.seq) for m in reader.messages([topic])}


def replay(bag: Path | str, params: Mapping[str, Mapping[str, Any]], estimators: Iterable[str] | None = None,
           *, follow_live: bool = False, sample_topic: str | None = None, progress: bool = False,
           allow_truncated: bool = False, start_seq: int = 0) -> ReplayResult:
    """Run model_node's and estimator_node's cores over the bag's RigSample stream.

    Args:
        bag: Bag directory or storage file.
        params: From :func:`node_parameters`.
        estimators: Names in the estimator registry; None: estimator_node's ``method``.
        follow_live: Feed each core only the samples live answered (see the module docstring).
        sample_topic: sample stream topic; None: the only one (or /rig/samples, then /rig/sample).
        start_seq: batches ending before this seq are not fed (a replay that starts where a live
            node's recorded answers start).
        progress: Show a progress bar on stderr.
        allow_truncated: Read a storage file cut inside a record as far as it goes.

    Raises:
        ReplayError: Bad bag, calibration or estimator name, or a sample far outside what
            estimator_node's rig can do (named by message, seq and column).
    """
    model_p, est_p = params["model_node"], params["estimator_node"]
    live_node = params.get("live", {}).get("node", "estimator_node")
    names = list(estimators) if estimators else [live_method(params) if "live" in params else str(est_p["method"])]
    if unknown := [n for n in names if n not in ESTIMATORS]:
        raise ReplayError(f"unknown estimator(s) {unknown}; registry: {sorted(ESTIMATORS)}")
    start = time.perf_counter()
    model = LiveModel(load_rig(model_p["rig_file"] or None), bool(model_p["use_acceleration"]),
                      float(model_p["acceleration_filter"]))
    rig_file = params[live_node]["rig_file"]
    try:
        est_rig = load_rig(rig_file or None)  # the envelope of plausible samples
    except ParameterError as err:
        raise ReplayError(f"{live_node}.rig_file: {err}") from None
    period = 1.0 / float(est_p["sample_rate"])
    cores = {name: _rig_core(params[live_node], est_rig, period)
             if live_node in RIG_NODES and name == live_method(params) else _core(est_p, name, period)
             for name in names}
    model_out, est_out = Outputs(), {name: Outputs() for name in names}
    envelope = Envelope.of(est_rig)
    first = last = None
    n = 0
    early: list[float] | None = []
    try:
        with BagReader(bag, allow_truncated=allow_truncated) as reader:
            topic = find_sample_topic(reader, sample_topic)
            # model_node processes every batch it receives, in timer-sized chunks, and publishes the newest
            # sample's forces: its outputs do not tell which batches it got, so it is fed them all
            model_seqs = None
            est_seqs = _live_seqs(reader, ESTIMATE_TOPIC) if follow_live else None
            total = reader.topics[topic].metadata_count or 0
            kind = reader.topics[topic].type
            with ProgressBar(total, "replay", enabled=progress) as bar:
                for n_messages, message in enumerate(reader.messages([topic]), 1):
                    batch = samples_of(message.decoded, kind)
                    if not batch:
                        continue
                    for s in batch:
                        for column in PLAUSIBLE_CHANNELS:
                            if problem := envelope.problem(column, float(getattr(s, column))):
                                raise ReplayError(f"{bag}: {topic} message {n_messages}, sample seq {int(s.seq)}, "
                                                  f"column {column!r}: {problem}")
                    last_seq = int(batch[-1].seq)
                    if last_seq < start_seq:
                        continue
                    stamps = [s.header.stamp.sec + 1e-9 * s.header.stamp.nanosec for s in batch]
                    if early is not None:  # the stamps' step against the rig's sample rate, as every reader checks
                        early += stamps
                        if len(early) >= 50 or n_messages == total:
                            if problem := sample_rate_problem(np.asarray(early), 1.0 / period, est_rig.name):
                                raise ReplayError(f"{bag}: {topic}: sample stamps: {problem}")
                            early = None
                    first = stamps[0] if first is None else first
                    last = stamps[-1]
                    n += len(batch)
                    if model_seqs is None or last_seq in model_seqs:  # per sample, as model_node
                        forces = model.update_batch([s.omega_worm for s in batch], [s.current_drive for s in batch],
                                                    [s.tau_load for s in batch])
                        for s, f in zip(batch, forces):
                            model_out.add(int(s.seq), f.as_dict())
                    if est_seqs is None or last_seq in est_seqs:
                        for s in batch:
                            for name, core in cores.items():
                                e = core.update(s.omega_worm, s.current_drive, voltage_drive=s.voltage_drive,
                                                theta_worm=s.theta_worm, seq=int(s.seq))
                                est_out[name].add(int(s.seq), {"torque": e.torque, "uncertainty": e.uncertainty,
                                                               "flags": e.flags, "omega_worm": e.omega_worm,
                                                               "current_drive": e.current_drive})
                    if n_messages % 200 == 0:
                        bar.update_to(n_messages)
    except (BagRecordingError, RigDataError) as err:
        raise ReplayError(str(err)) from None
    wall = time.perf_counter() - start
    return ReplayResult(n, (last - first) if first is not None else 0.0, wall, model_out, est_out,
                        {"model": len(model_out.seq), **{k: len(v.seq) for k, v in est_out.items()}}
                        if follow_live else {})


def _core(parameters: Mapping[str, Any], name: str, period: float):
    """estimator_node's core for estimator ``name`` with the node's ``parameters`` (as the node builds it).

    Raises:
        ReplayError: a bad or missing calibration, rig or model file, or a bad option (named).
    """
    try:
        return build_estimator(EstimatorSettings.from_parameters(parameters, name)).live(period)
    except CalibrationError as err:
        hint = "" if parameters["calibration_file"] else \
            " (pass --set estimator_node.calibration_file=FILE, or set it in the parameter file)"
        raise ReplayError(f"estimator_node.calibration_file: {err}{hint}") from None
    except ValueError as err:  # worm_model's ParameterError is a ValueError: a bad rig_file or model_file
        raise ReplayError(f"estimator_node: {err}") from None


def _rig_core(parameters: Mapping[str, Any], rig, period: float):
    """The rig's feedforward estimator, built as the rig builds it (control.rig_feedforward), for its samples.

    Raises:
        ReplayError: a bad calibration (named).
    """
    from torque_estimator.control.rig_feedforward import build as build_rig_feedforward
    try:
        return build_rig_feedforward(str(parameters["feedforward_estimator"]),
                                     str(parameters["feedforward_calibration"] or ""), rig, period).live
    except ValueError as err:  # CalibrationError is one
        raise ReplayError(f"feedforward_calibration: {err}") from None


# --- comparison with the live run ------------------------------------------------------------------

def difference(a: float, b: float) -> float:
    """|a - b|, with NaN == NaN counted equal and NaN against a number counted infinitely different
    (a plain ``abs(a - b)`` would give NaN, which ``max`` drops unless it comes first)."""
    if math.isnan(a) or math.isnan(b):
        return 0.0 if math.isnan(a) and math.isnan(b) else math.inf
    return abs(a - b)


@dataclass
class Comparison:
    """Replay vs what the live node published, matched by seq."""

    topic: str
    matched: int
    live_only: int
    """Live outputs for samples the replay did not feed (or the bag lacks)."""
    replay_only: int
    """Samples replayed that live produced no (recorded) output for."""
    max_abs: dict[str, float]
    """Largest |replay - live| per field over the compared samples (NaN == NaN counts equal,
    NaN against a number as inf: :func:`difference`)."""
    compared: int


def compare(bag: Path | str, topic: str, replayed: Outputs, fields: Sequence[str], warmup: float = 0.0,
            method: str | None = None, allow_truncated: bool = False) -> Comparison | None:
    """Compare one core's outputs with the live messages recorded on ``topic`` (None if not recorded).

    Samples within ``warmup`` [s] (of header stamp) after the first recorded
    live output are matched but not compared (filter start-up, see module docstring).
    """
    with BagReader(bag, allow_truncated=allow_truncated) as reader:
        if topic not in reader.topics:
            return None
        live = {}
        stamps = {}
        for message in reader.messages([topic]):
            m = message.decoded
            if method is not None and getattr(m, "method", method) != method:
                continue
            live[int(m.seq)] = m
            stamps[int(m.seq)] = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
    index = {seq: i for i, seq in enumerate(replayed.seq)}
    common = sorted(set(index) & set(live))
    start = min(stamps.values()) if stamps else 0.0
    compared = [s for s in common if stamps[s] >= start + warmup]
    max_abs = {}
    for name in fields:
        ours = replayed.array(name)
        max_abs[name] = max((difference(float(ours[index[s]]), float(getattr(live[s], name))) for s in compared),
                            default=0.0)
    return Comparison(topic, len(common), len(set(live) - set(index)), len(set(index) - set(live)), max_abs,
                      len(compared))


# --- CLI -------------------------------------------------------------------------------------------

def _print_comparison(c: Comparison, label: str) -> None:
    worst = max(c.max_abs.values(), default=0.0)
    print(f"replay_{label}_matched: {c.matched} count")
    print(f"replay_{label}_compared: {c.compared} count")
    print(f"replay_{label}_live_only: {c.live_only} count")
    print(f"replay_{label}_replay_only: {c.replay_only} count")
    print(f"replay_{label}_max_abs_diff: {worst:.3g} (largest field difference)")
    for name, value in c.max_abs.items():
        print(f"  {label}.{name}: max |replay - live| = {value:.3g}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    return run_tool("replay", lambda: _main(argv))


def _main(argv: Sequence[str] | None) -> int:
    parser = Parser(
        prog="replay", description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="prints `replay_<metric>: <value> <unit>` lines: samples, span, wall, speed_factor, and for\n"
               "the live outputs the bag holds, replay_forces_* and replay_estimates_* (matched, compared,\n"
               "live_only, replay_only, max_abs_diff; per-field differences on stderr).\n"
               "exit code 2 on a bad bag, parameter file or calibration (the message names it).")
    parser.add_argument("bag", type=existing_bag,
                        help="bag directory (or .mcap/.db3 file) holding /rig/samples or /rig/sample")
    parser.add_argument("--params-file", type=existing_file, default=None, metavar="FILE",
                        help="graph parameter file of the live run (default: the installed sim_graph.yaml)")
    parser.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=VALUE",
                        help="override one parameter of model_node, estimator_node or the rig's estimator "
                             "(sim_node/driver_node feedforward_estimator, feedforward_calibration, rig_file) "
                             "(repeatable), e.g. sim_node.feedforward_calibration=cal.json; other nodes' and "
                             "parameters are ignored, so run_graph's --set list can be passed as is")
    parser.add_argument("--estimators", default=None, metavar="NAME[,NAME...]",
                        help=f"estimators of the registry to run ({', '.join(sorted(ESTIMATORS))}; "
                             "default: the method of the graph's live estimator, estimator_node's or the rig's)")
    parser.add_argument("--topic", default=None,
                        help="sample stream topic, RigSamples or RigSample (default: the only one, or /rig/samples, "
                             "then /rig/sample)")
    parser.add_argument("--follow-live", action="store_true",
                        help="feed each core only the samples its live node answered (by the seqs of the "
                             "recorded /torque_estimate and /gearbox/forces)")
    parser.add_argument("--allow-truncated", action="store_true",
                        help="read a bag file cut inside a record (messages lost) as far as it goes")
    parser.add_argument("--warmup", type=number("s", 0, 1e6), default=0.0, metavar="SECONDS",
                        help="leave the first SECONDS of live outputs out of the comparison (filter start-up)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if not is_bag(args.bag):  # a CSV log is estimate's input
        raise InputError(str(args.bag), "replay reads a bag (a folder, or a .mcap or .db3 file) of the graph's "
                                        "sample stream; for a worm_rig_data CSV run `estimate` on it")
    params = node_parameters(args.params_file or default_graph_file(), args.set)
    names = args.estimators.split(",") if args.estimators else None
    result = replay(args.bag, params, names, follow_live=args.follow_live, sample_topic=args.topic,
                    progress=not args.quiet, allow_truncated=args.allow_truncated)
    print(f"replay_samples: {result.samples} count")
    print(f"replay_span: {result.span:.3f} s")
    print(f"replay_wall: {result.wall:.3f} s")
    print(f"replay_speed_factor: {result.speed_factor:.1f} x real time")
    forces = compare(args.bag, FORCES_TOPIC, result.model, FORCE_FIELDS, args.warmup,
                     allow_truncated=args.allow_truncated)
    if forces is not None:
        _print_comparison(forces, "forces")
    method = live_method(params)
    if method in result.estimates:
        estimates = compare(args.bag, ESTIMATE_TOPIC, result.estimates[method], ESTIMATE_FIELDS,
                            args.warmup, method, args.allow_truncated)
        if estimates is not None:
            _print_comparison(estimates, "estimates")
    for name, outputs in result.estimates.items():
        torque = outputs.array("torque")
        finite = torque[np.isfinite(torque)]
        print(f"replay_{name}_mean_torque: {finite.mean() if finite.size else math.nan:.6g} N m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
