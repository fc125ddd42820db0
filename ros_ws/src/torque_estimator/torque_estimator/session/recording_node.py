"""The ROS shell of session.recording: drive whatever rig is on the graph through a timeline, recording it.

Live ``identify`` (its excitation) and a live ``health_check`` (its reference run) run here, each as a node of
its own name.

Publishes the timeline's load torque on /rig/load_command (worm_msgs/LoadCommand) and its worm
speed on /controller/speed_setpoint (std_msgs/Float64), reliable and latched (worm_model.ros.qos
COMMAND), as the rig's sample clock walks the timeline; reads /rig/samples (RigSamples batches)
and /rig/speed_command (SpeedCommand).  The rig (sim_node or driver_node) is held by its own
speed loop on the set-points controller_node sends, as in operation and as ``calibrate --live``.
Recording starts with the first sample after controller_node's speed commands carry the first
set-point.  Timeline, samples and journal: session.recording (no ROS there).
"""
from __future__ import annotations

from collections.abc import Callable

from worm_msgs.msg import RigSamples

from torque_estimator.session.rig_session_node import RigClient, await_setpoint, measure_until, rig_session
from torque_estimator.session.recording import ExcitationRun

#: a set-point is published again once it moved by this much (speed [rad/s], load [N m])
RESEND = (0.05, 2e-4)


class RecordingClient(RigClient):
    """Commands the timeline's set-points and feeds the rig's samples to an ExcitationRun."""

    def __init__(self, run: ExcitationRun, name: str) -> None:
        super().__init__(name)
        self.run = run
        self.recording = False
        self.sent: tuple[float, float] | None = None

    def take(self, msg: RigSamples) -> None:
        if not self.recording:
            return
        for k in range(len(msg.omega_worm)):
            self.run.add({"current_drive": msg.current_drive[k], "omega_worm": msg.omega_worm[k],
                          "theta_worm": msg.theta_worm[k], "tau_load": msg.tau_load[k],
                          "voltage_drive": msg.voltage_drive[k], "theta_gear": msg.theta_gear[k],
                          "current_load": msg.current_load_1[k] + msg.current_load_2[k]})
        target = self.run.setpoints()
        if target is not None:
            self.command(*target)

    def stop_rig(self) -> None:
        self.recording = False
        self.command(0.0, 0.0, force=True)

    def command(self, speed: float, torque: float, force: bool = False) -> None:
        """Ask for a worm speed [rad/s] and a load torque [N m] (sent when it moved by RESEND or ``force``)."""
        if not force and self.sent is not None and abs(speed - self.sent[0]) < RESEND[0] \
                and abs(torque - self.sent[1]) < RESEND[1]:
            return
        self.sent = (speed, torque)
        self.publish_setpoints(speed, torque)


def run_live(run: ExcitationRun, name: str, *, start_timeout: float = 30.0, ack_timeout: float = 5.0,
             stall_timeout: float = 5.0, on_tick: Callable[[], None] | None = None) -> None:
    """Record every pending segment of ``run`` on the rig of the current ROS graph, as node ``name``.

    Raises:
        LiveRigError: no rig, no controller, or the rig stopped sending (the journal keeps every
            finished segment).
        KeyboardInterrupt: Ctrl-C or SIGTERM (turned into it between two executor steps).
    On every exit the load torque and the speed set-point are commanded to 0: the rig is left stopped.
    """
    with rig_session(lambda: RecordingClient(run, name), start_timeout=start_timeout, on_tick=on_tick) as (
            node, spin_until):
        first = run.setpoints()
        if first is not None:
            node.command(*first, force=True)
            await_setpoint(node, spin_until, first[0], ack_timeout)
            node.recording = True
            measure_until(node, spin_until, lambda: run.finished, stall_timeout,
                          f"segment {run.segment} of {len(run.timeline)}")

__all__ = ["RecordingClient", "run_live"]
