"""The bounded teardown of a node process (worm_model.ros.teardown): a teardown stuck in C
code, even one holding the GIL, ends the process with the exit code it would have had,
after printing where it was stuck; a teardown that returns is not cut short."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from worm_model.ros import teardown

SAFETY_TIMEOUT = 60.0  # [s] only so that a broken deadline cannot hang the suite


def run(body: str) -> subprocess.CompletedProcess[str]:
    script = "import ctypes, time\nfrom worm_model.ros.teardown import deadline\n" + textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=SAFETY_TIMEOUT)


@pytest.mark.skipif(teardown._libc_with_timers() is None, reason="needs glibc's POSIX timers")
@pytest.mark.parametrize("status", [0, 3])
def test_a_teardown_stuck_in_c_holding_the_gil_ends_with_the_exit_code_it_would_have_had(status: int) -> None:
    done = run(f"""
        print("stopping", flush=True)
        with deadline({status}, limit=0.3):
            ctypes.PyDLL(None).sleep(600)  # blocks in C and keeps the GIL: no Python thread could act
        print("never")
    """)
    assert done.returncode == status, done.stderr
    assert done.stdout == "stopping\n"
    # where it was stuck: the stack of the blocked thread, at the line of the blocking call
    assert "Timeout (0:00:00.300000)!" in done.stderr and 'File "<string>", line 6' in done.stderr, done.stderr


def test_a_teardown_that_returns_is_not_cut_short() -> None:
    done = run("""
        with deadline(0, limit=0.3):
            time.sleep(0.05)
        time.sleep(1.0)  # well past the limit and the exit timer: both were cancelled
        print("finished")
    """)
    assert (done.returncode, done.stdout, done.stderr) == (0, "finished\n", "")


def test_the_limit_is_the_one_the_readme_states() -> None:
    assert teardown.TEARDOWN_LIMIT_S == 5.0  # README, fault table: "gives the teardown 5 s"
