"""``worm_calc``: one worm-gear operating point through the model (``calculator`` core, ``worm_calc`` CLI)."""
