"""health_monitor: the gearbox's health between checks, live, from the rig's own samples.

Subscribes /rig/samples (worm_msgs/RigSamples, sensor-data QoS) and, if anything publishes it, the oil
temperature on ``oil_temperature`` (sensor_msgs/Temperature, relative name, remappable); queues the
batches and runs them through the live monitor's core (worm_model.health.live.LiveHealth: a sliding
window of the friction against the health model with the reference check's parameters) every
``publish_period``, then publishes the window's estimate on ``health`` (worm_msgs/GearboxHealth,
sensor-data QoS) and its level with the figures on /diagnostics (OK / WARN / ERROR, once a second and
at once when the level changes). The reference is the latest check of ``trend_file`` (the file
``health_check`` appends to; mu brought to the reference temperature by the law the trend learned),
or the rig file when no trend is given. Without a temperature message younger than
``temperature_timeout`` the oil temperature is the thermal model's estimate from the drive's losses
(a cold start at the settings' ambient when the node starts).
"""
from __future__ import annotations

import math
import time

from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import Temperature
from worm_msgs.msg import GearboxHealth, RigSamples

from worm_model.health.assess import Z95, assess_trend, baseline_of
from worm_model.health.live import LiveHealth, LiveReference
from worm_model.health.record import read_trend
from worm_model.health.settings import load_settings
from worm_model.physics.parameters import load_rig
from worm_model.rig_data.samples import batch_problem
from worm_model.ros.diagnostics import ERROR, OK, WARN, Diagnostics
from worm_model.ros.lifecycle import run_node
from worm_model.cli.node_options import RIG_FILE
from worm_model.ros.parameters import declare, declare_option
from worm_model.ros.qos import STREAM

LEVELS = {"OK": (GearboxHealth.LEVEL_OK, OK), "WARN": (GearboxHealth.LEVEL_WARN, WARN),
          "ERROR": (GearboxHealth.LEVEL_ERROR, ERROR)}


class HealthMonitorNode(Node):
    def __init__(self) -> None:
        super().__init__("health_monitor")
        rig_file = declare_option(self, RIG_FILE)
        trend_file = declare(self, "trend_file", "",
                             "The gearbox's trend (worm_gearbox_health_trend, written by health_check): its latest "
                             "check is the reference; empty = the rig file's values over the load motors' range.")
        settings_file = declare(self, "settings_file", "",
                                "Health settings YAML (worm_gearbox_health_settings: window, limits, thermal "
                                "model); empty = the defaults.")
        period = declare(self, "publish_period", 0.2,
                         "Period [s] of the processing of the queued samples and of the health message.",
                         low=0.01, high=10.0)
        self.temperature_timeout = declare(self, "temperature_timeout", 5.0,
                                           "A temperature message older than this [s] is not used (the estimate "
                                           "takes over).", low=0.1, high=3600.0)
        sample_rate = declare(self, "sample_rate", 1000.0, "Rig sample rate [Hz].", low=1.0, high=100000.0)
        self.rig = load_rig(rig_file or None)
        self.settings = load_settings(settings_file or None)
        if trend_file:
            trend = read_trend(trend_file)
            if not trend.records:
                raise ValueError(f"{trend_file}: the trend holds no check yet (run health_check first)")
            assess_trend(trend.records, self.settings, self.rig)
            reference = LiveReference.from_check(trend.records[-1], baseline_of(trend.records, self.settings,
                                                                                self.rig))
        else:
            reference = LiveReference.from_rig(self.rig, self.settings)
        self.core = LiveHealth(self.rig, reference, self.settings, 1.0 / sample_rate)
        self.pub = self.create_publisher(GearboxHealth, "health", STREAM)
        self.create_subscription(RigSamples, "rig/samples", self.on_samples, STREAM)
        self.create_subscription(Temperature, "oil_temperature", self.on_temperature, STREAM)
        self.queue: list[RigSamples] = []
        self.temperature: tuple[float, float] | None = None  # (degC, monotonic time received)
        self.received = 0
        self.malformed = 0
        self.last_stamp = None
        self.create_timer(period, self.process)
        self.diagnostics = Diagnostics(self, self.report)
        self.level = "OK"
        self.get_logger().info(f"watching against the {reference.source} (mu scale {reference.parameters.mu_scale:.3f} "
                               f"at {reference.law.reference:g} degC, k = {reference.law.mu_per_kelvin:+.4f}/K)")

    def on_samples(self, batch: RigSamples) -> None:
        problem = batch_problem(batch, ("omega_worm", "current_drive", "tau_load", "theta_worm"))
        if problem:
            self.malformed += 1
            self.get_logger().warning(f"ignored a /rig/samples message (first_seq {batch.first_seq}): {problem}",
                                      throttle_duration_sec=1.0)
            return
        if len(batch.omega_worm):
            self.queue.append(batch)

    def on_temperature(self, msg: Temperature) -> None:
        if math.isfinite(msg.temperature):
            self.temperature = (float(msg.temperature), time.monotonic())

    def process(self) -> None:
        """Run the queued batches through the monitor; publish its estimate (and /diagnostics on a new level)."""
        if not self.queue:
            return
        batches, self.queue = self.queue, []
        fresh = self.temperature is not None and time.monotonic() - self.temperature[1] < self.temperature_timeout
        for b in batches:
            n = len(b.omega_worm)
            self.received += n
            gear = b.theta_gear if len(b.theta_gear) == n else None
            self.core.add(b.omega_worm, b.current_drive, b.tau_load, b.theta_worm, gear,
                          [self.temperature[0]] * n if fresh else None)
        last = batches[-1]
        stamp = Time.from_msg(last.header.stamp).nanoseconds + int(round((len(last.omega_worm) - 1)
                                                                         * last.sample_period * 1e9))
        self.publish(Time(nanoseconds=stamp).to_msg(), last.header.frame_id)

    def publish(self, stamp, frame_id: str) -> None:
        st = self.core.status
        msg = GearboxHealth(level=LEVELS[st.level][0], message=st.message, reference=self.core.reference.source,
                            mu_change=st.mu_change.value, mu_change_ci=Z95 * st.mu_change.sigma,
                            friction_excess=st.friction_excess.value, friction_excess_ci=Z95 * st.friction_excess.sigma,
                            mu_scale_reference=self.core.reference.parameters.mu_scale,
                            oil_temperature=st.oil_temperature.value,
                            oil_temperature_ci=Z95 * st.oil_temperature.sigma,
                            temperature_measured=st.temperature_source == "measured", backlash=st.backlash.value,
                            backlash_ci=Z95 * st.backlash.sigma, window=st.window, window_blocks=st.blocks,
                            speed=st.speed, load=st.load, outside=st.outside)
        msg.header.stamp = stamp
        msg.header.frame_id = frame_id
        self.pub.publish(msg)
        if st.level != self.level:
            self.level = st.level
            self.get_logger().warning(f"{st.level}: {st.message}") if st.level != "OK" else \
                self.get_logger().info(f"OK: {st.message}")
            self.diagnostics.publish()

    def report(self) -> tuple[bytes, str, dict]:
        st = self.core.status
        values = {"reference": self.core.reference.source, "samples": self.received,
                  "malformed_messages": self.malformed, **st.values()}
        return LEVELS[st.level][1], st.message, values


def main(args=None) -> int:
    return run_node(HealthMonitorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
