"""Making a calibration database: ``batch`` (the grid on the simulator), ``live`` and
``calibration_node`` (point by point on a live graph), ``journal`` (resumable runs),
``operating_points`` (steady-state measurement), ``calibrate`` (the CLI)."""
