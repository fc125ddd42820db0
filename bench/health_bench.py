"""Benchmark of the live health monitor's work: health_monitor's callbacks, timed in-process on a simulated run.

    python bench/health_bench.py       (run_all.py runs it with its own ROS_DOMAIN_ID)

Builds the real HealthMonitorNode (rclpy, bundled rig, reference from the rig file, the oil temperature estimated:
the thermal model runs too), prepares the RigSamples messages (the shipped graph's batch_size of consecutive
samples each, as the rig publishes them at 1 kHz) of a simulated run of the paper's rig at work (every effect a
real gearbox has, speeds 120-280 rad/s, the load motors stepping every 5 s: health.study.operation), and feeds them
as the executor would: on_samples for every message, process() every publish_period (0.2 s) of rig time, which runs
the live window and publishes the GearboxHealth message (to no subscriber: the DDS write, no delivery). Each round
covers 20 s of rig time; the thread CPU time of all the calls over the rig time they cover is the monitor's share
of a core. Message deserialisation and the executor's dispatch are not included (the graph benchmark measures a
whole graph). Prints to stdout:

  health_monitor_cpu_cores: <x> cores         thread CPU time / rig time, lowest of 3 rounds (the target: <= 0.05)
  health_monitor_cpu_per_sample: <x> us       the same per rig sample

Progress goes to stderr. Never asserts.
"""
from __future__ import annotations

import sys
import time

import rclpy
from worm_msgs.msg import RigSamples

from worm_model.physics.parameters import load_rig
from torque_estimator.graph.runner import batch_size, default_graph_file
from torque_estimator.health.monitor_node import HealthMonitorNode
from torque_estimator.health.study import GEARBOX_EFFECTS, operation

ROUNDS = 3
SECONDS = 20.0  # of rig time per round
BATCH = batch_size(default_graph_file())  # samples per message, as shipped
PUBLISH_PERIOD = 0.2  # [s] the node's default


def info(text: str) -> None:
    print(f"[health_bench] {text}", file=sys.stderr, flush=True)


def messages(rig) -> list[RigSamples]:
    """The simulated run, cut into RigSamples messages of BATCH samples."""
    from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS, PiLoop
    from worm_rig_driver.sim.simulated_rig import SimulatedRig
    from torque_estimator.identification.excitation import sampled

    sim = SimulatedRig(rig, n=1, seed=5, effects=GEARBOX_EFFECTS)
    loop = PiLoop(rig, DEFAULT_GAINS, rig.supply_voltage)
    _index, speeds, loads = sampled(operation(rig, SECONDS), sim.sample_period)
    out, cols = [], {name: [] for name in ("omega_worm", "current_drive", "tau_load", "theta_worm", "theta_gear")}
    for k in range(len(speeds)):
        sim.command(load_torque=float(loads[k]))
        m = sim.sample()
        for name in cols:
            cols[name].append(float(getattr(m, name)[0]))
        sim.command(voltage_drive=loop.update(sim.sample_period, float(speeds[k]), float(m.omega_worm[0])))
        if len(cols["omega_worm"]) == BATCH:
            first = k + 1 - BATCH
            msg = RigSamples(first_seq=first, sample_period=sim.sample_period, **cols)
            msg.header.stamp.sec, msg.header.stamp.nanosec = int(first / 1000), int((first % 1000) * 1e6)
            out.append(msg)
            cols = {name: [] for name in cols}
    return out


def main() -> int:
    rig = load_rig()
    info(f"simulating {SECONDS:g} s of the rig at work")
    msgs = messages(rig)
    rclpy.init()
    node = HealthMonitorNode()
    try:
        per_publish = int(round(PUBLISH_PERIOD / (BATCH * 1e-3)))
        cores = []
        for r in range(ROUNDS):
            start = time.thread_time_ns()
            for j, msg in enumerate(msgs):
                node.on_samples(msg)
                if (j + 1) % per_publish == 0:
                    node.process()
            cpu = (time.thread_time_ns() - start) * 1e-9
            cores.append(cpu / SECONDS)
            info(f"round {r + 1}: {cpu:.3f} s of CPU for {SECONDS:g} s of rig time ({node.core.status.level}, "
                 f"{node.core.blocks_seen} blocks)")
        best = min(cores)
        print(f"health_monitor_cpu_cores: {best:.4f} cores")
        print(f"health_monitor_cpu_per_sample: {best * 1e3 * 1e3 / 1000:.2f} us")
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
