"""The drive's 1 kHz speed loop, run where the rig is (sim_node, driver_node; the firmware's
place on a drive that hosts it): ``speed_loop`` (the PI law, vectorised and scalar),
``rig_loop`` (command modes, watchdog, latency accounting), ``command_owner`` (one publisher at a time
drives the motor), ``rig_node_options`` (the parameters sim_node and driver_node share, as data),
``feedforward_plugin`` (finds the
load estimator the rig runs beside its PI, by entry point), ``realtime`` (SCHED_FIFO for the
loop's thread where the OS allows it). Plain Python, no ROS."""
