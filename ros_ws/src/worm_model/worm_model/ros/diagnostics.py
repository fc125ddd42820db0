"""Publish a node's health as diagnostic_msgs/DiagnosticArray on /diagnostics."""
from __future__ import annotations

from typing import Callable

# Levels are the message's own byte constants.

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR


class Diagnostics:
    """Every period, ask `report()` for (level, message, {key: value}) and publish it."""

    def __init__(self, node: Node, report: Callable[[], tuple[bytes, str, dict]], period: float = 1.0) -> None:
        self._node = node
        self._report = report
        self._pub = node.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._timer = node.create_timer(period, self.publish)

    def publish(self) -> None:
        level, message, values = self._report()
        status = DiagnosticStatus(level=level, name=f"{self._node.get_name()}", message=message,
                                  hardware_id=self._node.get_fully_qualified_name(),
                                  values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])
        array = DiagnosticArray(status=[status])
        array.header.stamp = self._node.get_clock().now().to_msg()
        self._pub.publish(array)
