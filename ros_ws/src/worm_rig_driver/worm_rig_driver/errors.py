"""worm_rig_driver's errors, every one in this module.

================  =================================================================
``CodecError``    a frame that cannot be encoded (protocol.codec; a ValueError: the rig's bytes, not a user's)
``CobsError``     bytes that are not a valid COBS encoding (protocol.codec)
``FilError``      the firmware harness could not start, or the simulated AVR stopped (fil; a RuntimeError)
``FeedforwardUnavailable``  no package provides the rig feedforward a node asks for (a RuntimeError: what is
                  installed, not the user's input)
================  =================================================================
"""
from __future__ import annotations


class CodecError(ValueError):
    """A frame cannot be encoded (unknown type, wrong or out-of-range field values)."""



class CobsError(ValueError):
    """Bytes that are not a valid COBS encoding."""



class FilError(RuntimeError):
    """The harness could not start, or the simulated AVR stopped."""



class FeedforwardUnavailable(RuntimeError):
    """No rig feedforward could be built (drive.feedforward_plugin); the message says why, in one line."""


__all__ = ["CobsError", "CodecError", "FeedforwardUnavailable", "FilError"]
