"""Making a calibration database: ``batch`` (the grid on the simulator), ``live`` and
``calibration_node`` (point by point on a live graph), ``rig_session_node`` (a client's session with
the live rig, shared with identification), ``journal`` (resumable runs),
``operating_points`` (steady-state measurement), ``calibrate`` (the CLI)."""
