"""worm_model's errors, every one in this module: what a tool refuses, and why.

Each bad-input error is an :class:`InputError` (a ValueError: the input's value is wrong), carrying ``where``
(an option, a file, ``file: line 7, column 'x'``) and ``what``; a tool's main (cli.errors.run_tool) turns
any of them into one line on stderr and exit 2, and nothing else into exit 2. The packages above subclass
InputError for their own inputs (worm_rig_driver.errors, torque_estimator.errors).

==========================  ===========================================================
``InputError``              the base: bad input, one line, exit 2
``ParameterError``          a rig (parameter) file: ``file: field: problem`` (physics.parameters)
``EffectsError``            an effects file or mapping: ``file: key: problem`` (effects.file_format)
``RigDataError``            rig data, CSV or bag or EPOS export: ``file: line N, column 'c': problem``
``DirtyRowsError``          an EPOS export's dirty rows, refused (rig_data.epos; ``--skip-bad-rows``)
``ReportError``             ``report``'s calibration file or options
``CalculatorError``         ``worm_calc``'s operating point
``FitError``                a health check's run that cannot be fitted
``TrendError``              a health trend file
``SettingsError``           a health settings file
``OutputError``             an output that may not or cannot be written (files.writing)
``BagRecordingError``       a bag that cannot be read or written; ``BagReadError`` (unreadable),
                            ``TypeDefinitionNotFoundError`` (no message definition), ``BagClosedError``
==========================  ===========================================================
"""
from __future__ import annotations


class InputError(ValueError):
    """Bad input: ``where`` it is (option, file, line, column) and ``what`` is wrong with it.

    ``InputError(message)`` alone: a message that names its own place (``where`` is then empty).
    """

    def __init__(self, where: str, what: str | None = None) -> None:
        if what is None:
            where, what = "", str(where)
        self.where = str(where)
        self.what = what
        super().__init__(f"{self.where}: {what}" if self.where else what)


class ParameterError(InputError):
    """A parameter file (or dict) is unreadable or inconsistent.

    Attributes:
        source: the file (or other origin) that was being read.
        field: dotted name of the offending field ("" if the whole file).
    """

    def __init__(self, source: str, field_name: str, problem: str) -> None:
        self.source = str(source)
        self.field = field_name
        where = f"{self.source}: {field_name}" if field_name else self.source
        super().__init__(where, problem)


class EffectsError(ParameterError):
    """An effects file (or mapping) is unreadable or wrong; the message names file and key.

    A :class:`ParameterError` (same message form, ``source: key: problem``), so number parsing is
    shared with the rig file's loader.

    Attributes:
        source: the file (or other origin) that was being read.
        key: dotted name of the offending key ("" for the whole file).
    """

    @property
    def key(self) -> str:
        return self.field



class RigDataError(InputError):
    """Unreadable or inconsistent rig data; the message names the file, line (1 = header) and column.

    Attributes:
        source: the file (or other origin, e.g. ``bag:/rig/sample``).
        line: 1-based line of the file (1 = header), 0 if not about one line.
        column: the offending column ("" if not about one column).
    """

    def __init__(self, source: str, problem: str, line: int = 0, column: str = "") -> None:
        self.source = str(source)
        self.line = line
        self.column = column
        where = [f"line {line}"] if line else []
        where += [f"column {column!r}"] if column else []
        prefix = f"{self.source}: {', '.join(where)}" if where else self.source
        super().__init__(prefix, problem)



class DirtyRowsError(RigDataError):
    """Dirty rows refused (not ``skip_bad_rows``): the message names the first as ``file: line N: what`` and
    counts them. ``rows``: every dirty row of the file (or folder), rig_data.epos.DirtyRow."""

    def __init__(self, rows: list, files: int = 1, of_files: int = 1) -> None:
        self.rows = rows
        first = rows[0]
        where = "this file" if of_files == 1 else f"{files} of the folder's {of_files} files"
        super().__init__(first.source, f"{first.what} ({len(rows)} dirty row(s) in {where}: refused; "
                                       "--skip-bad-rows leaves them out and reports them)", first.line)



class ReportError(InputError):
    """The calibration file or the options are unusable; the message names the file and field."""



class CalculatorError(InputError):
    """An input of the calculator is out of range; the message names the input."""



class FitError(InputError):
    """The run cannot be fitted (too few steady points); the message says what is missing."""



class TrendError(InputError):
    """A trend file is unreadable or wrong; ``where`` names the file and the line."""



class SettingsError(InputError):
    """A settings file is unreadable or wrong: ``where`` names the file and the key."""



class OutputError(InputError):
    """An output that may not or cannot be written; ``where`` is the option and the user's path."""



class BagRecordingError(InputError):
    """A bag could not be written or read; the message names path/topic/type."""



class TypeDefinitionNotFoundError(BagRecordingError):
    """No definition of a message type in the stock store or the ament prefixes."""



class BagClosedError(BagRecordingError):
    """A write reached a bag that is already closed."""



class BagReadError(BagRecordingError):
    """A bag could not be opened or decoded."""



__all__ = ["BagClosedError", "BagReadError", "BagRecordingError", "CalculatorError", "DirtyRowsError", "EffectsError",
           "FitError",
           "InputError", "OutputError", "ParameterError", "ReportError", "RigDataError", "SettingsError", "TrendError",
           "TypeDefinitionNotFoundError"]
