"""Per-sample processing of live rig streams: ``live_model`` (LiveModel, model_node's and replay's
core) and the causal ``filters`` it uses. Plain Python, no ROS."""
