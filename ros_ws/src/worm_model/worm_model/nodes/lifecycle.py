"""Run one node in its own process and shut it down cleanly.

The order matters with rclpy: stop spinning, destroy the node, then shut the
context down; an executor left spinning in a thread at exit ends in SIGABRT.
SIGINT and SIGTERM both end the spin (rclpy's own signal handlers).
"""
from __future__ import annotations

import sys
from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


def run_node(make_node: Callable[[], Node], args: list[str] | None = None) -> int:
    """rclpy.init, build the node, spin until shutdown, clean up; returns an exit code."""
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = make_node()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ValueError, OSError) as err:  # bad parameters or files: say so, exit non-zero
        print(f"[fatal] {err}", file=sys.stderr)
        code = 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
