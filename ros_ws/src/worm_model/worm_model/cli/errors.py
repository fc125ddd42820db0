"""How a tool's main ends: bad input as one line and exit 2, Ctrl-C as 130, a bug as a saved traceback.

Every command-line tool of the project refuses bad input the same way: one line on stderr,
``tool: where: what is wrong``, and exit code 2 (:data:`EXIT_BAD_INPUT`); no traceback reaches the
user. Bad input is a :class:`worm_model.errors.InputError` (the loaders' own errors, ParameterError,
RigDataError, torque_estimator's CalibrationError, ..., subclass it: each package's ``errors`` module
holds them all). :func:`run_tool` wraps a tool's main: an InputError -> the one line and exit 2,
Ctrl-C -> 130, anything else -> one line saying it is a bug, the traceback saved to a file.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import tempfile
import traceback
from collections.abc import Callable
from typing import Final

from worm_model.errors import InputError

EXIT_BAD_INPUT: Final = 2
EXIT_INTERRUPTED: Final = 130


def one_line(err: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(err).split()) or type(err).__name__


def _raise_interrupt(signum: int, _frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def _terminate_as_interrupt() -> None:
    """SIGTERM (``kill``, a closed terminal's session) ends a tool as Ctrl-C does: with its cleanup."""
    if threading.current_thread() is threading.main_thread() \
            and signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
        signal.signal(signal.SIGTERM, _raise_interrupt)


def restore_ctrl_c() -> None:
    """Make Ctrl-C raise KeyboardInterrupt again in this process and in those it starts, where SIGINT is ignored.

    A shell without job control starts a background command with SIGINT ignored (`nohup cmd &`, `cmd &` in a
    script, some CI runners); every process below it inherits that, and Python then leaves it ignored. What
    starts tools in order to interrupt them as a terminal's Ctrl-C does (the tests, the bad-input probe) calls
    this first: its own handler back, and the processes it starts begin with SIGINT at its default. Main
    thread only.
    """
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def run_tool(tool: str, main: Callable[[], int]) -> int:
    """Run a tool's ``main`` and turn what escapes it into an exit code and one stderr line.

    InputError (every package's bad-input errors subclass it) -> exit 2;
    KeyboardInterrupt (Ctrl-C, and SIGTERM, which is made to raise it so that temporary outputs are
    removed alike) -> 130; OSError (disk full, ...) -> exit 1; any other exception is a bug: one line
    saying so, the traceback written to a file named in that line, exit 1.
    """
    _terminate_as_interrupt()
    try:
        return main()
    except InputError as err:
        print(f"{tool}: {one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"{tool}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # e.g. `... | head`
        sys.stderr.close()
        return 0
    except OSError as err:  # the machine, not the input: a full disk, a folder gone meanwhile
        what = f"{err.filename}: {err.strerror}" if err.filename and err.strerror else one_line(err)
        print(f"{tool}: {what}", file=sys.stderr)
        return 1
    except Exception as err:  # noqa: BLE001 - reported as a bug, with its traceback kept
        fd, name = tempfile.mkstemp(prefix=f"{tool}-traceback-", suffix=".txt")
        with os.fdopen(fd, "w", encoding="utf-8") as stream:
            stream.write(f"{tool} {' '.join(sys.argv[1:])}\n\n{traceback.format_exc()}")
        print(f"{tool}: internal error (a bug, please report it): {type(err).__name__}: {one_line(err)}; "
              f"traceback in {name}", file=sys.stderr)
        return 1
