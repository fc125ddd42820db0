"""Running the node graph: ``runner`` (every node of one parameter file, one process each, or several
in one), ``run_graph`` (its CLI)."""
