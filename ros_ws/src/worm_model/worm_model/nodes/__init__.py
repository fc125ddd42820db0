"""ROS 2 shell support shared by the project's nodes (the only rclpy code besides *_node.py)."""
