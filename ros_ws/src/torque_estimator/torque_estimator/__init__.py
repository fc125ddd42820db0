"""torque_estimator: the load torque without a torque sensor, and what it is for (feedforward).

Map (dependencies point up this list; rclpy only in ``nodes`` and the two
``*_node.py`` helpers beside the CLIs that talk to a live graph):

==============  ===============================================================
``estimation``  the estimators behind one interface (``base``: inputs, outputs,
                flags; ``registry``: name -> factory): ``knn`` (the paper's k-NN),
                ``extended_model`` (inverts the identified model); the calibration
                ``database`` they read; ``live`` (LiveEstimator: per-sample front
                end, matched filters, inertia compensation); ``quasi_static``
``control``     the speed PI with load-torque feedforward, and the rule for which
                estimate may be fed forward
``calibration`` making a calibration: grid and batch run on the simulator
                (``batch``), point by point on a live graph (``live``,
                ``calibration_node``), the resumable ``journal``, the steady-state
                ``operating_points``, the ``calibrate`` CLI
``identification`` the fast road: one short excitation (``excitation``, ``recording``,
                live over the graph by ``identify_node``, in-process by ``simulated``), the
                fit of the rig's uncertain parameters and effects (``fit``), the ``identify`` CLI
``experiment``  the paper's experiment and the demo: held-out ``evaluation`` and
                ``evaluate`` CLI, ``scenario`` timelines, ``closed_loop`` (the graph's
                loop in one process), ``run_analysis``, ``plots``, ``demo``; ``estimate``
                (any estimator over a log, scored against its tau_load); ``identified``
                (identify vs the k-NN grid on the simulator, for evaluate and bench)
``graph``       running the node graph: ``runner`` (start nodes from one parameter
                file), ``run_graph`` CLI, ``replay`` (the graph's cores over a bag)
``nodes``       estimator_node, controller_node, and ``composed`` (several nodes in one
                process on one executor: run_graph --together)
==============  ===============================================================

Read first: ``estimation/base.py`` (what an estimator is), ``estimation/knn.py``
(the paper's method), ``estimation/live.py`` (what the node does per sample).
"""
import os as _os

# One BLAS thread for numpy in every process of this package (set before numpy loads: this module is
# imported first by every executable and node here). The estimators' matrices are 7x7 and per sample;
# OpenBLAS's worker threads only add wake-ups, and on a busy 2-core machine a matrix exponential took
# 3-40 ms with them against ~0.4 ms without (bench/observer_bench.py). A value the user set stands.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
