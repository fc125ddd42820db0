"""What a robot's stack sees of a drive, beside the rig's own types (no ROS in these modules).

``standard_outputs``  which load estimates sensor_msgs/JointState and geometry_msgs/WrenchStamped
                      carry (the trusted ones; NaN at once otherwise) and why
``joint_states``      several rigs' sample streams onto one sensor_msgs/JointState per tick, as
                      ros2_control's joint_state_broadcaster publishes a robot's joints
"""
