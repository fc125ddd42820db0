"""The live graph's control loop in one process: simulated rig, estimator, speed controller.

Per sample, what sim_node, estimator_node and controller_node do over DDS:

  1. the rig (SimulatedRig, n = 1) advances one sample period and is sampled;
  2. the controller takes the held estimate (FeedforwardGate: fresh, usable)
     and runs one PI period with tau_d reflected through the gearbox as
     feedforward (speed_controller.feedforward_torque at the set-point);
  3. the estimator (LiveEstimator) turns the same sample into an estimate,
     which the controller gets ``estimate_delay`` samples later (on the graph
     estimator and controller both react to a sample at once, so the
     controller uses the previous sample's estimate at best).

By default the rig takes each command at the next sample (the firmware's
timing). ``command_period`` and ``command_delay`` imitate the node graph
instead: sim_node simulates publish_period worth of samples at a time with
the last command it received, so a command waits for the next tick and,
when the processes are busy, for a few more (a recorded demo run showed 1 to
~40 samples between a sample and the command that acted on it, median ~10).

Feedforward modes: "off" (PI only), "estimate" (the estimator's τ_d),
"truth" (the load the rig actually applied, one sample late: the best any
estimator could do). Several modes run side by side, one rig each.
Deterministic for a seed. Plain numpy; no ROS.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from worm_model.physics.parameters import Rig
from worm_rig_driver.sim.simulated_rig import SimulatedRig

from torque_estimator.estimation.base import TorqueEstimator
from torque_estimator.estimation.live import LiveEstimator
from torque_estimator.experiment.scenario import Segment, segment_at
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiGains, SpeedController
from torque_estimator.control.feedforward import FeedforwardGate
from worm_model.physics.steady_state import balancing_torque as feedforward_torque

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
                 estimator: TorqueEstimator | None = None, seed: int = 0, gains: PiGains = DEFAULT_GAINS,
                 estimate_delay: int = 1, estimate_timeout: float = 0.05,
                 live_options: Mapping[str, Any] | None = None, command_period: int = 1,
                 command_delay: int = 0) -> dict[str, LoopRun]:
    """Play a scenario (speed set-points and load torques over time) on the closed loop.

    One rig per feedforward mode, all side by side in one vectorised
    SimulatedRig (each rig draws its own sensor noise from the seed).

    Args:
        modes: feedforward modes, each one of FEEDFORWARD_MODES.
        estimator: the τ_d map lookup, needed for mode "estimate" (only that rig runs it).
        estimate_delay: samples between a sample and its estimate reaching the controller (>= 1).
        estimate_timeout: as the controller_node parameter [s].
        live_options: keyword arguments of LiveEstimator (the estimator_node parameters
            input_filter, estimate_filter, change_threshold, ...); None: its defaults.
        command_period: the rig takes a new drive command only every this many samples (>= 1).
        command_delay: samples between a control period and its command reaching the rig (>= 0).

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
    if estimate_delay < 1:
        raise ValueError(f"estimate_delay must be >= 1, got {estimate_delay}")
    if command_period < 1 or command_delay < 0:
        raise ValueError(f"need command_period >= 1 and command_delay >= 0, got {command_period}, {command_delay}")
    n = len(modes)
    sim = SimulatedRig(rig, n=n, seed=seed)
    dt = sim.sample_period
    controller = SpeedController(rig, gains, n=n)
    gates = [FeedforwardGate(estimate_timeout, enabled=mode != "off") for mode in modes]
    live = {i: LiveEstimator(rig, estimator, dt, **(live_options or {}))
            for i, mode in enumerate(modes) if mode == "estimate"}
    in_flight: dict[int, deque] = {i: deque() for i in live}  # estimates on their way to the controller
    commands: deque = deque()  # drive voltages on their way to the rig

    steps = int(round(sum(s.duration for s in scenario) / dt))
    rec = {name: np.full((steps, n), np.nan) for name in LoopRun.__dataclass_fields__}
    tau_ff = np.zeros(n)
    segment = None
    for k in range(steps):
        t = k * dt
        if (current := segment_at(scenario, t)) != segment:
            segment = current
            sim.command(load_torque=scenario[segment].load)
        setpoint = scenario[segment].speed
        m = sim.sample()
        stamp = sim.time
        for i, mode in enumerate(modes):
            if mode == "truth":  # the load applied one sample ago
                gates[i].offer(rec["tau_true"][k - 1, i] if k else 0.0, 0, stamp - dt)
            tau_d = gates[i].load(stamp)
            tau_ff[i] = 0.0 if tau_d is None else float(feedforward_torque(rig, tau_d, setpoint))
        out = controller.update(dt, setpoint, m.omega_worm, tau_ff)
        commands.append(out.voltage)
        if len(commands) > command_delay:
            voltage = commands.popleft()
            if (k + 1) % command_period == 0:  # the rig's next tick takes the latest command
                sim.command(voltage_drive=voltage)
        for i, estimate in live.items():
            est = estimate.update(float(m.omega_worm[i]), float(m.current_drive[i]))
            rec["tau_estimated"][k, i] = est.torque
            in_flight[i].append((est.torque, est.flags, stamp))
            if len(in_flight[i]) >= estimate_delay:
                gates[i].offer(*in_flight[i].popleft())
        rec["t"][k] = t
        rec["omega_true"][k] = sim.plant.state.omega_worm
        rec["omega_measured"][k] = m.omega_worm
        rec["setpoint"][k] = setpoint
        rec["tau_true"][k] = sim.applied_load_torque
        rec["feedforward"][k] = tau_ff
        rec["voltage"][k] = out.voltage
    return {mode: LoopRun(**{name: values[:, i] for name, values in rec.items()}) for i, mode in enumerate(modes)}


__all__ = ["FEEDFORWARD_MODES", "LoopRun", "run_scenario"]
