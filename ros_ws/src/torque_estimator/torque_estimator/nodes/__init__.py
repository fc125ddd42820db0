"""The executables' ROS shells: ``estimator_node``, ``controller_node``; ``composed`` runs several
nodes of a graph in one process (run_graph --together)."""
