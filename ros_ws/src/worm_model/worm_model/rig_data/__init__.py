"""Measured rig data: the ``worm_rig_data`` CSV schema, its conversion to and from bags, drive-controller exports.

=================  ==============================================================
``schema``         the CSV schema, :class:`MeasuredData`, CSV reader and writer
``reader``         :func:`read_rig_data`: the one entry for CSV files, bags and EPOS exports
``epos``           EPOS Studio data-recorder exports (Maxon): header, channel table, SI,
                   dirty rows reported and refused or skipped; one steady point per file
``epos_options``   the load options (``--load-torque``, ``--load-mass`` ...) of the tools
                   that read EPOS exports
``plausibility``   rig data and calibration points against the rig: sample rate, units, angle
``bags``           RigSample bags <-> MeasuredData (``bag export`` / ``bag import``)
``samples``        the rig's sample streams as recorded (one per message or batched), in order;
                   :class:`~worm_model.rig_data.samples.RigSample`, the one record of a sample
``estimate``       :class:`~worm_model.rig_data.estimate.Estimate`, the one record of a sample's
                   load estimate, from the estimators to the topics
``joint_states``   a robot's sensor_msgs/JointState as rig samples: joints by name, motor or
                   output side, effort as current or motor torque, stamps checked and counted
=================  ==============================================================

Start with :mod:`~worm_model.rig_data.schema`. Bags themselves (rosbag2 layouts,
reading, writing) are :mod:`worm_model.bags`; the ``bag`` command is
``worm_rig_driver.recording.bag_cli``.
"""
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData, read_rig_csv, write_rig_csv
from worm_model.errors import RigDataError

__all__ = ["MeasuredData", "RigDataError", "read_rig_csv", "read_rig_data", "write_rig_csv"]
