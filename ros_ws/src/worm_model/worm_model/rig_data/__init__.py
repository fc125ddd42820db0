"""Measured rig data: the ``worm_rig_data`` CSV schema and its conversion to and from bags.

=================  ==============================================================
``schema``         the CSV schema, :class:`MeasuredData`, CSV reader and writer
``reader``         :func:`read_rig_data`: the one entry for CSV files and bags
``plausibility``   rig data and calibration points against the rig: sample rate, units, angle
``bags``           RigSample bags <-> MeasuredData (``bag export`` / ``bag import``)
``samples``        the rig's sample streams as recorded (RigSample or RigSamples batches)
=================  ==============================================================

Start with :mod:`~worm_model.rig_data.schema`. Bags themselves (rosbag2 layouts,
reading, writing) are :mod:`worm_model.bags`; the ``bag`` command is
``worm_rig_driver.recording.bag_cli``.
"""
from worm_model.rig_data.reader import read_rig_data
from worm_model.rig_data.schema import MeasuredData, RigDataError, read_rig_csv, write_rig_csv

__all__ = ["MeasuredData", "RigDataError", "read_rig_csv", "read_rig_data", "write_rig_csv"]
