"""The executables' ROS shells: ``sim_node`` (the simulated rig), ``driver_node`` (the real rig
over serial), ``recorder_node`` (the bag recorder), ``joint_state_merger`` (several rigs as one
robot's JointState), ``rig_topics`` (the topics and commands sim_node and driver_node share) and
``estimate_topics`` (the topics of a load estimate: worm_msgs/TorqueEstimate and the standard
outputs, for the rig nodes and estimator_node alike)."""
