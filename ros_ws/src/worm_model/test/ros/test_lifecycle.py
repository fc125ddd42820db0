"""run_node's life of a node process: spins until SIGINT, with what it built out of the
cyclic collector's sight (a full collection then walks only what the running node allocates;
see lifecycle.run_nodes), and exits 0."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

from worm_model.ros.testing import local_domain

SAFETY_TIMEOUT = 120.0  # [s] only so that a node that ignores SIGINT cannot hang the suite

NODE = textwrap.dedent("""
    import gc, os, signal
    from rclpy.node import Node
    from worm_model.ros.lifecycle import run_node

    class Probe(Node):
        def __init__(self):
            super().__init__("lifecycle_probe")
            self.create_timer(0.01, self.tick)

        def tick(self):
            # spinning now: report what the collector no longer walks, then stop as Ctrl-C would
            print("frozen", gc.get_freeze_count(), "tracked", len(gc.get_objects()), flush=True)
            self.destroy_timer(self._timers[0])
            os.kill(os.getpid(), signal.SIGINT)

    raise SystemExit(run_node(Probe, ["lifecycle_probe"]))
""")


def test_a_node_spins_with_its_start_up_objects_frozen_and_exits_0_on_sigint() -> None:
    done = subprocess.run([sys.executable, "-c", NODE], capture_output=True, text=True, timeout=SAFETY_TIMEOUT,
                          env={**os.environ, **local_domain()})
    assert done.returncode == 0, done.stderr
    words = done.stdout.split()
    frozen, tracked = int(words[1]), int(words[3])
    # rclpy's modules alone leave tens of thousands of objects; the collector walks a small rest
    assert frozen > 20_000 and tracked < frozen / 10, done.stdout
