"""Recorded runs: ``bag_cli``, the ``bag`` command (info, echo, export to the rig-data CSV, import from
it) over the bags the recorder (``nodes/recorder_node.py``) and the real rosbag2 write; ``bag_folder``, the
folder a recording goes into (a new one; beside the bag of a recorder that was killed)."""
