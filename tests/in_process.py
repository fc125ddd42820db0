"""A tool's ``main(argv)`` run in the test's own process, as its console script calls it: the same code without a
Python start per run (the bad-input properties and the round trip run tools hundreds of times)."""
from __future__ import annotations

import contextlib
import io
import os
import signal
from collections.abc import Callable, Sequence
from pathlib import Path


def run_main(main: Callable[[list[str]], int], argv: Sequence[str], cwd: Path) -> tuple[int, str, str]:
    """``main(argv)`` in ``cwd``: (exit code, stdout, stderr); SIGINT/SIGTERM handlers restored after."""
    out, err = io.StringIO(), io.StringIO()
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    here = os.getcwd()
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(argv))
            except SystemExit as exit_:
                code = exit_.code if isinstance(exit_.code, int) else 1
    finally:
        os.chdir(here)
        for s, h in handlers.items():
            signal.signal(s, h)
    return code, out.getvalue(), err.getvalue()
