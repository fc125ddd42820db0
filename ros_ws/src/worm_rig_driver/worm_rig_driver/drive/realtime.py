"""Real-time scheduling for the thread that runs the rig's 1 kHz loop, where the OS allows it.

A motor drive's loop must not wait behind whatever else the computer runs. On
Linux a thread may ask for SCHED_FIFO (what ros2_control's controller manager
asks for its loop); it then runs as soon as it wakes, ahead of every normal
process, for the few microseconds each sample needs. That needs CAP_SYS_NICE
(root, or an rtprio limit in /etc/security/limits.conf); without it the thread
stays at normal priority and says so. The kernel's RT throttling
(sched_rt_runtime_us, 95 % by default) keeps a runaway RT thread from locking
a core. Plain Python; no ROS.
"""
from __future__ import annotations

import os
import sys

#: The interpreter's thread switch interval [s] while a real-time loop runs: a thread
#: waiting for the GIL asks the holder to drop it after this long (CPython's default
#: 5 ms would be five of the loop's periods).
SWITCH_INTERVAL = 0.0005


def make_realtime(priority: int) -> str:
    """Ask for SCHED_FIFO at ``priority`` (1-99) for the CALLING thread; 0 leaves it alone.

    Returns one line saying what the thread got (for the node's log). Never raises.
    """
    if priority <= 0:
        return "normal scheduling (priority 0 asked)"
    sys.setswitchinterval(SWITCH_INTERVAL)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))  # 0: this thread (Linux)
    except (OSError, AttributeError) as err:
        return (f"normal scheduling: SCHED_FIFO {priority} refused ({err}); a busy machine can delay the rig's "
                "loop (grant CAP_SYS_NICE or an rtprio limit to avoid it)")
    return f"SCHED_FIFO priority {priority}"


def realtime_permitted(priority: int) -> bool:
    """Whether this process may ask for SCHED_FIFO at ``priority`` (tried in a throwaway thread)."""
    import threading

    allowed: list[bool] = []

    def attempt() -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
            allowed.append(True)
        except (OSError, AttributeError):
            allowed.append(False)

    thread = threading.Thread(target=attempt)
    thread.start()
    thread.join()
    return allowed[0]


__all__ = ["SWITCH_INTERVAL", "make_realtime", "realtime_permitted"]
