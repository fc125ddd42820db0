"""Fixtures shared by the system tests: the run's DDS domain, and node graphs started from a parameter text.

The helpers without pytest in them (domain, probe node, stopping a process) are in
worm_model.ros.testing, so that the bench scripts can use them too.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from torque_estimator.graph.runner import Graph, process_file_name

# the tests' own helper modules (markdown_tables, in_process, rig_sessions): importable by name from every test here
sys.path.insert(0, str(Path(__file__).resolve().parent))
from worm_model.ros.testing import local_domain


@pytest.fixture(scope="module")
def ros_env() -> Iterator[dict[str, str]]:
    """This module's DDS domain (worm_model.ros.testing.local_domain), set in os.environ.

    The variables hold for this process's probe nodes and for the processes it
    starts. The fixture yields the whole environment, to pass to subprocesses.
    """
    with pytest.MonkeyPatch.context() as mp:
        for name, value in local_domain().items():
            mp.setenv(name, value)
        yield dict(os.environ)


@pytest.fixture(scope="module")
def start_graph(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory
                ) -> Iterator[Callable[[str, str], Graph]]:
    """Start a graph, one process per node, from the text of a ROS 2 parameter file.

    The function takes the text and a folder name and returns the started Graph.
    The parameter file and the node logs go into that folder. At the end of the
    module every node gets SIGINT and must exit with code 0.
    """
    graphs: list[Graph] = []

    def start(params_text: str, name: str = "graph") -> Graph:
        folder = tmp_path_factory.mktemp(name)
        params = folder / "graph.yaml"
        params.write_text(params_text, encoding="utf-8")
        graph = Graph(params, {}, log_dir=folder / "logs")
        graphs.append(graph)
        return graph.start()

    try:
        yield start
    finally:
        codes = {str(graph.log_dir): graph.stop() for graph in graphs}
    unclean = {logs: c for logs, c in codes.items() if any(code != 0 for code in c.values())}
    # a node killed after the grace period printed its threads' stacks (SIGUSR1) into its log: show them,
    # pytest's temporary folders do not outlive three runs
    tails = "".join(f"\n--- {logs}/{name}.log (end) ---\n" + (Path(logs) / f"{process_file_name(name.split('+'))}.log")
                    .read_text(errors="replace")[-4000:] for logs, c in unclean.items() for name, code in c.items()
                    if code != 0)
    assert not unclean, f"nodes did not exit cleanly (exit codes by log folder): {unclean}{tails}"


#: the test files that take a minute or more, the longest first (as measured on a 2-core machine): `make test` runs
#: files two at a time (pytest-xdist, in collection order), so they start first, longest first; started last, they
#: would leave one worker alone at the end
SLOWEST_FILES = ("tests/test_residuals_cases.py", "tests/test_readme_figures.py",
                 "torque_estimator/test/health/test_study.py", "tests/test_soak_bench.py",
                 "torque_estimator/test/evaluation/test_datasheet_road.py", "tests/test_bad_input_probe.py",
                 "tests/test_tool_round_trip.py", "tests/test_residuals_sim.py",
                 "torque_estimator/test/evaluation/test_identified.py", "tests/test_new_drive.py")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    def rank(item: pytest.Item) -> int:  # the longest first; the rest as found (a stable sort)
        path = item.path.as_posix()
        return next((k for k, name in enumerate(SLOWEST_FILES) if path.endswith(name)), len(SLOWEST_FILES))

    items.sort(key=rank)
