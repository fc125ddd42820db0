"""The drive's 1 kHz speed loop, run where the rig is (sim_node, driver_node; the firmware's
place on a drive that hosts it): ``speed_loop`` (the PI law, vectorised and scalar) and
``rig_loop`` (command modes, watchdog, latency accounting). Plain Python, no ROS."""
