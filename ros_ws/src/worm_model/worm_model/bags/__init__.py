"""rosbag2 bags without rclpy (the recorder's core, the readers of ``bag``, ``replay`` and ``residuals``).

``reader`` (BagReader: sqlite3 and MCAP, metadata v4-9, split, zstd; the facade that opens, merges and decodes)
over ``metadata`` (``metadata.yaml`` and the copies in storage files), ``bag_files`` (a bag's storage files, their
split order, which plugin reads each, zstd), ``storage`` (what a storage plugin yields), ``storage_sqlite3`` and
``storage_mcap`` (the two plugins) and ``qos`` (offered-QoS comparison, for warnings); ``writer``
(BagWriter: what the recorder writes), ``typestore`` (message definitions and CDR
decoding), ``seq_check`` (lost or repeated samples from ``seq``), ``message_yaml``
(``ros2 topic echo``-style YAML), ``topic_names`` (whether a name can be a topic). Start with
``reader``.
"""
