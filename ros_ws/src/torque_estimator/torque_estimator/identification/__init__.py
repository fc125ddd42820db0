"""Identification: the fast road to a working estimator on a new rig (one short run, no grid).

Map (dependencies point up this list; no rclpy: a live run's ROS shell is session.recording_node):

================  ============================================================
``excitation``    the timeline of speed and load set-points (<= 90 s of rig time)
``simulated``     the excitation on the simulated rig in-process (tests, evaluate, bench)
``steady``        the road of a record held at speeds: one point a run, the base
                  unknowns and the terms a cross-fitted selection accepts
``identifiability`` what a record can tell: each parameter's band against its tolerance,
                  its bound, what the record is (held speeds, a torque channel)
``noise``         the sensors' noise as the record shows it
``fit``           both roads (steady points, or worm_model's residual analysis of a time
                  series), the parameters the record pins, the sensors
``writing``       the extended rig file with its ``identification:``, checked readable
``identify``      the ``identify`` CLI (live or ``--from`` a log)
================  ============================================================

Read first: ``excitation`` (what the rig is asked to do), then ``fit`` (what is fitted, why).
"""
