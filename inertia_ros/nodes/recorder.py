"""A raw-message recorder on its own rclpy context: what ``python -m inertia_ros demo`` hears.

:class:`Recorder` subscribes a set of topics without deserialising them, hands every
message to a callback as ``(topic, receive time [ns], CDR bytes)`` and spins on demand.
Sensor-data topics (kHz) are polled every ``poll_period`` from subscriptions no executor
waits on (:func:`inertia_ros.nodes._ros.polled_subscription`), as in the estimator; the
others are dispatched one message at a time.
"""
from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Mapping
from typing import Any

import rclpy
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription

from inertia_ros.nodes._ros import (
    PolledGroup,
    latched_qos,
    polled_subscription,
    sensor_qos,
    take_raw,
)

__all__ = ['KINDS', 'Recorder', 'deserialize', 'message_class']

#: Subscription kinds: ``sensor_data`` (best effort, polled), ``latched`` (reliable,
#: transient local: gets the last message published before it joined), ``reliable``.
KINDS: tuple[str, ...] = ('sensor_data', 'latched', 'reliable')


def message_class(msgtype: str) -> type:
    """The Python class of a ROS 2 message type ``pkg/msg/Type`` (its package imported).

    Raises
    ------
    ValueError
        If the name is malformed or the package or type is not installed.
    """
    parts = msgtype.split('/')
    if len(parts) != 3 or parts[1] != 'msg' or not all(parts):
        raise ValueError(f"msgtype: expected 'pkg/msg/Type', got {msgtype!r}")
    try:
        return getattr(importlib.import_module(f'{parts[0]}.msg'), parts[2])
    except (ImportError, AttributeError):
        raise ValueError(f'msgtype: {msgtype} is not installed') from None


def deserialize(msgtype: str, payload: bytes) -> Any:
    """The message object of a CDR payload of type ``pkg/msg/Type``."""
    return deserialize_message(payload, message_class(msgtype))


class Recorder:
    """Record raw messages of several topics from a private rclpy context.

    Parameters
    ----------
    name : str
        Node name.
    topics : mapping of str to (str, str)
        ``topic -> (message type 'pkg/msg/Type', kind)``, kind one of :data:`KINDS`.
    on_message : callable
        ``on_message(topic, receive_time_ns, payload)`` for every message, in arrival order
        per topic; polled topics are delivered in batches by :meth:`drain`.
    poll_period : float, optional
        Period of the sensor-data drain [s].
    sensor_depth : int, optional
        History depth of the sensor-data subscriptions [messages]: what one poll can take.

    Raises
    ------
    ValueError
        On an unknown kind or message type.
    """

    def __init__(self, name: str, topics: Mapping[str, tuple[str, str]],
                 on_message: Callable[[str, int, bytes], None], *,
                 poll_period: float = 0.01, sensor_depth: int = 5000) -> None:
        for topic, (_, kind) in topics.items():
            if kind not in KINDS:
                raise ValueError(f'{topic}: kind must be one of {", ".join(KINDS)}, '
                                 f'got {kind!r}')
        self._classes = {t: message_class(m) for t, (m, _) in topics.items()}
        self._on_message = on_message
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node(name, context=self.context)
        self._exe = SingleThreadedExecutor(context=self.context)
        self._exe.add_node(self.node)
        self._polled: dict[str, Subscription] = {}
        self._subs: dict[str, Subscription] = {}
        group = PolledGroup()
        for topic, (_, kind) in topics.items():
            cls = self._classes[topic]
            if kind == 'sensor_data':
                sub = polled_subscription(self.node, cls, topic, sensor_qos(sensor_depth),
                                          group)
                self._polled[topic] = sub
            else:
                qos: QoSProfile = latched_qos(100) if kind == 'latched' else QoSProfile(depth=100)
                sub = self.node.create_subscription(
                    cls, topic, lambda data, t=topic: self._on_message(t, time.time_ns(), data),
                    qos, raw=True)
            self._subs[topic] = sub
        self.node.create_timer(poll_period, self.drain,
                               clock=Clock(clock_type=ClockType.STEADY_TIME))

    def subscription(self, topic: str) -> Subscription:
        """The subscription of ``topic`` (publisher counts, resolved name)."""
        return self._subs[topic]

    def drain(self) -> None:
        """Hand every queued sensor-data message to the callback (oldest first per topic)."""
        for topic, sub in self._polled.items():
            for data in take_raw(sub):
                self._on_message(topic, time.time_ns(), data)

    def spin_once(self, timeout: float = 0.05) -> None:
        """Run at most one ready callback, waiting up to ``timeout`` [s]."""
        self._exe.spin_once(timeout_sec=timeout)

    def close(self) -> None:
        """Take what is still queued, then destroy the node and shut the context down."""
        self.drain()
        self._exe.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
