"""fil_commander: drives the rig through driver_node during a firmware-in-the-loop run.

Publishes a fixed drive-voltage / load-torque profile (timed from the first
/rig/sample it receives, in wall time) and records what comes back, so the run
exercises the whole loop: commands -> driver_node -> serial -> firmware -> PWM ->
plant -> ADC/encoders -> firmware -> serial -> driver_node -> /rig/sample.
When the first sample arrives it creates `ready_file` (when set): the run's rig time
starts counting from then, so a commander that discovers the driver late under a
loaded machine misses nothing of the profile.
On shutdown it writes a JSON summary to `report_file` (when set): per profile
phase the mean speed and load torque over the samples with the motors running
(samples flagged STATUS_WATCHDOG_STOP are only counted).

Profile (wall seconds after the first sample): 0-1 s 0 V; 1-4 s 8 V; 4-7 s 10 V
with 0.1 N m of load; then -8 V with 0.05 N m; the drive command is repeated at
`command_rate` Hz. With `speed_mode` the same profile is run by the rig's own speed
loop instead (worm_msgs/SpeedCommand at `command_rate` Hz, set-points SPEEDS): the
driver then runs the PI on every telemetry frame and sends the firmware a new drive
duty each millisecond. The worm stays below ~170 rad/s
(54k encoder edges/s): the firmware keeps up with ~64k edges/s on the drive
encoder while it streams at 1 kHz (see firmware/README.md).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from rclpy.node import Node
from worm_msgs.msg import DriveCommand, LoadCommand, RigSample, RigSamples, SpeedCommand

from worm_model.rig_data.samples import unbatch

from worm_model.ros.lifecycle import run_node
from worm_model.ros.parameters import declare
from worm_model.ros.qos import COMMAND, STREAM
from worm_rig_driver.drive.speed_loop import DEFAULT_GAINS

#: (start [s], drive voltage [V], load torque [N m])
PROFILE = ((0.0, 0.0, 0.0), (1.0, 8.0, 0.0), (4.0, 10.0, 0.1), (7.0, -8.0, 0.05))
#: speed_mode: the worm speed [rad/s] asked for instead of each voltage of PROFILE
SPEEDS = {0.0: 0.0, 8.0: 120.0, 10.0: 150.0, -8.0: -120.0}


def profile_at(t: float) -> tuple[float, float]:
    """Drive voltage [V] and load torque [N m] at t [s] into the profile."""
    voltage, torque = 0.0, 0.0
    for start, v, tau in PROFILE:
        if t >= start:
            voltage, torque = v, tau
    return voltage, torque


class FilCommander(Node):
    def __init__(self) -> None:
        super().__init__("fil_commander")
        rate = declare(self, "command_rate", 50.0, "Drive commands per second [Hz].", low=1.0, high=1000.0)
        self.report_file = declare(self, "report_file", "", "Write the JSON summary here at shutdown (empty: no file).")
        self.ready_file = declare(self, "ready_file", "",
                                  "Create this file when the first sample arrives (empty: no file).")
        self.speed_mode = declare(self, "speed_mode", False,
                                  "Run the profile with the rig's speed loop (SpeedCommand) instead of voltages.")
        self.drive = self.create_publisher(DriveCommand, "rig/drive_command", STREAM)
        self.speed = self.create_publisher(SpeedCommand, "rig/speed_command", STREAM)
        self.load = self.create_publisher(LoadCommand, "rig/load_command", COMMAND)
        self.create_subscription(RigSamples, "rig/samples", self.on_samples, STREAM)
        self.create_timer(1.0 / rate, self.on_tick)
        self.start: float | None = None
        self.torque: float | None = None
        self.samples = 0
        self.seq_gaps = 0
        self.last_seq: int | None = None
        self.phases: dict[str, dict[str, float]] = {}
        self.watchdog_samples = 0

    def on_samples(self, batch: RigSamples) -> None:
        for s in unbatch(batch):
            self.on_sample(s)

    def on_sample(self, s) -> None:
        """One sample (worm_model.rig_data.samples.Sample: RigSample's fields)."""
        if self.start is None:
            self.start = time.monotonic()
            if self.ready_file:
                Path(self.ready_file).touch()
        self.samples += 1
        if self.last_seq is not None and s.seq != self.last_seq + 1:
            self.seq_gaps += 1
        self.last_seq = s.seq
        if s.status & RigSample.STATUS_WATCHDOG_STOP:  # motors stopped (the final line cut): not the profile's
            self.watchdog_samples += 1
            return
        voltage, torque = profile_at(time.monotonic() - self.start)
        phase = self.phases.setdefault(f"{voltage:g} V {torque:g} N m", {
            "n": 0, "omega_worm_sum": 0.0, "tau_load_sum": 0.0, "omega_worm_max": 0.0, "status_or": 0})
        phase["n"] += 1
        phase["omega_worm_sum"] += s.omega_worm
        phase["tau_load_sum"] += s.tau_load
        phase["omega_worm_max"] = max(phase["omega_worm_max"], abs(s.omega_worm))
        phase["status_or"] = int(phase["status_or"]) | s.status

    def on_tick(self) -> None:
        if self.start is None:
            return
        voltage, torque = profile_at(time.monotonic() - self.start)
        if self.speed_mode:
            msg = SpeedCommand(speed_setpoint=SPEEDS[voltage], kp=DEFAULT_GAINS.kp, ki=DEFAULT_GAINS.ki,
                               voltage_limit=12.0)
            msg.header.stamp = self.get_clock().now().to_msg()
            self.speed.publish(msg)
        else:
            msg = DriveCommand(voltage=voltage)
            msg.header.stamp = self.get_clock().now().to_msg()
            self.drive.publish(msg)
        if torque != self.torque:
            self.torque = torque
            self.load.publish(LoadCommand(torque=torque))

    def report(self) -> dict:
        phases = {name: {"samples": int(p["n"]), "omega_worm_mean": p["omega_worm_sum"] / p["n"],
                         "tau_load_mean": p["tau_load_sum"] / p["n"], "omega_worm_max": p["omega_worm_max"],
                         "status_or": int(p["status_or"])}
                  for name, p in self.phases.items() if p["n"]}
        return {"samples": self.samples, "seq_gaps": self.seq_gaps, "watchdog_samples": self.watchdog_samples,
                "phases": phases}

    def destroy_node(self) -> None:
        if self.report_file:
            Path(self.report_file).write_text(json.dumps(self.report(), indent=1))
        super().destroy_node()


def main(args=None) -> int:
    return run_node(FilCommander, args)


if __name__ == "__main__":
    raise SystemExit(main())
