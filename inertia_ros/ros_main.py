"""The one ``main()`` shape every inertia_ros node shares (Jazzy idiom, one-line errors)."""
from __future__ import annotations

import sys
from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


def run_node(make_node: Callable[[], Node], name: str, args: list[str] | None = None,
             spin: Callable[[Node], None] = rclpy.spin) -> None:
    """Initialise rclpy, build the node, spin it, and shut down cleanly.

    Parameters
    ----------
    make_node : callable
        Builds the node (after ``rclpy.init``).
    name : str
        Node name used in the one-line error message.
    args : list of str, optional
        Command-line arguments (``--ros-args ...``); default ``sys.argv``.
    spin : callable, optional
        How to spin the node; default ``rclpy.spin`` (players stop by themselves).

    Bad parameters, scenes or logs raise ``ValueError`` in the node; they are printed as one
    line on stderr and the process exits with status 2, never with a traceback.
    """
    rclpy.init(args=args)
    node = None
    status = 0
    try:
        node = make_node()
        spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ValueError as exc:
        print(f'{name}: error: {exc}', file=sys.stderr)
        status = 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if status:
        sys.exit(status)
