"""The ROS shell of `calibrate --live`: drive whatever rig is on the graph through the grid.

Publishes the current point's load torque on /rig/load_command
(worm_msgs/LoadCommand) and its worm speed on /controller/speed_setpoint
(std_msgs/Float64), both reliable and latched; reads /rig/samples (RigSamples)
and /rig/speed_command (SpeedCommand). The rig is sim_node or driver_node, held
by its own speed loop on the set-point controller_node sends: calibrate does
not close a loop over DDS itself, so the rig is held by the same controller
(gains, limits, watchdog) as in operation. A point's samples are counted from
the first sample after controller_node's speed commands carry the new set-point. Sequencing,
steady-state detection and the journal live in live_calibration.
"""
from __future__ import annotations

from collections.abc import Callable

from worm_msgs.msg import RigSamples

from torque_estimator.calibration.live import PointByPoint
from torque_estimator.session.rig_session_node import RigClient, await_setpoint, measure_until, rig_session


class CalibrationClient(RigClient):
    """Commands the grid's set-points and feeds the rig's samples to a PointByPoint run."""

    def __init__(self, run: PointByPoint) -> None:
        super().__init__("calibrate")
        self.run = run

    def take(self, msg: RigSamples) -> None:
        for omega, current, load in zip(msg.omega_worm, msg.current_drive, msg.tau_load):
            self.run.add(omega, current, load)

    def command(self, speed: float, torque: float) -> None:
        """Ask for a worm speed [rad/s] and a load torque [N m] (positive opposing + rotation)."""
        self.publish_setpoints(speed, torque)


def run_live(run: PointByPoint, *, start_timeout: float = 30.0, ack_timeout: float = 5.0,
             stall_timeout: float = 5.0, on_point: Callable[[], None] | None = None,
             on_tick: Callable[[], None] | None = None) -> None:
    """Measure every pending point of `run` on the rig of the current ROS graph.

    Args:
        start_timeout: wait this long [s] for rig samples and controller_node's speed commands.
        ack_timeout: wait this long [s] for controller_node to take a new set-point.
        stall_timeout: samples stopping for this long [s] aborts the run.
        on_point: called after every finished (journalled) point.
        on_tick: called about every 0.1 s (progress display).

    Raises:
        LiveRigError: no rig, no controller, or the rig stopped sending; the
            journal keeps every point finished before.
        KeyboardInterrupt: Ctrl-C (or SIGTERM turned into it by the caller).
    On every exit the load torque and the speed set-point are commanded to 0.
    """
    with rig_session(lambda: CalibrationClient(run), start_timeout=start_timeout, on_tick=on_tick) as (
            node, spin_until):
        while (point := run.current) is not None:
            node.command(point.speed, point.torque)
            await_setpoint(node, spin_until, point.speed, ack_timeout)
            run.start()
            measure_until(node, spin_until, lambda: run.current != point, stall_timeout,
                          f"point {point.plan_index}: {point.speed:g} rad/s, {point.torque:g} N m")
            if on_point is not None:
                on_point()


__all__ = ["CalibrationClient", "run_live"]
