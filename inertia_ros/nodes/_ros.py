"""ROS plumbing shared by the nodes and the demo: ``main()``, QoS, polled input, share dir.

- :func:`run_node`: the one ``main()`` shape of every inertia_ros node (Jazzy idiom, one-line
  errors);
- :func:`sensor_qos`, :func:`latched_qos` and :func:`clock_qos`: the QoS profiles the package
  uses;
- :func:`polled_subscription` and :func:`take_raw`: a raw subscription of a node that no
  executor waits on, drained by a timer (at kHz rates one executor wake-up per message costs
  a few times more CPU than taking a whole batch every few milliseconds);
- :func:`share_path`: a file of the installed package share directory, or of the source tree.
"""
from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rclpy
from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.subscription import Subscription

__all__ = ['PolledGroup', 'clock_qos', 'latched_qos', 'polled_subscription', 'run_node',
           'sensor_qos', 'share_path', 'take_raw']

PACKAGE = 'inertia_ros'


def _init_holding_stderr(args: list[str] | None) -> None:
    """``rclpy.init(args)``, with what rcl writes on stderr meanwhile held back: on failure
    it is dropped (rcl's own "[ERROR] ... [rcl]: Failed to parse global arguments" would
    precede the node's one-line error), on success it is written out unchanged."""
    import os
    import tempfile

    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        try:
            rclpy.init(args=args)
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        held.seek(0)
        text = held.read()
        if text:
            os.write(2, text)


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
    line on stderr and the process exits with status 2, never with a traceback.  So are
    command-line arguments rcl cannot parse, and a ``--params-file`` that is missing or not a
    parameters file (named, before rcl reads it).  ``--help`` (before ``--ros-args``) prints the
    node's usage (:func:`inertia_ros.nodes.params.help_text`) and returns without starting
    ROS.
    """
    from inertia_ros.nodes.params import NODE_TABLES, help_text, print_help_if_asked
    from inertia_ros.nodes.params_file import params_file_problem
    from inertia_ros.runtime import keep_freed_memory

    if name in NODE_TABLES and print_help_if_asked(args, lambda: help_text(name)):
        return
    keep_freed_memory()               # the estimates' arrays reuse freed heap, no page faults
    problem = params_file_problem(args)   # named here: rcl only says it could not parse one
    if problem:
        print(f'{name}: error: {problem}', file=sys.stderr)
        sys.exit(2)
    try:
        _init_holding_stderr(args)
    except Exception as exc:  # rcl's RCLError for arguments it cannot parse
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        text = text.removeprefix('failed to initialize rcl: ')
        if text.startswith("Couldn't parse params file"):   # what params_file_problem missed
            file, _, detail = text.partition("'. Error: ")
            path = file.split('--params-file ', 1)[-1].rstrip("'")
            why = detail.split(' at /', 1)[0].split(', at /')[0].rstrip(', ')
            text = f'--params-file {path}: not a valid ROS 2 parameters file ({why})'
        text = text.split('. Error:')[0]
        print(f'{name}: error: bad command-line arguments: {text}', file=sys.stderr)
        sys.exit(2)
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
    except Exception:
        if rclpy.ok():
            raise
        # SIGINT/SIGTERM shut the context down while a callback was publishing: that
        # callback's RCLError is the shutdown itself, not a fault to print.
    finally:
        if node is not None:
            try:
                node.destroy_node()
            except Exception:
                if rclpy.ok():
                    raise
        rclpy.try_shutdown()
    if status:
        sys.exit(status)


def sensor_qos(depth: int = 100) -> QoSProfile:
    """Sensor-data QoS (best effort, volatile) with history ``depth`` [messages]."""
    qos = QoSProfile(depth=depth)
    qos.reliability = qos_profile_sensor_data.reliability
    qos.durability = qos_profile_sensor_data.durability
    qos.history = qos_profile_sensor_data.history
    return qos


def latched_qos(depth: int = 1) -> QoSProfile:
    """Reliable, transient local, depth 1: a late subscriber gets the last message."""
    return QoSProfile(depth=depth, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                      reliability=ReliabilityPolicy.RELIABLE)


def clock_qos() -> QoSProfile:
    """QoS of ``/clock``: best effort, volatile, keep last 1 (``rclcpp::ClockQoS``).

    What rosbag2's ``--clock`` publisher and the time sources of rclcpp and rclpy use: a
    late or lost clock message is superseded by the next one, never queued.
    """
    return QoSProfile(depth=1, durability=DurabilityPolicy.VOLATILE,
                      reliability=ReliabilityPolicy.BEST_EFFORT)


class PolledGroup(CallbackGroup):
    """A callback group whose entities no executor waits on or runs: they are polled.

    Executors build their wait set from the entities whose group ``can_execute``; a
    subscription in this group stays a subscription of its node (``ros2 node info`` lists
    it, remaps and namespaces apply, ``destroy_node`` destroys it) but never wakes an
    executor.  Its messages are taken with :func:`take_raw`.
    """

    def can_execute(self, entity: Any) -> bool:
        """Never: the entity is polled."""
        return False

    def beginning_execution(self, entity: Any) -> bool:
        """Never: the entity is polled."""
        return False

    def ending_execution(self, entity: Any) -> None:
        """Nothing to release (nothing ever began)."""


def _never_called(_: Any) -> None:
    raise AssertionError('polled subscriptions are never dispatched')


def polled_subscription(node: Node, msg_type: Any, topic: str, qos: QoSProfile,
                        group: PolledGroup | None = None) -> Subscription:
    """A raw subscription of ``node`` that no executor waits on (see :class:`PolledGroup`).

    Parameters
    ----------
    node : rclpy.node.Node
        Owner: the topic name is resolved by it (namespace, remaps) and the graph lists the
        subscription under it.
    msg_type : type
        Message class (``sensor_msgs.msg.Imu``, ...).
    topic : str
        Topic name, relative or absolute.
    qos : rclpy.qos.QoSProfile
        Subscription QoS; its history depth bounds what one poll can take.
    group : PolledGroup, optional
        Group to put it in; a new one by default.

    Returns
    -------
    rclpy.subscription.Subscription
        Drain it with :func:`take_raw`.
    """
    return node.create_subscription(
        msg_type, topic, _never_called, qos, callback_group=group or PolledGroup(),
        event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False), raw=True)


def take_raw(sub: Subscription) -> list[bytes]:
    """Take every message queued on a raw subscription, oldest first (serialised CDR)."""
    out: list[bytes] = []
    with sub.handle:
        while (got := sub.handle.take_message(sub.msg_type, True)) is not None:
            out.append(got[0])
    return out


def share_path(*parts: str) -> Path:
    """A file under the package's share directory: installed (ament index) or source tree.

    Parameters
    ----------
    *parts : str
        Path inside the share directory, e.g. ``('config', 'scenes', 'default.yaml')``.

    Returns
    -------
    pathlib.Path
        The installed file when the package is installed and has it, else the same path in
        the source tree (which may not exist: callers check).
    """
    try:
        from ament_index_python.packages import get_package_share_directory
        candidate = Path(get_package_share_directory(PACKAGE), *parts)
        if candidate.is_file():
            return candidate
    except Exception:  # not installed through ament: the source tree is the share dir
        pass
    return Path(__file__).resolve().parents[2].joinpath(*parts)
