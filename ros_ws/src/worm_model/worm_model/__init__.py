"""worm_model: the worm gearbox's model (paper Eqs 19-30) and the data it is checked against.

Map (dependencies point up this list, never down; no module imports rclpy
outside ``ros/`` and ``nodes/``):

============  =================================================================
``errors``    every error of the package; bad input is an ``InputError`` (one line, exit 2)
``cli``       what every command-line tool shares: bad input as one line and exit 2
              (``errors``), checked options (``options``), progress bars
``files``     a user's files: ``reading`` (text, YAML, JSON, every refusal one line),
              ``writing`` (never over a user's file without --force, atomic outputs)
``physics``   the model itself: rig parameters (one YAML file, a source for every
              number), friction mu, modes and flanks, efficiencies, internal forces
              (Eqs 21-23), coupled dynamics (Eq 28), PMDC motor (Eq 29), steady state
``live``      per-sample processing for live streams (LiveModel: one sample in,
              the mesh's forces out; causal filters), shared by model_node and replay
``bags``      rosbag2 bags without rclpy: reader (every layout since Foxy), writer,
              message types, sequence-gap checks, ros2-topic-echo-style YAML
``rig_data``  measured rig data: the ``worm_rig_data`` CSV schema and the one reader
              of CSV files, bags and EPOS Studio exports (``read_rig_data``); the ``bag``
              command
``effects``   the one vocabulary of the effects the model lacks (name, parameters,
              units, defaults), the ``worm_rig_effects`` file, the oil law and the
              mesh heat; the simulator, ``residuals`` and ``health`` read it
``residuals`` closing the loop with measured data: fit, residual, effects, report
``health``    watching the gearbox's wear: the friction model with mu's temperature law,
              the check's fit, the trend and its baseline, the thermal estimate, the
              live window (torque_estimator.health: the CLI and the node)
``calc``      ``worm_calc``: one operating point through the model; ``rig_from_datasheet``:
              a rig file from a gear catalogue and a motor datasheet
``figures``   ``report``: the paper's Figures 6-11 from a calibration
``ros``       what every node of the project shares (QoS, parameters, diagnostics,
              lifecycle, ament lookup), and what tests and benchmarks share (DDS
              probes, two network namespaces as two hosts)
``nodes``     model_node, the ROS shell over ``live``
============  =================================================================

Read first: ``physics/parameters.py`` (the rig and its units), then
``physics/internal_forces.py`` (Eqs 21-23) and ``physics/dynamics.py`` (Eq 28).
Signs everywhere: positive worm rotation is the reference; the load torque
tau_d on the gear shaft is positive when it opposes positive rotation.
"""
