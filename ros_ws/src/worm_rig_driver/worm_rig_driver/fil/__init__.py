"""Firmware in the loop: ``harness`` (simavr via ctypes + the plant), ``run`` (``make fil``),
``commander_node`` (drives the rig through driver_node during a run)."""
