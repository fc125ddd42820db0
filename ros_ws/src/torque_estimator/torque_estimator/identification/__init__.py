"""Identification: the fast road to a working estimator on a new rig (one short run, no grid).

Map (dependencies point up this list; rclpy only in ``identify_node``):

================  ============================================================
``excitation``    the timeline of speed and load set-points (<= 90 s of rig time)
``recording``     walking the timeline on the rig's sample clock, recording every
                  sample, the resumable journal
``simulated``     the excitation on the simulated rig in-process (tests, evaluate, bench)
``fit``           the rig's uncertain parameters and the effects, by worm_model's
                  residual analysis; the extended rig file with its ``identification:``
``identify_node`` the ROS shell of a live run (set-points out, /rig/samples in)
``identify``      the ``identify`` CLI (live or ``--from`` a log)
================  ============================================================

Read first: ``excitation`` (what the rig is asked to do), then ``fit`` (what is fitted, why).
"""
