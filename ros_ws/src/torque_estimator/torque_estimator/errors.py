"""torque_estimator's errors, every one in this module.

Bad input is a worm_model.errors.InputError (one line, exit 2, through worm_model.cli.errors.run_tool).

=======================  ==========================================================
``CalibrationError``     a calibration database or file (estimation.database)
``JournalError``         a resumable journal, of a calibration or an identification
``IdentificationError``  a record ``identify`` cannot fit (identification.fit)
``GraphError``           a graph file, or an executable it names (graph)
``ReplayError``          a bag, parameter file or calibration ``replay`` cannot use
``LiveRigError``         a live graph without what a session on the rig needs (a RuntimeError: the
                         graph's state, not the user's input)
``RealDataMissing``      the real drive's data not in this tree (a RuntimeError)
=======================  ==========================================================
"""
from __future__ import annotations

from worm_model.errors import InputError


class CalibrationError(InputError):
    """A calibration database or file is invalid; the message names the field."""



class JournalError(CalibrationError):
    """A journal (a calibration's or an identification's) cannot be used: unreadable, another format, other
    settings, or one that exists without --resume; the message says why."""



class IdentificationError(InputError):
    """The record cannot be fitted (too short, too slow, nothing identifiable); the message says what to change."""



class GraphError(InputError):
    """A graph file or executable problem, naming the file or node."""



class LiveRigError(RuntimeError):
    """The graph does not provide what a live calibration needs; the message names the topic or node."""



class ReplayError(InputError):
    """A bad bag, parameter file or calibration; the message names it."""



class RealDataMissing(RuntimeError):
    """The real drive's data, reader or rig file are not in this tree (health.real_drive)."""


__all__ = ["CalibrationError", "GraphError", "IdentificationError", "JournalError", "LiveRigError", "RealDataMissing",
           "ReplayError"]
