"""The ``inertia_estimator`` node's result topics: one estimate published on each.

``~/inertia`` (latched, only while valid), ``~/inertia_covariance``,
``~/principal_moments`` (and ``_std``), ``~/principal_ratios`` (and ``_std``),
``~/principal_axes`` and ``~/markers``, all stamped with the newest input stamp.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from geometry_msgs.msg import InertiaStamped, QuaternionStamped, Vector3Stamped
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from inertia_ros.core.estimation.result import InertiaEstimate
from inertia_ros.nodes import messages
from inertia_ros.nodes._ros import latched_qos
from inertia_ros.nodes.markers import inertia_markers

__all__ = ['EstimateOutputs', 'quiet']


def quiet() -> dict[str, Any]:
    """``create_publisher`` keywords for a publisher without QoS-event handlers: each would be
    one more entity in every executor wait-set, i.e. CPU at every poll."""
    return {'event_callbacks': PublisherEventCallbacks(use_default_callbacks=False)}


def _finite(x: Any) -> bool:
    return x is not None and bool(np.all(np.isfinite(x)))


class EstimateOutputs:
    """The result publishers of one node and the publishing of an estimate on them."""

    def __init__(self, node: Node) -> None:
        q = quiet()
        self.inertia = node.create_publisher(
            InertiaStamped, '~/inertia', latched_qos(), **q)
        self.moments = node.create_publisher(
            Vector3Stamped, '~/principal_moments', 10, **q)
        self.axes = node.create_publisher(
            QuaternionStamped, '~/principal_axes', 10, **q)
        self.cov = node.create_publisher(
            Float64MultiArray, '~/inertia_covariance', 10, **q)
        self.moments_std = node.create_publisher(
            Vector3Stamped, '~/principal_moments_std', 10, **q)
        self.ratios = node.create_publisher(
            Vector3Stamped, '~/principal_ratios', 10, **q)
        self.ratios_std = node.create_publisher(
            Vector3Stamped, '~/principal_ratios_std', 10, **q)
        self.markers = node.create_publisher(
            MarkerArray, '~/markers', 10, **q)

    def publish(self, est: InertiaEstimate, stamp: int, frame: str, *, publish_partial: bool,
                omega: np.ndarray | None, marker_scale: float) -> None:
        """Publish every output of one estimate, all stamped ``stamp`` [ns] in ``frame``.

        ``~/inertia`` only while the status is ``ok`` (or ``partially_identifiable`` with
        ``publish_partial``); ``omega`` (3,) [rad/s] is the newest gyro sample (an arrow
        among the markers, scaled by ``marker_scale``).
        """
        status = est.status
        valid = status == 'ok' or (status == 'partially_identifiable' and publish_partial)
        if valid and est.inertia is not None:  # the main output first: lowest latency
            self.inertia.publish(messages.inertia_stamped(est.inertia, stamp, frame))
            cov = messages.estimate_covariance(est)
            if cov is not None:
                self.cov.publish(messages.covariance_msg(*cov))
        diag = est.diagnostics
        have_axes = _finite(est.principal_moments) and _finite(est.principal_axes)
        if have_axes:
            self.moments.publish(
                messages.principal_moments_msg(est.principal_moments, stamp, frame))
            if diag.get('principal_moments_std') is not None:
                self.moments_std.publish(messages.vector3_stamped(
                    stamp, diag['principal_moments_std'], frame))
        ratios = diag.get('principal_ratios')
        if _finite(ratios):
            self.ratios.publish(messages.vector3_stamped(stamp, ratios, frame))
            if diag.get('principal_ratios_std') is not None:
                self.ratios_std.publish(messages.vector3_stamped(
                    stamp, diag['principal_ratios_std'], frame))
        if _finite(est.principal_axes):
            self.axes.publish(messages.principal_axes_msg(est.principal_axes, stamp, frame))
        self.markers.publish(inertia_markers(
            stamp, frame, inertia=est.inertia if valid else None,
            moments=est.principal_moments if have_axes else None,
            axes=est.principal_axes if have_axes else None,
            omega=omega, scale=marker_scale, label=status))
