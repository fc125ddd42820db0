"""rosbag2 bags without rclpy (the recorder's core, the readers of ``bag``, ``replay`` and ``residuals``).

``reader`` (BagReader: sqlite3 and MCAP, metadata v4-9, split, zstd), ``writer``
(BagWriter: what the recorder writes), ``typestore`` (message definitions and CDR
decoding), ``seq_check`` (lost or repeated samples from ``seq``), ``message_yaml``
(``ros2 topic echo``-style YAML), ``topic_names`` (whether a name can be a topic). Start with
``reader``.
"""
