"""Per-sample processing of live rig streams: ``live_model`` (LiveModel, model_node's and replay's
core), the causal ``filters`` it uses, and ``model_node_options`` (model_node's parameters as data, which
replay reads too). Plain Python, no ROS."""
