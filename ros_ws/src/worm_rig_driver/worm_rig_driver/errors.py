"""worm_rig_driver's errors, every one in this module.

================  =================================================================
``CodecError``    a frame that cannot be encoded (protocol.codec; a ValueError: the rig's bytes, not a user's)
``CobsError``     bytes that are not a valid COBS encoding (protocol.codec)
``FilError``      the firmware harness could not start, or the simulated AVR stopped (fil; a RuntimeError)
``EffectsError``  an effects file: a worm_model.errors.ParameterError, so bad input (one line, exit 2)
``FeedforwardUnavailable``  no package provides the rig feedforward a node asks for (a RuntimeError: what is
                  installed, not the user's input)
================  =================================================================
"""
from __future__ import annotations

from worm_model.errors import ParameterError


class CodecError(ValueError):
    """A frame cannot be encoded (unknown type, wrong or out-of-range field values)."""



class CobsError(ValueError):
    """Bytes that are not a valid COBS encoding."""



class FilError(RuntimeError):
    """The harness could not start, or the simulated AVR stopped."""



class EffectsError(ParameterError):
    """An effects file (or mapping) is unreadable or wrong; the message names file and key.

    A :class:`worm_model.errors.ParameterError` (same message form, ``source: key: problem``),
    so number parsing is shared with the rig file's loader.

    Attributes:
        source: the file (or other origin) that was being read.
        key: dotted name of the offending key ("" for the whole file).
    """

    @property
    def key(self) -> str:
        return self.field



class FeedforwardUnavailable(RuntimeError):
    """No rig feedforward could be built (drive.feedforward_plugin); the message says why, in one line."""


__all__ = ["CobsError", "CodecError", "EffectsError", "FeedforwardUnavailable", "FilError"]
