"""Making a calibration database: ``batch`` (the grid on the simulator), ``live`` and
``calibration_node`` (point by point on a live graph, a session of torque_estimator.session),
``journal`` (resumable runs), ``operating_points`` (steady-state measurement), ``calibrate`` (the CLI)."""
