"""worm_rig_driver: the rig on the ROS graph, real (serial + firmware) or simulated.

Map (dependencies point up this list; only ``nodes`` and ``fil.commander_node`` import rclpy):

============  =================================================================
``errors``    every error of the package (bad input subclasses worm_model.errors.InputError)
``protocol``  the serial protocol as one table (``table``: frames, fields, units,
              scales; generates the firmware header and docs/protocol.md), its
              codec (COBS + CRC-16) and the raw-unit <-> SI ``scaling``
``link``      the driver's core: link state machine, limits, telemetry -> SI
              (``core``), bound to a serial port by a reader thread
              (``serial_link``); ``rig_peer``: a Python rig on a pty for tests
``sim``       the simulated rig: ``plant`` (motor + worm gearbox + load motors),
              ``sensors`` (ADC chain, tachos, encoders), ``effects`` (what the
              model lacks, as plug-ins), ``simulated_rig`` (all of it on the sample
              clock), ``virtual_rig`` (the simulated rig behind a pty speaking the
              firmware protocol)
``drive``     the rig's 1 kHz speed loop, run where the rig is (sim_node's clock thread,
              driver_node's serial reader): the PI law (``speed_loop``), the command
              modes, watchdog and latency accounting (``rig_loop``), real-time
              scheduling (``realtime``)
``fil``       the real firmware in simavr, closed through the simulated plant
              (``harness``, ``run`` = ``make fil``, ``commander_node``)
``recording`` the recorder's core (``recorder``: topics, QoS, loss report; ``bag_folder``: the folder
              a recording goes into, beside a killed recorder's bag) and the ``bag`` command over
              recorded runs (``bag_cli``)
``robot``     what a robot's stack sees of a drive: the standard outputs' trusted load
              (``standard_outputs``), several rigs merged into one JointState (``joint_states``)
``nodes``     sim_node, driver_node, recorder_node, joint_state_merger: the executables' ROS
              shells; the rig's and the estimate's topics
============  =================================================================

``firmware/`` beside this package is the ATmega2560 firmware (AVR C).
Reading and writing bags and rig-data CSV is ``worm_model.bags`` and ``worm_model.rig_data``.
Read first: ``sim/simulated_rig.py`` (what a rig sample is), then
``protocol/table.py`` and ``link/core.py`` for the real rig.
"""
