"""run_graph: start every node of a graph parameter file, each in its own process.

    ros2 run torque_estimator run_graph <graph.yaml> [--set node.param=value ...] [--together a,b ...]

--together runs the listed nodes in one process on one executor (a rig computer
that wants fewer processes; each node still runs alone with `ros2 run`).
--priority runs every process of the graph SCHED_FIFO at that priority (`chrt -f`,
needs CAP_SYS_NICE; the rig's loop thread asks for more on its own), so other work
on the computer cannot delay the graph's answers.

--respawn starts a node's process again when it exits on its own (a crash, `kill -9`),
--respawn-delay seconds later, its log appended to, as launch's respawn does; a
process of several nodes (--together) if any of them is named. One line on stderr
per restart. A node that refused its input (exit code 2) is not started again, nor
one that has used up --respawn-max.

Stops all nodes on Ctrl-C / SIGTERM, or when a node that is not respawned exits on
its own (exit code 1).
"""
from __future__ import annotations

import signal
import sys
import time
from pathlib import Path

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, integer, log_folder, number

from torque_estimator.errors import GraphError
from torque_estimator.graph.runner import Graph, graph_nodes, parse_overrides

#: [s] between two looks at the graph's processes (a respawn waits up to this much beyond its delay)
SUPERVISE_PERIOD = 0.2


def main(argv: list[str] | None = None) -> int:
    return run_tool("run_graph", lambda: _main(argv))


def _main(argv: list[str] | None) -> int:
    parser = Parser(prog="run_graph", description=__doc__.split("\n\n")[0])
    parser.add_argument("graph", type=Path, help="ROS 2 parameter file whose top-level keys are the nodes to start")
    parser.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=VALUE",
                        help="override one parameter of one node (repeatable)")
    parser.add_argument("--together", action="append", default=[], metavar="NODE,NODE,...",
                        help="run these nodes in one process on one executor (repeatable, one group each; "
                             "e.g. --together sim_node,model_node,estimator_node,controller_node)")
    parser.add_argument("--priority", type=integer(0, 99), default=0, metavar="0-99",
                        help="SCHED_FIFO priority of the graph's processes (0: normal scheduling)")
    parser.add_argument("--log-dir", type=log_folder, default=None,
                        help="write each node's output to <dir>/<node>.log instead of this terminal")
    parser.add_argument("--respawn", action="append", default=[], metavar="NODE,NODE,...",
                        help="start these nodes again when they exit on their own (a crash, kill -9), each "
                             "in its process as first started (same command, environment and priority, its "
                             "log appended to); repeatable; 'all': every node of the graph. A process of "
                             "several nodes (--together) is restarted if any of them is named. Not restarted: "
                             "a node that refused its input (exit code 2). Default: none, and a node that "
                             "exits stops the graph")
    parser.add_argument("--respawn-delay", type=number("s", 0.0, 3600.0), default=1.0, metavar="SECONDS",
                        help="wait this long after a node exited before starting it again (default: 1.0; "
                             "checked every 0.2 s)")
    parser.add_argument("--respawn-max", type=integer(0, 10**6), default=None, metavar="N",
                        help="restart each process at most N times; its next exit stops the graph "
                             "(default: no limit)")
    args = parser.parse_args(argv)
    groups = [[n for n in group.split(",") if n] for group in args.together]
    respawn = [n for item in args.respawn for n in item.split(",") if n]
    if "all" in respawn:
        respawn = graph_nodes(args.graph)
    elif args.respawn and not respawn:
        raise GraphError("--respawn: no node named (NODE,NODE,... or all)")
    graph = Graph(args.graph, parse_overrides(args.set), args.log_dir, together=groups, priority=args.priority,
                  respawn=respawn, respawn_delay=args.respawn_delay, respawn_max=args.respawn_max)
    stop = []
    for signum in (signal.SIGINT, signal.SIGTERM):  # a flag, so a second Ctrl-C cannot cut the clean stop short
        signal.signal(signum, lambda *_: stop.append(True))
    graph.start()
    try:
        print(f"run_graph: started {', '.join(graph.processes)}", flush=True)
        while not stop and not graph.failed():
            for name in graph.supervise():
                code, waited = graph.last_exit[name]
                print(f"run_graph: {name} exited with code {code}; respawned after {waited:.1f} s "
                      f"(restart {graph.restarts[name]})", file=sys.stderr, flush=True)
            time.sleep(SUPERVISE_PERIOD)
        # after Ctrl-C (which a terminal sends the nodes too) none exits on its own
        early = {} if stop else graph.failed()
    finally:
        graph.stop()
    for node, code in early.items():
        print(f"run_graph: {node} exited on its own with code {code}", file=sys.stderr)
    return 1 if early else 0


if __name__ == "__main__":
    raise SystemExit(main())
