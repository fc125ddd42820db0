"""controller_node and the rig's speed loop over real DDS: the output limit, anti-windup, the watchdog.

controller_node (voltage_limit 3 V, feedforward off) and sim_node run as their own
processes; the probe commands set-points and reads the rig's samples. The PI runs in
sim_node on every sample, with the gains and the limit controller_node sends
(worm_msgs/SpeedCommand). Asking for 300 rad/s (the worm reaches ~55 rad/s at 3 V)
must apply exactly the limit, flagged STATUS_DRIVE_LIMIT, never more; after that,
asking for 0 rad/s must bring the voltage to ~0 V at once: the integrator did not wind
up while the output was limited (a plain PI would have integrated ki x 250 rad/s x 1 s
= 5 N m and still command the full 3 V). When controller_node is gone, the rig stops
driving within its command_timeout (0.1 s) of rig time, and says so in its samples.

Timing is judged on the rig's own clock (the samples' seq), not the probe's.
ROS_DOMAIN_ID: the environment's if set, else a random one in 100..230;
discovery stays on this host (the ros_env fixture of tests/conftest.py).
"""
from __future__ import annotations

import signal
from collections.abc import Callable

import pytest
from std_msgs.msg import Float64
from worm_msgs.msg import RigSample, RigSamples

from torque_estimator.graph.runner import Graph
from worm_model.rig_data.samples import unbatch
from worm_model.ros.qos import COMMAND, STREAM
from worm_model.ros.testing import probe_node, spin_until

LIMIT = 3.0  # [V]
PARAMS = f"""\
sim_node:
  ros__parameters:
    command_timeout: 0.1
controller_node:
  ros__parameters:
    voltage_limit: {LIMIT}
    feedforward: false
    speed_setpoint: 0.0
"""


def rig_time(executor, last_seq: Callable[[], int | None], seconds: float, start_timeout: float,
             timeout: float) -> None:
    """Spin until the rig's clock has advanced by ``seconds`` (its samples' seqs; ``last_seq()``: the newest seq
    received, None before any): the first sample within ``start_timeout`` [s], the advance within ``timeout``."""
    assert spin_until(executor, lambda: last_seq() is not None, start_timeout), "no samples"
    start = last_seq()
    assert spin_until(executor, lambda: last_seq() - start >= seconds * 1000, timeout), "the rig stopped sampling"


def test_output_limit_no_windup_and_the_watchdog_over_dds(start_graph: Callable[[str, str], Graph]) -> None:
    graph = start_graph(PARAMS, "controller")
    with probe_node("controller_test_probe") as (node, executor):
        samples: list = []
        node.create_subscription(RigSamples, "/rig/samples", lambda m: samples.extend(unbatch(m)), STREAM)
        setpoint = node.create_publisher(Float64, "/controller/speed_setpoint", COMMAND)

        def last_seq() -> int | None:
            return samples[-1].seq if samples else None

        assert spin_until(executor, lambda: bool(samples) and setpoint.get_subscription_count() > 0, 30.0), (
            f"no samples or no controller; logs in {graph.log_dir}")
        setpoint.publish(Float64(data=300.0))
        assert spin_until(executor, lambda: samples[-1].voltage_drive == LIMIT, 15.0), "the limit was never reached"
        samples.clear()
        rig_time(executor, last_seq, 1.0, 10.0, 30.0)  # a worm that cannot reach the set-point
        assert all(s.voltage_drive == LIMIT for s in samples), sorted({s.voltage_drive for s in samples})
        assert all(s.status & RigSample.STATUS_DRIVE_LIMIT for s in samples[1:])

        setpoint.publish(Float64(data=0.0))
        samples.clear()
        assert spin_until(executor, lambda: bool(samples) and abs(samples[-1].voltage_drive) < 1.0, 15.0)
        first_low = next(k for k, s in enumerate(samples) if abs(s.voltage_drive) < 1.0)
        # the first commands after the set-point change take the voltage down at once (no wound-up
        # integral to unwind: that would take seconds at ki = 0.02)
        assert all(abs(s.voltage_drive) < 1.0 for s in samples[first_low:first_low + 50])

        # the controller dies: the rig stops driving within its command_timeout, on its own clock
        setpoint.publish(Float64(data=40.0))
        assert spin_until(executor, lambda: bool(samples) and samples[-1].voltage_drive > 0.5, 15.0)
        graph.processes["controller_node"].send_signal(signal.SIGKILL)
        graph.processes["controller_node"].wait(10)
        samples.clear()
        rig_time(executor, last_seq, 0.5, 10.0, 30.0)
        stopped = next((s for s in samples if s.status & RigSample.STATUS_WATCHDOG_STOP), None)
        assert stopped is not None, "the rig kept driving without its controller"
        assert all(s.voltage_drive == 0.0 for s in samples if s.seq >= stopped.seq)
        # the rig drove for at most command_timeout after the controller's last command (which came
        # 20 ms or less before the kill: command_period)
        driven = [s for s in samples if s.seq < stopped.seq]
        assert len(driven) <= 100 + 20 + 1, f"the rig drove {len(driven)} ms after its controller died"
    graph.processes.pop("controller_node")  # killed on purpose: not part of the clean-exit check
    assert not graph.failed(), graph.failed()
    assert graph.stop() == {"sim_node": 0}  # now: the next test's rig must be the only one on the domain


def test_feedforward_from_another_stacks_joint_state(start_graph: Callable[[str, str], Graph]) -> None:
    """controller_node takes the load from a sensor_msgs/JointState (feedforward_source joint_state): a
    resistive load gives the speed commands the feedforward that balances it. What is judged is the message's
    mapping, not the estimate's freshness (the fault tests judge that): estimate_timeout is 0.5 s here, so a
    busy machine that delays the estimates does not take the feedforward away. Settling and the averaging
    window are counted in rig time (the samples' seqs) and in commands, not in the probe's seconds."""
    from worm_msgs.msg import LoadCommand, SpeedCommand

    from worm_model.physics.parameters import load_rig
    from worm_model.physics.steady_state import balancing_torque

    graph = start_graph("""\
sim_node:
  ros__parameters:
    command_timeout: 0.1
estimator_node:
  ros__parameters:
    method: observer
controller_node:
  ros__parameters:
    speed_setpoint: 150.0
    feedforward_source: joint_state
    estimate_timeout: 0.5
""", "controller_joint_state")
    with probe_node("controller_joint_state_probe") as (node, executor):
        commands: list = []
        seqs: list[int] = []
        node.create_subscription(SpeedCommand, "/rig/speed_command", commands.append, STREAM)
        node.create_subscription(RigSamples, "/rig/samples", lambda m: seqs.extend(s.seq for s in unbatch(m)), STREAM)
        load = node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)

        def last_seq() -> int | None:
            return seqs[-1] if seqs else None

        assert spin_until(executor, lambda: bool(commands) and load.get_subscription_count() > 0, 30.0), (
            f"no speed commands; logs in {graph.log_dir}")
        load.publish(LoadCommand(torque=0.15))
        # the estimator may still be starting (a loaded machine: its first JointState came >3 s after the
        # controller's first command in CI): wait for the first feedforward, then for the speed to settle
        assert spin_until(executor, lambda: any(c.feedforward_torque for c in commands[-10:]), 60.0), (
            f"no feedforward from the JointState source; logs in {graph.log_dir}")
        rig_time(executor, last_seq, 2.0, 30.0, 60.0)
        commands.clear()
        rig_time(executor, last_seq, 1.0, 30.0, 60.0)
        assert spin_until(executor, lambda: len(commands) >= 100, 30.0), len(commands)
    expected = float(balancing_torque(load_rig(), 0.15, 150.0))
    fed = [c.feedforward_torque for c in commands]
    assert sum(fed) / len(fed) == pytest.approx(expected, rel=0.1), (
        sum(fed) / len(fed), expected, (graph.log_dir / "controller_node.log").read_text()[-3000:])
    assert not graph.failed(), graph.failed()
    assert set(graph.stop().values()) == {0}  # the next test's rig and controller must be the only ones


def test_feedforward_at_the_rig_meets_a_load_step_within_a_few_samples(start_graph: Callable[[str, str], Graph]
                                                                       ) -> None:
    """sim_node runs the observer beside its PI (feedforward_estimator) and controller_node asks for it
    (feedforward_at_rig); the rig does not publish that estimate (publish_estimate false) and no
    estimator_node runs, so any feedforward is the rig's own. After a resistive load
    step the drive voltage has made most of its way to the new steady value within a few samples: the
    feedforward moved it, where the PI alone (feedforward_at_rig set false at run time, as `ros2 param set` does)
    has barely started. Judged on the rig's own samples (the applied load's step, their seqs). The rig's
    watchdog waits 1 s here: on a busy machine commands can come late, and the watchdog has its own test."""
    import numpy as np
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from worm_msgs.msg import LoadCommand

    graph = start_graph("""\
sim_node:
  ros__parameters:
    command_timeout: 1.0
    feedforward_estimator: observer
    publish_estimate: false
controller_node:
  ros__parameters:
    speed_setpoint: 150.0
    feedforward_at_rig: true
""", "controller_at_rig")
    with probe_node("controller_at_rig_probe") as (node, executor):
        samples: list = []
        node.create_subscription(RigSamples, "/rig/samples", lambda m: samples.extend(unbatch(m)), STREAM)
        load = node.create_publisher(LoadCommand, "/rig/load_command", COMMAND)

        def last_seq() -> int | None:
            return samples[-1].seq if samples else None

        def step_response(torque: float) -> float:
            """Apply a load step once the speed has settled; the voltage's mean change 5-15 samples after it,
            as a fraction of its change to the new steady state. Windows by the samples' seqs: a probe starved
            by a busy machine may miss some samples (best-effort stream), and must not shift the windows."""
            rig_time(executor, last_seq, 1.5, 60.0, 60.0)
            first = len(samples)
            load.publish(LoadCommand(torque=torque))
            rig_time(executor, last_seq, 1.5, 60.0, 60.0)
            start = max(first - 300, 0)
            got, new = samples[start:], first - start
            seq = np.array([s.seq for s in got])
            tau = np.array([s.tau_load for s in got])
            volts = np.array([s.voltage_drive for s in got])
            stopped = np.array([bool(s.status & RigSample.STATUS_WATCHDOG_STOP) for s in got])
            # the first sample under the new load
            k = seq[new + int(np.argmax(np.abs(tau[new:] - torque) < 0.5 * abs(torque)))]
            assert seq[-1] - k >= 1000, (k, seq[-1])
            assert not stopped.any(), f"the rig's watchdog stopped the drive (commands late); logs in {graph.log_dir}"
            before = volts[(seq >= k - 200) & (seq < k)].mean()
            after = volts[seq > seq[-1] - 300].mean()
            return float((volts[(seq >= k + 5) & (seq < k + 16)].mean() - before) / (after - before))

        # the controller running and the worm up to speed
        assert spin_until(executor, lambda: load.get_subscription_count() > 0 and bool(samples)
                          and samples[-1].omega_worm >= 140.0, 60.0), (
            f"the worm never reached speed; logs in {graph.log_dir}")
        at_rig = step_response(0.2)
        load.publish(LoadCommand(torque=0.0))
        client = AsyncParameterClient(node, "controller_node")  # what `ros2 param set` calls
        assert client.wait_for_services(timeout_sec=30.0), "controller_node's parameter services"
        future = client.set_parameters([Parameter("feedforward_at_rig", value=False)])
        executor.spin_until_future_complete(future, timeout_sec=30.0)
        assert future.done() and all(r.successful for r in future.result().results), future.result()
        pi_alone = step_response(0.2)
    # measured in 8 runs (4 with a CPU hog): 0.97-1.07 with the rig's feedforward, 0.32-0.36 without; 0.79 once
    # with another test file running beside it (the step detector fired a few samples later): the bar sits
    # between that and twice what the PI alone gets
    assert at_rig > 0.7 and pi_alone < 0.45, (at_rig, pi_alone, f"logs in {graph.log_dir}")
    assert not graph.failed(), graph.failed()
    assert set(graph.stop().values()) == {0}
