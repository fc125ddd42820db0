"""The executables' ROS shells: sim_node, driver_node, recorder_node."""
