"""Estimators of the load torque tau_d: ``base`` (interface, flags), ``registry`` (by name),
``knn``, ``extended_model``, ``database`` (the calibration map they read), ``live``
(per-sample front end), ``quasi_static`` (inertia compensation)."""
