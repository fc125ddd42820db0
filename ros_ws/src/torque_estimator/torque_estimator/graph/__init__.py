"""Running the node graph: ``runner`` (every node of one parameter file, one process each),
``run_graph`` (its CLI), ``replay`` (the graph's cores over a recorded bag, no DDS)."""
