"""Recorded runs: ``recorder``, the recorder's plain-Python core (which topics, their classes and offered QoS,
what it lost), whose ROS shell is ``nodes/recorder_node.py``; ``bag_folder``, the folder a recording goes into
(a new one; beside the bag of a recorder that was killed); ``bag_cli``, the ``bag`` command (info, echo, export
to the rig-data CSV, import from it) over the bags the recorder and the real rosbag2 write."""
