"""Run one node in its own process and shut it down cleanly.

The order matters with rclpy: stop spinning, destroy the node, then shut the
context down; an executor left spinning in a thread at exit ends in SIGABRT,
and rclpy's own SIGINT handler can raise KeyboardInterrupt in the middle of
that cleanup. So once the nodes are built, SIGINT and SIGTERM only set a flag
here, and the main thread spins until the flag is set; while they are being
built (a file that is slow to read, a rig to open) a signal interrupts at once.

Before rclpy starts, the arguments are checked (:func:`start_problem`): a
parameter file rcl would refuse with a traceback is one line and exit code 2.
Once the nodes are built, a parameter that none of them declares is refused
the same way, naming the closest declared one.
"""
from __future__ import annotations

import faulthandler
import gc
import os
import re
import signal
import sys
import threading
from collections.abc import Callable, Sequence

import rclpy
from rclpy.exceptions import NameValidationException, ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from worm_model.cli.errors import EXIT_BAD_INPUT, EXIT_INTERRUPTED, one_line
from worm_model.errors import InputError
from worm_model.files.reading import load_parameter_file, ros_arguments
from worm_model.ros.parameters import (check_undeclared, help_text, undeclared_problem, wants_help,
                                      wildcard_names)
from worm_model.ros.teardown import deadline

try:  # rclpy >= Jazzy: callbacks dispatched from C++, several times less CPU per message at 1 kHz
    from rclpy.experimental import EventsExecutor as _Executor
except ImportError:  # Humble
    from rclpy.executors import SingleThreadedExecutor as _Executor


def executor_for(nodes: Sequence[Node]) -> Executor:
    """The executor of a process's nodes: the EventsExecutor where rclpy has one (callbacks dispatched from C++,
    several times less CPU per message at 1 kHz), unless a node takes its messages' MessageInfo (a node whose
    ``takes_message_info`` is true: the rig's command gate reads the publisher's GID), which this rclpy's
    EventsExecutor cannot hand a callback (it raises SystemError): then rclpy's SingleThreadedExecutor."""
    if any(getattr(node, "takes_message_info", False) for node in nodes):
        return SingleThreadedExecutor()
    return _Executor()


def parameter_problem(err: ParameterException) -> str:
    """rclpy's 'Invalid parameter value (-1) for parameter. Reason: ... : k' as 'parameter k: ...'."""
    text = one_line(err)
    message, _, name = text.rpartition(": ")
    return f"parameter {name}: {message}" if message else text


def name_problem(err: NameValidationException) -> str:
    """rclpy's three-line 'Invalid topic name: why:\n  'name'\n   ^' as one line: 'invalid topic name 'name': why'."""
    lines = [line.strip() for line in str(err).splitlines() if line.strip() and set(line.strip()) != {"^"}]
    kind, _, why = lines[0].partition(": ") if lines else ("invalid name", "", "")
    name = lines[1] if len(lines) > 1 else ""
    return f"{kind.lower()} {name}: {why.rstrip(':')}" if name else one_line(err)


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
    parameter value, a parameter file rcl cannot read, or a parameter the node does not declare is one line
    ``<program>: ...`` and exit code 2.
    """
    return run_nodes([make_node], args)


def start_problem(program: str, argv: Sequence[str], makers: Sequence[Callable[[], Node]] = ()) -> int | None:
    """What every node executable checks before rclpy.init; an exit code (a refusal: 2), or None.

    Every ``--params-file`` is read as rcl will read it (worm_model.files.reading.load_parameter_file: a
    regular file, UTF-8, YAML within limits, no anchors, aliases or merge keys, node sections rcl accepts):
    a file rcl would refuse with a traceback in every node is one line and exit code 2 here instead. Then
    a parameter given to one of ``makers``' nodes that it does not declare is refused the same way, naming
    the closest declared name, before the node logs a word.
    """
    for flag, value in ros_arguments(list(argv)):
        if flag == "--params-file":
            try:
                load_parameter_file(value)
            except InputError as err:
                print(f"{program}: --params-file {one_line(err)}", file=sys.stderr)
                return EXIT_BAD_INPUT
    problem = undeclared_problem(makers, argv) if makers else None
    if problem:
        print(f"{program}: {problem}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return None


def rcl_problem(err: BaseException) -> str:
    """rcl's refusal of the arguments, on one line without its C source locations."""
    text = one_line(err)
    text = re.sub(r",? at [\w/.+-]+\.c:\d+", "", text)
    return text.replace("failed to initialize rcl: ", "").strip() or type(err).__name__


def init_rclpy(program: str, args: list[str] | None) -> int | None:
    """rclpy.init without its signal handlers; an exit code (2) when rcl refuses the arguments, else None."""
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except KeyboardInterrupt:
        print(f"{program}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as err:  # noqa: BLE001 - rcl's RCLError: bad arguments, an unreadable parameter file
        print(f"{program}: {rcl_problem(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return None


def _interrupt(signum: int, _frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def run_nodes(makers: Sequence[Callable[[], Node]], args: list[str] | None = None) -> int:
    """:func:`run_node` for several nodes in this one process, on one executor (a composed graph).

    Each node takes its own section of a ``--params-file`` by its name, as it would alone. Before anything
    starts, the parameter files are checked (:func:`start_problem`); once the nodes are built, a parameter
    given to a node that declares no such name is refused with the closest declared name
    (worm_model.ros.parameters.check_undeclared). While the nodes are being built, Ctrl-C interrupts at
    once (exit 130); once they run, it stops them cleanly.
    """
    given = sys.argv if args is None else list(args)
    program, argv = (os.path.basename(given[0]) or "node", given[1:]) if given else ("node", [])
    if wants_help(argv):  # before rclpy.init: no context, no DDS
        print(help_text(makers, program))
        return 0
    code_or_none = start_problem(program, argv, makers)
    if code_or_none is not None:
        return code_or_none
    stop = threading.Event()
    # A node that does not exit after SIGINT can be asked where it is stuck: SIGUSR1 prints every
    # thread's Python stack to stderr (run_graph and the tests do this before SIGKILL).
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    # A crash inside the middleware or a C extension (SIGSEGV, SIGABRT, ...) prints every thread's Python
    # stack to stderr before the process dies, so its log says where instead of being empty.
    faulthandler.enable(all_threads=True)
    for signum in (signal.SIGINT, signal.SIGTERM):  # building may block (a slow file): Ctrl-C must end it
        signal.signal(signum, _interrupt)
    refused = init_rclpy(program, args)
    if refused is not None:
        return refused
    executor = None
    nodes: list[Node] = []
    code = 0
    try:
        for make_node in makers:
            nodes.append(make_node())
        executor = executor_for(nodes)
        for node in nodes:
            executor.add_node(node)
        check_undeclared(nodes, wildcard_names(argv))
        for signum in (signal.SIGINT, signal.SIGTERM):  # running: a signal only sets the flag (module docstring)
            signal.signal(signum, lambda *_: stop.set())
        freeze_built_objects()
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except ExternalShutdownException:
        pass
    except KeyboardInterrupt:  # while the nodes were being built
        print(f"{program}: interrupted", file=sys.stderr)
        code = EXIT_INTERRUPTED
    except ParameterException as err:  # a value outside the declared range or of the wrong type
        print(f"{program}: {parameter_problem(err)}", file=sys.stderr)
        code = EXIT_BAD_INPUT
    except NameValidationException as err:  # a topic (or other ROS name) given in a parameter
        print(f"{program}: {name_problem(err)}", file=sys.stderr)
        code = EXIT_BAD_INPUT
    except (ValueError, OSError) as err:  # bad parameters or files: say so, exit non-zero
        print(f"{program}: {one_line(err)}", file=sys.stderr)
        code = EXIT_BAD_INPUT
    finally:
        for signum in (signal.SIGINT, signal.SIGTERM):  # the teardown is bounded (deadline), not interrupted
            signal.signal(signum, lambda *_: stop.set())
        # bounded: a middleware hang in the teardown must not keep a stopped node alive (ros.teardown)
        with deadline(code):
            if executor is not None:
                executor.shutdown()
            for node in nodes:
                node.destroy_node()
            rclpy.try_shutdown()
    return code
