"""The QoS profiles of the graph: sensor-data for streams, reliable for commands."""
from __future__ import annotations

from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.qos import HistoryPolicy, ReliabilityPolicy, DurabilityPolicy

#: Streams (samples, estimates, forces, commands at the sample rate): best effort, keep last.
STREAM = qos_profile_sensor_data

#: Occasional commands and set-points: reliable, latched for late joiners.
COMMAND = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
