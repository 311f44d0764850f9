"""Entry point of ``exciter``: ``ros2 run inertia_ros exciter`` and
``python -m inertia_ros.exciter_node``.


The node is :mod:`inertia_ros.nodes.exciter`; this module imports it only when run.
"""
from __future__ import annotations


def main(args: list[str] | None = None) -> None:
    """Run the node (see :func:`inertia_ros.nodes.exciter.main`)."""
    from inertia_ros.nodes.params import help_text, print_help_if_asked

    if print_help_if_asked(args, lambda: help_text('exciter')):
        return  # usage printed; ROS (and the node's heavy imports) never started
    from inertia_ros.nodes.exciter import main as run

    run(args)


if __name__ == '__main__':
    main()
