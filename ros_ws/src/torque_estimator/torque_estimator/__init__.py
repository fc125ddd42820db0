"""torque_estimator: the load torque without a torque sensor, and what it is for (feedforward).

Map (dependencies point up this list; rclpy only in ``nodes`` and the ``*_node.py``
helpers beside the CLIs that talk to a live graph):

==================  ===========================================================
``errors``          every error of the package (bad input subclasses worm_model.errors.InputError)
``estimation``      the estimators behind one interface (``base``: inputs, outputs,
                    flags, the streaming protocols; ``registry``: name -> factory and
                    options): ``observer`` (a folder: the shipped default, a Kalman
                    filter on the model with a step detector), ``knn`` (the paper's
                    k-NN map), ``extended_model`` (inverts the identified model); the
                    calibration ``database`` they read; ``settings`` (what every
                    caller builds its estimator from, and the one builder); ``live``
                    (LiveEstimator: the per-sample front end every node, replay and
                    study runs); ``quasi_static``, ``calibration_bias``
``joints``          a robot's JointState in, one estimator per joint (``settings``: the
                    per-joint files and which methods need no voltage; ``estimators``)
``control``         what feeds the load forward: ``feedforward`` (which estimate may
                    be fed forward, and when it is too old), ``rig_feedforward`` (the
                    estimator the rig runs beside its speed PI; the PI itself is
                    ``worm_rig_driver.drive``)
``session``         a session with the rig, what calibration, identification and the
                    health check share: the client node and its waits
                    (``rig_session_node``), the timeline's ``recording`` and its
                    journal, its ROS shell (``recording_node``), the ``resume`` rule,
                    the rig's ``topics``
``calibration``     making a calibration: grid and batch run on the simulator
                    (``batch``), point by point on a live graph (``live``,
                    ``calibration_node``), the resumable ``journal``, the steady-state
                    ``operating_points``, the ``calibrate`` CLI
``identification``  the fast road: one short excitation (``excitation``, recorded by session,
                    live over the graph by session's ``recording_node``, in-process by
                    ``simulated``), the fit of the rig's uncertain parameters and
                    effects (``fit``), the ``identify`` CLI
``offline``         the estimators over recorded data: ``estimate`` (any log, scored
                    against its tau_load), ``replay`` (the graph's cores over a bag)
``evaluation``      ``make evaluate``'s studies: ``held_out`` (Table 3), ``transient``,
                    ``identified``, ``observer_study``, ``residual_cases``,
                    ``closed_loop``, ``real_drive`` (a real drive's measurements), the
                    ``scenario`` timelines they and the demo play; the ``evaluate`` CLI
``demo``            ``make demo``: the demo's scenario played on the live graph
                    (``scenario_node``), ``run_analysis``, ``plots``, the ``demo`` CLI
``health``          watching the gearbox: the ``health_check`` CLI (a short reference
                    run against the gearbox's baseline and trend), ``health_monitor``
                    (the live window on /diagnostics), the simulated checks and the
                    study of how soon and how often wrong (worm_model.health: the core)
``graph``           running the node graph: ``runner`` (start nodes from one
                    parameter file), the ``run_graph`` CLI
``nodes``           estimator_node, controller_node, and ``composed`` (several nodes
                    in one process on one executor: run_graph --together)
==================  ===========================================================

Read first: ``estimation/base.py`` (what an estimator is), ``estimation/live.py`` (what
estimator_node does with every sample), then ``estimation/observer/`` (the shipped
estimator; its map, then ``kalman.py``) or ``estimation/knn.py`` (the paper's method).
"""
import os as _os

# One BLAS thread for numpy in every process of this package (set before numpy loads: this module is
# imported first by every executable and node here). The estimators' matrices are 7x7 and per sample;
# OpenBLAS's worker threads only add wake-ups, and on a busy 2-core machine a matrix exponential took
# 3-40 ms with them against ~0.4 ms without (bench/observer_bench.py). A value the user set stands.
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
