"""The ROS side of ``python -m inertia_ros bench node``: feed the estimator, record its outputs.

:class:`EstimatorProbe` publishes ``imu`` (sensor_msgs/Imu) and ``torque``
(geometry_msgs/WrenchStamped) with sensor-data QoS from one node, and a second node, spun in
a thread, records every ``/inertia_estimator/inertia`` stamp with its monotonic receive time
and the estimator's ``/diagnostics`` key-values.  The measurement itself (schedule, CPU,
latency) is in :mod:`inertia_ros.bench.node`, which imports this module only when it runs.

``python -m inertia_ros.nodes.probe`` is the benchmark's witness: a process of its own that
subscribes to ``imu`` and ``torque`` as the estimator does (sensor-data QoS, depth 100000,
polled every 5 ms) and, on SIGINT, prints how many messages of each it received as one JSON
line.  What the witness got is what the publisher put on the wire; a message the witness has
and the estimator lacks was lost on the estimator's side.
"""
from __future__ import annotations

import threading
import time
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import InertiaStamped, WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Imu

from . import messages
from ._ros import PolledGroup, polled_subscription, sensor_qos, take_raw

__all__ = ['EstimatorProbe', 'count_inputs']


class EstimatorProbe:
    """Publishers of the estimator's inputs and a recorder of its outputs.

    Attributes
    ----------
    received : list of (int, int)
        ``(header stamp [ns], monotonic receive time [ns])`` of every estimate.
    diags : list of dict
        Key-values of every diagnostic status whose name starts with ``inertia_estimator``.
    """

    def __init__(self, estimator: str = 'inertia_estimator', depth: int = 1000) -> None:
        rclpy.init()
        self.received: list[tuple[int, int]] = []
        self.diags: list[dict[str, str]] = []
        self._stop = threading.Event()
        self._pub_node = Node('bench_publisher')
        self._pubs = [self._pub_node.create_publisher(Imu, 'imu', sensor_qos(depth)),
                      self._pub_node.create_publisher(WrenchStamped, 'torque',
                                                      sensor_qos(depth))]
        self._sub_node = Node('bench_listener')
        self._sub_node.create_subscription(InertiaStamped, f'/{estimator}/inertia',
                                           self._on_estimate, 100)
        self._sub_node.create_subscription(DiagnosticArray, '/diagnostics',
                                           lambda m: self._on_diag(m, estimator), 100)
        self._exe = SingleThreadedExecutor()
        self._exe.add_node(self._sub_node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _on_estimate(self, msg: InertiaStamped) -> None:
        self.received.append((messages.stamp_to_ns(msg.header.stamp), time.monotonic_ns()))

    def _on_diag(self, msg: DiagnosticArray, estimator: str) -> None:
        self.diags += [{kv.key: kv.value for kv in st.values} for st in msg.status
                       if st.name.startswith(estimator)]          # '<node>: <task>'

    def _spin(self) -> None:
        while not self._stop.is_set():
            self._exe.spin_once(timeout_sec=0.05)

    def matched(self, subscribers: int = 1) -> bool:
        """Whether both input topics have at least ``subscribers`` subscribers."""
        return all(p.get_subscription_count() >= subscribers for p in self._pubs)

    @staticmethod
    def gyro_message(t_ns: int, omega: Any, frame_id: str) -> Imu:
        """An Imu message carrying ``omega`` [rad/s] stamped ``t_ns``."""
        return messages.imu_msg(t_ns, omega, frame_id)

    @staticmethod
    def torque_message(t_ns: int, torque: Any, frame_id: str) -> WrenchStamped:
        """A WrenchStamped message carrying ``torque`` [N m] stamped ``t_ns``."""
        return messages.wrench_msg(t_ns, torque, frame_id)

    def publish(self, stream: int, msg: Any) -> None:
        """Publish ``msg`` on the gyro (``stream`` 0) or torque (1) topic."""
        self._pubs[stream].publish(msg)

    def close(self) -> None:
        """Stop the listener thread and shut ROS down."""
        self._stop.set()
        self._thread.join()
        rclpy.try_shutdown()


def count_inputs(depth: int = 100000, period: float = 0.005) -> dict[str, int]:
    """Count the ``imu`` and ``torque`` messages received until SIGINT (the witness).

    Parameters
    ----------
    depth : int
        History depth of both subscriptions [messages]: deep enough for any burst of the
        publisher (the witness must not lose what the estimator might).
    period : float
        Poll period [s]: at 8 kHz, 40 messages per poll.

    Returns
    -------
    dict
        ``{'gyro': n, 'torque': n}`` messages received.
    """
    import json
    import signal

    counts = {'gyro': 0, 'torque': 0}
    rclpy.init()
    node = Node('bench_witness')
    group = PolledGroup()
    subs = {'gyro': polled_subscription(node, Imu, 'imu', sensor_qos(depth), group),
            'torque': polled_subscription(node, WrenchStamped, 'torque', sensor_qos(depth),
                                          group)}
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    print('witness ready', flush=True)
    while not stop.wait(period):
        for name, sub in subs.items():
            counts[name] += len(take_raw(sub))
    for name, sub in subs.items():
        counts[name] += len(take_raw(sub))
    node.destroy_node()
    rclpy.try_shutdown()
    print(json.dumps(counts), flush=True)
    return counts


if __name__ == '__main__':
    count_inputs()
