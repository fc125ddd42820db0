"""The paper's experiment and the demo: ``evaluation`` + ``evaluate`` (held-out Table 3),
``scenario``, ``closed_loop``, ``run_analysis``, ``plots``, ``demo`` (+ its ROS shell
``scenario_node``), ``transient`` (estimators through steps, ramps, reversals),
``residual_cases`` (the residuals tool on simulated cases), ``observer_study``."""
