"""The ROS shell of a live ``health_check``'s temperature: what the graph says about the oil, before and after the run.

The run itself is driven by session.recording_node (the same machinery as ``identify``); this
only listens, for up to ``timeout`` seconds, for a sensor_msgs/Temperature on the oil's topic (a
sensor) and for the live monitor's worm_msgs/GearboxHealth (its estimate from the drive's losses).
"""
from __future__ import annotations

import math
import time

import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Temperature
from worm_msgs.msg import GearboxHealth

from worm_model.ros.qos import STREAM


def listen_temperature(temperature_topic: str, health_topic: str, timeout: float) -> tuple[str, float, float] | None:
    """("measured" | "estimated", degC, standard uncertainty [K]) from the graph, or None if nothing came.

    A sensor's reading wins (its variance, if given, is used); the monitor's estimate is taken only if no
    sensor spoke within ``timeout`` [s].
    """
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = Node("health_check_temperature")
    found: dict[str, tuple[float, float]] = {}

    def on_sensor(msg: Temperature) -> None:
        if math.isfinite(msg.temperature):
            found["measured"] = (float(msg.temperature), math.sqrt(msg.variance) if msg.variance > 0 else math.nan)

    def on_health(msg: GearboxHealth) -> None:
        if math.isfinite(msg.oil_temperature):
            found["measured" if msg.temperature_measured else "estimated"] = (
                float(msg.oil_temperature), float(msg.oil_temperature_ci) / 1.96)

    node.create_subscription(Temperature, temperature_topic, on_sensor, STREAM)
    node.create_subscription(GearboxHealth, health_topic, on_health, STREAM)
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and "measured" not in found:
            rclpy.spin_once(node, timeout_sec=0.05)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    for source in ("measured", "estimated"):
        if source in found:
            return source, *found[source]
    return None


__all__ = ["listen_temperature"]
