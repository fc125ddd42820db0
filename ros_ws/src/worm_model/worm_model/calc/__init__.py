"""One worm-gear operating point through the model (``calculator`` core, ``worm_calc`` CLI), and a rig file from a
drive's datasheet (``datasheet``: the ``rig_from_datasheet`` CLI)."""
