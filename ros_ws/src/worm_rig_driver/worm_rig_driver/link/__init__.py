"""The driver's link to the real rig: ``core`` (state machine, limits, statistics; no I/O),
``serial_link`` (a reader thread owning the port), ``rig_peer`` (a Python rig on a pty for tests)."""
