"""The live graph's control loop in one process: simulated rig with its speed loop, estimator, controller.

Per sample, what sim_node, estimator_node and controller_node do over DDS:

  1. the rig (SimulatedRig) advances one sample period and is sampled;
  2. the rig's own speed loop (worm_rig_driver.drive: the PI, every sample, no
     delay) sets the voltage for the next period from that sample and the
     feedforward torque of the speed command in force;
  3. the estimator (LiveEstimator) turns the sample into an estimate; the
     newest estimate of every ``ff_batch`` samples (a /rig/samples batch) goes to
     the controller, which sends the rig a speed command whose feedforward is
     tau_d reflected through the gearbox at the set-point (FeedforwardGate:
     fresh, usable estimates only); that command drives the rig from
     ``ff_latency`` sample periods after the next one on (the latency the graph
     benchmark reads off the rig's stream: 0 = the very next period).

Timings: the rig's (``ff_batch`` 1, ``ff_latency`` 0: the estimator beside the
rig's PI, the estimate of a sample feeding the very next period, as the shipped
graph runs it: sim_node's feedforward_estimator, control.rig_feedforward; a test
holds RigLoop with it equal to this loop), the firmware's (``ff_batch`` 1,
``ff_latency`` 1: the estimate of one sample feeds the period after next, as a
loop on the rig's own clock fed by a separate estimator would) and the node
graph's (``ff_batch`` 5, ``ff_latency`` as measured by bench/graph_bench.py).

Feedforward modes: "off" (PI only), "estimate" (the estimator's τ_d),
"truth" (the load the rig actually applied, through the same batch and
latency: the best any estimator could do with that timing). Several modes run
side by side, one rig each. Deterministic for a seed. Plain numpy; no ROS.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from worm_model.physics.parameters import Rig
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.estimation.settings import BuiltEstimator
from torque_estimator.evaluation.scenario import Segment, segment_at
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiGains, SpeedController
from worm_model.physics.steady_state import balancing_torque
from torque_estimator.control.feedforward import FeedforwardGate

FEEDFORWARD_MODES = ("off", "estimate", "truth")


@dataclass
class LoopRun:
    """Time series of one run, one entry per sample; times [s] from the scenario's start."""

    t: np.ndarray
    omega_true: np.ndarray  # [rad/s] the rig's true worm speed
    omega_measured: np.ndarray  # [rad/s] tachogenerator reading the controller saw
    setpoint: np.ndarray  # [rad/s]
    tau_true: np.ndarray  # [N m] load torque applied
    tau_estimated: np.ndarray  # [N m] estimator output (NaN when no estimator ran)
    feedforward: np.ndarray  # [N m] torque at the worm added as feedforward
    voltage: np.ndarray  # [V] drive command


def run_scenario(rig: Rig, scenario: tuple[Segment, ...], modes: tuple[str, ...] = ("off",), *,
                 estimator: BuiltEstimator | None = None, seed: int = 0, gains: PiGains = DEFAULT_GAINS,
                 estimate_timeout: float = 0.05, ff_batch: int = 1, ff_latency: int = 1,
                 ff_phase: int = 0) -> dict[str, LoopRun]:
    """Play a scenario (speed set-points and load torques over time) on the closed loop.

    One rig per feedforward mode, all side by side in one vectorised
    SimulatedRig (each rig draws its own sensor noise from the seed).

    Args:
        modes: feedforward modes, each one of FEEDFORWARD_MODES.
        estimator: the τ_d estimator as estimation.settings.build_estimator builds it for estimator_node or a
            rig's feedforward (its LiveEstimator, filters and all: BuiltEstimator.live), needed for mode
            "estimate" (only that rig runs it).
        estimate_timeout: as the controller_node parameter [s].
        ff_batch: samples per estimate the controller gets (>= 1; the rig's batch_size).
        ff_latency: sample periods between the period right after an estimate's sample
            and the first period its feedforward drives (>= 0).
        ff_phase: where the batches fall on the scenario's clock (0 <= ff_phase < ff_batch): a batch
            ends with sample k + 1 when (k + 1 + ff_phase) is a multiple of ff_batch. The demo's
            segments last whole batches, so at 0 every load step lands on a batch's first sample;
            live, where a step falls in its batch is chance.

    Returns:
        mode -> its run.
    """
    for mode in modes:
        if mode not in FEEDFORWARD_MODES:
            raise ValueError(f"feedforward modes must be among {FEEDFORWARD_MODES}, got {mode!r}")
    if len(set(modes)) != len(modes) or not modes:
        raise ValueError(f"need distinct feedforward modes, got {modes!r}")
    if "estimate" in modes and estimator is None:
        raise ValueError("feedforward mode 'estimate' needs an estimator")
    if ff_batch < 1 or ff_latency < 0 or not 0 <= ff_phase < ff_batch:
        raise ValueError(f"need ff_batch >= 1, ff_latency >= 0 and 0 <= ff_phase < ff_batch, got {ff_batch}, "
                         f"{ff_latency}, {ff_phase}")
    n = len(modes)
    sim = SimulatedRig(rig, n=n, seed=seed)
    dt = sim.sample_period
    controller = SpeedController(rig, gains, n=n)
    gates = [FeedforwardGate(estimate_timeout, enabled=mode != "off", max_load=1.5 * rig.max_load_torque)
             for mode in modes]
    live = {i: estimator.live(dt)
            for i, mode in enumerate(modes) if mode == "estimate"}
    pending: deque = deque()  # (first period driven, feedforward torque per rig) on their way to the rig

    steps = int(round(sum(s.duration for s in scenario) / dt))
    rec = {name: np.full((steps, n), np.nan) for name in LoopRun.__dataclass_fields__}
    tau_ff = np.zeros(n)
    estimates = np.zeros(n)
    flags = np.zeros(n, dtype=int)
    segment = None
    for k in range(steps):
        t = k * dt
        if (current := segment_at(scenario, t)) != segment:
            segment = current
            sim.command(load_torque=scenario[segment].load)
        setpoint = scenario[segment].speed
        m = sim.sample()  # sample k + 1 of the rig's clock; period k + 1 just ended
        stamp = sim.time
        for i, estimate in live.items():
            est = estimate.update(float(m.omega_worm[i]), float(m.current_drive[i]),
                                  voltage_drive=float(m.voltage_drive[i]), theta_worm=float(m.theta_worm[i]))
            rec["tau_estimated"][k, i] = est.torque
            estimates[i], flags[i] = est.torque, est.flags
        truth = sim.applied_load_torque
        if (k + 1 + ff_phase) % ff_batch == 0:  # a batch's newest sample: the controller sends a speed command
            ff = np.zeros(n)
            for i, mode in enumerate(modes):
                if mode == "truth":
                    gates[i].offer(float(truth[i]), 0, stamp)
                elif mode == "estimate":
                    gates[i].offer(float(estimates[i]), int(flags[i]), stamp)
                tau_d = gates[i].load(stamp)
                ff[i] = 0.0 if tau_d is None else float(balancing_torque(rig, tau_d, setpoint))
            pending.append((k + 2 + ff_latency, ff))
        # the rig's PI sets period k + 2 after this sample's command is queued, so that latency 0 reaches
        # that very period (popping first made latency 0 act as latency 1)
        while pending and pending[0][0] <= k + 2:  # commands in force for the coming period
            tau_ff = pending.popleft()[1]
        out = controller.update(dt, setpoint, m.omega_worm, tau_ff)  # the rig's PI
        sim.command(voltage_drive=out.voltage)
        rec["t"][k] = t
        rec["omega_true"][k] = sim.plant.state.omega_worm
        rec["omega_measured"][k] = m.omega_worm
        rec["setpoint"][k] = setpoint
        rec["tau_true"][k] = truth
        rec["feedforward"][k] = tau_ff
        rec["voltage"][k] = out.voltage
    return {mode: LoopRun(**{name: values[:, i] for name, values in rec.items()}) for i, mode in enumerate(modes)}


__all__ = ["FEEDFORWARD_MODES", "LoopRun", "run_scenario"]
