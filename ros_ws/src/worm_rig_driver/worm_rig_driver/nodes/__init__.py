"""The executables' ROS shells: ``sim_node`` (the simulated rig), ``driver_node`` (the real rig
over serial), ``recorder_node`` (the bag recorder), and ``rig_topics`` (the topics and commands
sim_node and driver_node share)."""
