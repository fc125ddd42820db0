"""The QoS profiles of the graph: sensor-data for streams, reliable for commands."""
from __future__ import annotations

from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.qos import HistoryPolicy, ReliabilityPolicy, DurabilityPolicy

#: Streams (samples, estimates, forces, commands at the sample rate): the sensor-data
#: profile (best effort, volatile) with a deeper queue: a 1 kHz rig delivers samples in
#: bursts (the sim: 5 per 5 ms tick), and depth 5 drops them whenever a reader is late.
STREAM = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=qos_profile_sensor_data.reliability,
                    durability=qos_profile_sensor_data.durability)

#: Publishers of occasional commands and set-points: reliable, latched for late joiners.
COMMAND = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)

#: Subscriptions to commands and set-points: reliable but volatile, so every ordinary
#: publisher reaches them (``ros2 topic pub`` offers volatile; a transient-local
#: subscription would refuse it as incompatible). A volatile subscription gets no
#: history: worm_model.ros.commands pairs it with a transient-local one for that.
COMMAND_IN = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
