"""The demo (``make demo``): the paper's experiment end to end on the simulated rig.

``demo`` (the CLI: calibrate, held-out points, the live graph with feedforward off and on, plots),
``scenario_node`` (plays the demo's scenario on the live graph and records it), ``run_analysis``
(what the recorded bags say: errors, dips, IAE), ``plots`` (the live runs' PNGs).
"""
