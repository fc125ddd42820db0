"""The paper's experiment and the demo: ``evaluation`` + ``evaluate`` (held-out Table 3),
``scenario``, ``closed_loop``, ``run_analysis``, ``plots``, ``demo`` (+ its ROS shell
``scenario_node``)."""
