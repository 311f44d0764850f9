"""Entry point of ``scene_simulator``: ``ros2 run inertia_ros scene_simulator`` and
``python -m inertia_ros.scene_simulator_node``.


The node is :mod:`inertia_ros.nodes.scene_simulator`; this module imports it only when run.
"""
from __future__ import annotations


def main(args: list[str] | None = None) -> None:
    """Run the node (see :func:`inertia_ros.nodes.scene_simulator.main`)."""
    from inertia_ros.nodes.params import help_text, print_help_if_asked

    if print_help_if_asked(args, lambda: help_text('scene_simulator')):
        return  # usage printed; ROS (and the node's heavy imports) never started
    from inertia_ros.nodes.scene_simulator import main as run

    run(args)


if __name__ == '__main__':
    main()
