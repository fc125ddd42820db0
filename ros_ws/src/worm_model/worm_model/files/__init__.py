"""A user's files, one policy each way: ``reading`` (regular files only, stat-ed before they are opened;
UTF-8 text with or without a byte-order mark; YAML and JSON with limits on size, nesting and alias
expansion; ROS parameter files checked as rcl will read them) and ``writing`` (an output never is, holds or
lies inside an input; ``--force`` replaces only the same tool's earlier output; written atomically)."""
