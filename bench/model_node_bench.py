"""Benchmark of model_node's work: one publish period of it (its /rig/samples callbacks and the processing), in-process.

    python bench/model_node_bench.py       (run_all.py runs it with its own ROS_DOMAIN_ID)

Builds the real ModelNode (rclpy, bundled rig), prepares RigSamples messages (the shipped graph's batch_size of
consecutive samples each, as the rig publishes them) of a simulated run (speed swings through both directions,
load torque sweeps all modes, the current the model needs plus sensor noise), and runs what the node's executor
runs in one publish_period (20 ms): on_samples for each message of it (each only queues its batch) and then
process() (filter updates and Eqs 21-23 for every queued sample, modes, the GearboxForces message of the newest
and its publish, to no subscriber: the DDS write but no delivery), timing each period with perf_counter_ns, in 3
rounds of 2000 periods. Executor dispatch and DDS transport to a subscriber are not included (the graph
benchmark measures those end to end). Prints to stdout:

  model_node_latency_p99: <x> us     p99 of one period's work: how long it holds the executor (lowest of the 3
                                     rounds: on a shared machine the tail is mostly other processes)
  model_node_latency_p50: <x> us     median of the same (lowest round)
  model_node_cpu_p99: <x> us         p99 of the thread CPU time of one period (what the code costs, without
                                     the waits for a CPU that wall time includes)
  model_node_cpu_per_sample: <x> us  mean thread CPU time per sample (lowest round)

Progress goes to stderr. Never asserts.
"""
from __future__ import annotations

import sys
import time

import numpy as np
import rclpy
from worm_msgs.msg import RigSamples

from worm_model.physics.dynamics import reflected_input_torque
from worm_model.physics.friction import friction_coefficient
from worm_model.physics.gear_side import gear_side_load
from worm_model.nodes.model_node import ModelNode
from torque_estimator.graph.runner import batch_size, default_graph_file

N = 2000  # publish periods per round
ROUNDS = 3
WARMUP = 200
BATCH = batch_size(default_graph_file())  # samples per message, as shipped


def info(text: str) -> None:
    print(f"[model_node_bench] {text}", file=sys.stderr, flush=True)


def messages(rig, n: int) -> list[RigSamples]:
    """A 1 kHz run: speed swings -300 -> 300 rad/s, load sweeps +-0.25 N m (every mode), and the
    drive current the quasi-static model needs for that (Eqs 28-29) plus sensor noise."""
    rng = np.random.default_rng(4)
    t = np.arange(n) / 1000.0
    omega = 300.0 * np.sin(2 * np.pi * t / (n / 1000.0)) + rng.normal(0, 0.5, n)
    tau = 0.25 * np.sin(2 * np.pi * 7 * t / (n / 1000.0))
    mu = friction_coefficient(rig.friction, rig.gearbox, omega)
    t_mesh = reflected_input_torque(rig.gearbox, mu, gear_side_load(rig, tau, omega), omega)
    m = rig.drive_motor
    current = (t_mesh + m.viscous_drag * omega + m.coulomb_drag * np.sign(omega)) / m.torque_constant
    current += rng.normal(0, rig.sensors.current_noise_std, n)
    out = []
    for k in range(0, n - BATCH + 1, BATCH):
        b = slice(k, k + BATCH)
        msg = RigSamples(first_seq=k, sample_period=1e-3, omega_worm=omega[b].tolist(),
                         current_drive=current[b].tolist(), tau_load=tau[b].tolist(),
                         omega_gear=(omega[b] * rig.gearbox.ratio).tolist())
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(t[k]), int((t[k] % 1.0) * 1e9)
        out.append(msg)
    return out


def main() -> int:
    rclpy.init()
    node = ModelNode()
    try:
        per_period = max(1, round(node.get_parameter("publish_period").value / (BATCH * 1e-3)))  # messages
        msgs = messages(node.rig, (WARMUP + ROUNDS * N) * per_period * BATCH)
        periods = [msgs[k:k + per_period] for k in range(0, len(msgs), per_period)]
        for period in periods[:WARMUP]:
            for msg in period:
                node.on_samples(msg)
            node.process()
        clock, cpu_clock = time.perf_counter_ns, time.thread_time_ns
        p50, p99, cpu99, per_sample = [], [], [], []
        for r in range(ROUNDS):
            times, cpu = np.empty(N), np.empty(N)
            for k, period in enumerate(periods[WARMUP + r * N:WARMUP + (r + 1) * N]):
                t0, c0 = clock(), cpu_clock()
                for msg in period:
                    node.on_samples(msg)
                node.process()
                times[k], cpu[k] = clock() - t0, cpu_clock() - c0
            p50.append(np.percentile(times, 50) / 1e3)
            p99.append(np.percentile(times, 99) / 1e3)
            cpu99.append(np.percentile(cpu, 99) / 1e3)
            per_sample.append(cpu.mean() / 1e3 / (per_period * BATCH))
            info(f"round {r + 1}: {N} periods of {per_period} messages of {BATCH} samples, p50 {p50[-1]:.1f} us, "
                 f"p99 {p99[-1]:.1f} us, max {times.max() / 1e3:.1f} us; CPU time p99 {cpu99[-1]:.1f} us")
        info(f"mu out of bound {node.mu_out_of_bound}, invalid {node.invalid} of {node.received} samples")
        # the least disturbed round: on a shared machine the tail is mostly other processes
        print(f"model_node_latency_p99: {min(p99):.1f} us", flush=True)
        print(f"model_node_latency_p50: {min(p50):.1f} us", flush=True)
        print(f"model_node_cpu_p99: {min(cpu99):.1f} us", flush=True)
        print(f"model_node_cpu_per_sample: {min(per_sample):.1f} us", flush=True)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
