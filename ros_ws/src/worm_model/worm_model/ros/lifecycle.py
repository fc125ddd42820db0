"""Run one node in its own process and shut it down cleanly.

The order matters with rclpy: stop spinning, destroy the node, then shut the
context down; an executor left spinning in a thread at exit ends in SIGABRT,
and rclpy's own SIGINT handler can raise KeyboardInterrupt in the middle of
that cleanup. So SIGINT and SIGTERM only set a flag here, and the main thread
spins until the flag is set.
"""
from __future__ import annotations

import faulthandler
import gc
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from worm_model.cli.errors import one_line
from worm_model.ros.parameters import help_text, wants_help
from worm_model.ros.teardown import deadline

try:  # rclpy >= Jazzy: callbacks dispatched from C++, several times less CPU per message at 1 kHz
    from rclpy.experimental import EventsExecutor as _Executor
except ImportError:  # Humble
    from rclpy.executors import SingleThreadedExecutor as _Executor


def parameter_problem(err: ParameterException) -> str:
    """rclpy's 'Invalid parameter value (-1) for parameter. Reason: ... : k' as 'parameter k: ...'."""
    text = one_line(err)
    message, _, name = text.rpartition(": ")
    return f"parameter {name}: {message}" if message else text


def freeze_built_objects() -> None:
    """Put every object that exists now out of the cyclic collector's sight (``gc.freeze``).

    Call it once a node is built: what exists then (modules, the node, its tables) lives as long as
    the process, and a full collection then walks only what the running node allocates. Measured:
    ~94k tracked objects once rclpy, numpy and the graph's nodes are loaded; a full collection of
    them took 35 ms holding the GIL, the executor and sim_node's 1 kHz rig thread standing still
    (bench/graph_bench.py, rig computer, idle, 30 s windows: graph_latency_p99 3 ms before, 2 ms in
    each of three runs after).
    """
    gc.collect()
    gc.freeze()


def run_node(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """rclpy.init, build the node, spin until SIGINT/SIGTERM, clean up; returns an exit code.

    ``-h``/``--help`` prints the node's parameters and returns 0 without starting anything; a bad
    parameter value is one line ``<program>: parameter <name>: ...`` and exit code 2.
    """
    return run_nodes([make_node], args)


def run_nodes(makers: Sequence[Callable[[], Node]], args: list[str] | None = None) -> int:
    """:func:`run_node` for several nodes in this one process, on one executor (a composed graph).

    Each node takes its own section of a ``--params-file`` by its name, as it would alone.
    """
    given = sys.argv if args is None else list(args)
    program, argv = (os.path.basename(given[0]) or "node", given[1:]) if given else ("node", [])
    if wants_help(argv):  # before rclpy.init: no context, no DDS
        print(help_text(makers, program))
        return 0
    stop = threading.Event()
    # A node that does not exit after SIGINT can be asked where it is stuck: SIGUSR1 prints every
    # thread's Python stack to stderr (run_graph and the tests do this before SIGKILL).
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    executor = _Executor()
    nodes: list[Node] = []
    code = 0
    try:
        for make_node in makers:
            nodes.append(make_node())
            executor.add_node(nodes[-1])
        freeze_built_objects()
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except ExternalShutdownException:
        pass
    except ParameterException as err:  # a value outside the declared range or of the wrong type
        print(f"{program}: {parameter_problem(err)}", file=sys.stderr)
        code = 2
    except (ValueError, OSError) as err:  # bad parameters or files: say so, exit non-zero
        print(f"{program}: {one_line(err)}", file=sys.stderr)
        code = 2
    finally:
        # bounded: a middleware hang in the teardown must not keep a stopped node alive (ros.teardown)
        with deadline(code):
            executor.shutdown()
            for node in nodes:
                node.destroy_node()
            rclpy.try_shutdown()
    return code
