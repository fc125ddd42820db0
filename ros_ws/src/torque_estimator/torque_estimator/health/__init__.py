"""health: watching the gearbox in operation: the health check, the live monitor, and how well they do.

Map (dependencies point up this list; rclpy only in the ``*_node`` modules):

================  ============================================================
``reference``     the check's reference run: a few speeds per direction, held loads
                  (a timeline walked by identification's recording machinery)
``simulated``     checks on the vectorised simulated rig, many side by side
``study``         ``make evaluate``'s health lines: detection and false alarms on
                  simulated lives, and the live monitor on simulated operation
``real_drive``    the check on the real T-RO 2021 drive's data, half its speeds
                  against the other half (skipped while those data are not here)
``check_node``    the oil temperature a live check hears on the graph
``health_check``  the ``health_check`` CLI (live over the graph, or ``--from`` a log)
``monitor_node``  ``health_monitor``: the live monitor on /rig/samples, its
                  ``health`` message and /diagnostics
================  ============================================================

The physics, the fit, the trend and the live core are worm_model.health (plain Python).
Read first: ``reference`` (what a check asks of the rig), then ``health_check``.
"""
