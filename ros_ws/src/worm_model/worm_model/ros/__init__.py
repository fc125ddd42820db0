"""ROS 2 shell support shared by every node of the project: QoS profiles (``qos``), parameter
declaration with descriptions and ranges (``parameters``), /diagnostics (``diagnostics``),
one node per process with a clean shutdown (``lifecycle``), the ament prefixes and
executables (``ament``), and helpers for tests over DDS (``testing``)."""
