"""run_graph: start every node of a graph parameter file, each in its own process.

    ros2 run torque_estimator run_graph <graph.yaml> [--set node.param=value ...] [--together a,b ...]

--together runs the listed nodes in one process on one executor (a rig computer
that wants fewer processes; each node still runs alone with `ros2 run`).
--priority runs every process of the graph SCHED_FIFO at that priority (`chrt -f`,
needs CAP_SYS_NICE; the rig's loop thread asks for more on its own), so other work
on the computer cannot delay the graph's answers.

Stops all nodes on Ctrl-C / SIGTERM, or when one of them exits on its own.
"""
from __future__ import annotations

import signal
import sys
import time
from pathlib import Path

from worm_model.cli.errors import run_tool
from worm_model.cli.options import Parser, integer, log_folder

from torque_estimator.graph.runner import Graph, parse_overrides


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
    args = parser.parse_args(argv)
    stop = []
    for signum in (signal.SIGINT, signal.SIGTERM):  # a flag, so a second Ctrl-C cannot cut the clean stop short
        signal.signal(signum, lambda *_: stop.append(True))
    groups = [[n for n in group.split(",") if n] for group in args.together]
    graph = Graph(args.graph, parse_overrides(args.set), args.log_dir, together=groups,
                  priority=args.priority).start()
    print(f"run_graph: started {', '.join(graph.processes)}", flush=True)
    while not stop and not graph.failed():
        time.sleep(0.2)
    early = {} if stop else graph.failed()  # after Ctrl-C (which a terminal sends the nodes too) none exits on its own
    graph.stop()
    for node, code in early.items():
        print(f"run_graph: {node} exited on its own with code {code}", file=sys.stderr)
    return 1 if early else 0


if __name__ == "__main__":
    raise SystemExit(main())
