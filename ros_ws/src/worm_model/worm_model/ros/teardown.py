"""A bounded end for a node process: rclpy's teardown gets a deadline it cannot ignore.

Why: rclpy's teardown (``destroy_node``, the context's shutdown) can block for good
inside the middleware. CI on a busy 2-core machine saw it about once in 150 node stops:
estimator_node, after SIGINT, stuck in ``Node.destroy_node`` (rclpy's node handle ->
``rcl_node_fini``) until it was killed (the same class of hang is reported for
rclpy with Fast DDS, e.g. ros2/rclpy#456 and ros2/build_cop#248). By the time the
teardown starts, a node asked to stop has done its part: spinning stopped, files
closed, the rig told to stop. What the teardown has left to do frees DDS resources
the OS frees at exit anyway (peers drop the participant when its lease ends). So a
node process gives it :data:`TEARDOWN_LIMIT_S`; past that, every thread's stack goes
to stderr (where it was stuck, for a bug report) and the process ends with the exit
code it would have returned.

The deadline is kept by threads that need no Python: a thread stuck in C code may
hold the GIL, so a Python watchdog thread might never run. faulthandler's watchdog
thread prints the stacks; a POSIX timer (``timer_create`` with ``SIGEV_THREAD``)
calls libc's ``_exit(code)`` from a thread of libc's own. Where that timer is not
available (not glibc), faulthandler ends the process itself, with exit code 1.
Plain Python (ctypes); no ROS.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import faulthandler
import sys
from collections.abc import Iterator
from contextlib import contextmanager

#: How long a node process gives rclpy's teardown [s]: sim_node's clock thread takes up
#: to 2 s to join, a normal DDS teardown well under 1 s even on a loaded machine.
TEARDOWN_LIMIT_S = 5.0
#: After the stacks are printed, how long before the process ends [s] (time to write them).
_EXIT_AFTER_DUMP_S = 0.5

_SIGEV_THREAD = 2  # <bits/sigevent-consts.h>, Linux
_CLOCK_MONOTONIC = 1


class _Sigval(ctypes.Union):
    _fields_ = [("sival_int", ctypes.c_int), ("sival_ptr", ctypes.c_void_p)]


class _Sigevent(ctypes.Structure):
    """``struct sigevent`` of glibc on 64-bit Linux (64 bytes), SIGEV_THREAD members."""
    _fields_ = [("sigev_value", _Sigval), ("sigev_signo", ctypes.c_int), ("sigev_notify", ctypes.c_int),
                ("sigev_notify_function", ctypes.c_void_p), ("sigev_notify_attributes", ctypes.c_void_p),
                ("_pad", ctypes.c_int * 8)]


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [("it_interval", _Timespec), ("it_value", _Timespec)]


def _libc_with_timers() -> ctypes.CDLL | None:
    """libc (glibc >= 2.34 holds timer_create) or librt before it; None off Linux/glibc."""
    if not sys.platform.startswith("linux") or ctypes.sizeof(ctypes.c_void_p) != 8:
        return None
    for name in (None, ctypes.util.find_library("rt")):
        try:
            lib = ctypes.CDLL(name, use_errno=True)
            lib.timer_create  # noqa: B018 (present?)
            return lib
        except (OSError, AttributeError):
            continue
    return None


class _ExitTimer:
    """A one-shot POSIX timer that calls ``_exit(code)`` in a libc thread after ``seconds``."""

    def __init__(self, lib: ctypes.CDLL, seconds: float, code: int) -> None:
        self._lib = lib
        self._timer = ctypes.c_void_p()
        event = _Sigevent()
        event.sigev_notify = _SIGEV_THREAD
        # The notify function gets the union sigval by value: in the first integer
        # argument register on x86-64 and aarch64, where _exit reads its int status.
        event.sigev_value.sival_ptr = code & 0xFF
        event.sigev_notify_function = ctypes.cast(lib._exit, ctypes.c_void_p).value
        if lib.timer_create(_CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(self._timer)) != 0:
            raise OSError(ctypes.get_errno(), "timer_create failed")
        whole = int(seconds)
        when = _Itimerspec(it_value=_Timespec(whole, int((seconds - whole) * 1e9)))
        if lib.timer_settime(self._timer, 0, ctypes.byref(when), None) != 0:
            lib.timer_delete(self._timer)
            raise OSError(ctypes.get_errno(), "timer_settime failed")

    def cancel(self) -> None:
        self._lib.timer_delete(self._timer)


@contextmanager
def deadline(status: int, limit: float = TEARDOWN_LIMIT_S) -> Iterator[None]:
    """Run the body; if it has not returned after ``limit`` [s], print every thread's stack
    to stderr and end the process with exit code ``status``.

    Use it around rclpy teardown only, after everything the process must finish is done.
    """
    lib = _libc_with_timers()
    timer: _ExitTimer | None = None
    if lib is not None:
        try:
            timer = _ExitTimer(lib, limit + _EXIT_AFTER_DUMP_S, status)
        except OSError:
            timer = None
    sys.stderr.flush()
    # without the libc timer, faulthandler ends the process itself (status 1)
    faulthandler.dump_traceback_later(limit, exit=timer is None, file=sys.stderr)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
        if timer is not None:
            timer.cancel()


__all__ = ["TEARDOWN_LIMIT_S", "deadline"]
