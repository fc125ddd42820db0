"""The executables' ROS shells: estimator_node, controller_node."""
