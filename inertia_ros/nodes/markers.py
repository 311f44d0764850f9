"""``visualization_msgs/MarkerArray`` picturing an inertia estimate for RViz and Foxglove.

:func:`inertia_markers` draws the inertia ellipsoid, the principal axes, and the angular
velocity and angular momentum directions, in stable ids (:data:`MARKER_IDS`) so that
displays update in place.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from inertia_ros.core.inertia import axes_to_quaternion
from inertia_ros.nodes.messages import header, matrix33, vec3

__all__ = ['MARKER_IDS', 'inertia_markers']


def _color(r: float, g: float, b: float, a: float = 1.0) -> ColorRGBA:
    return ColorRGBA(r=float(r), g=float(g), b=float(b), a=float(a))


def _arrow(mid: int, ns: str, hdr: Header, direction: np.ndarray, length: float,
           color: ColorRGBA, shaft: float) -> Marker:
    m = Marker(header=hdr, ns=ns, id=mid, type=Marker.ARROW, action=Marker.ADD)
    m.pose.orientation.w = 1.0
    tip = direction * length
    m.points = [Point(x=0.0, y=0.0, z=0.0),
                Point(x=float(tip[0]), y=float(tip[1]), z=float(tip[2]))]
    m.scale.x, m.scale.y, m.scale.z = shaft, 2.0 * shaft, 3.0 * shaft
    m.color = color
    return m


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    if not math.isfinite(n) or n <= 0.0:
        return None
    return v / n


#: Marker ids inside the namespace (stable so that displays update in place).
MARKER_IDS = {'ellipsoid': 0, 'axis1': 1, 'axis2': 2, 'axis3': 3, 'omega': 4,
              'momentum': 5, 'label': 6}


def _body_markers(hdr: Header, ns: str, moments: np.ndarray, axes: Any, scale: float,
                  shaft: float) -> list[Marker]:
    """The inertia ellipsoid (when every moment is positive) and the principal-axis arrows."""
    quat = axes_to_quaternion(axes)  # also checks that axes is a proper rotation
    rot = np.asarray(axes, dtype=float)
    out = []
    if np.all(np.isfinite(moments)) and np.all(moments > 0):
        semi = 1.0 / np.sqrt(moments)
        semi = semi * (scale / semi.max())
        m = Marker(header=hdr, ns=ns, id=MARKER_IDS['ellipsoid'], type=Marker.SPHERE,
                   action=Marker.ADD)
        x, y, z, w = quat
        m.pose.orientation.x, m.pose.orientation.y = float(x), float(y)
        m.pose.orientation.z, m.pose.orientation.w = float(z), float(w)
        m.scale.x, m.scale.y, m.scale.z = (float(2.0 * s) for s in semi)
        m.color = _color(0.3, 0.6, 1.0, 0.35)
        out.append(m)
    colors = (_color(1, 0, 0), _color(0, 0.8, 0), _color(0, 0, 1))
    for k in range(3):
        out.append(_arrow(MARKER_IDS[f'axis{k + 1}'], ns, hdr, rot[:, k], 1.3 * scale,
                          colors[k], shaft))
    return out


def inertia_markers(t_ns: int, frame_id: str, *, inertia: Any = None, moments: Any = None,
                    axes: Any = None, omega: Any = None, scale: float = 0.5,
                    ns: str = 'inertia', label: str = '') -> MarkerArray:
    """Markers picturing the tensor: inertia ellipsoid, principal axes, omega and L arrows.

    The inertia ellipsoid ``x^T I x = 1`` has semi-axes ``1/sqrt(I_k)`` along the principal
    axes; it is drawn scaled so that its longest semi-axis is ``scale`` metres (the shape and
    orientation are the information; the absolute size in 1/sqrt(kg m^2) is not a length).
    The principal axes are arrows of length ``1.3 * scale`` (red, green, blue for I1 <= I2 <=
    I3).  The angular velocity ``omega`` (yellow) and the angular momentum ``L = I omega``
    (magenta) are unit-direction arrows of length ``1.5 * scale``: they coincide only when
    omega lies on a principal axis.

    Parameters
    ----------
    t_ns : int
        Header stamp [ns].
    frame_id : str
        Frame of the gyro (markers are drawn at its origin).
    inertia : array_like, shape (3, 3), optional
        Tensor [kg m^2]; needed for the L arrow.
    moments : array_like, shape (3,), optional
        Principal moments ascending [kg m^2]; with ``axes``, needed for the ellipsoid.
    axes : array_like, shape (3, 3), optional
        Principal axes as columns (proper rotation).
    omega : array_like, shape (3,), optional
        Latest angular velocity [rad/s].
    scale : float, optional
        Display size [m] (> 0).
    ns : str, optional
        Marker namespace.
    label : str, optional
        Text shown above the body (e.g. the status); omitted when empty.

    Returns
    -------
    visualization_msgs.msg.MarkerArray
        A DELETEALL marker first (so markers of a previous, valid estimate disappear when
        the estimate becomes invalid), then whatever the given data allow.

    Raises
    ------
    ValueError
        If ``scale`` is not a positive finite number or an array has the wrong shape.
    """
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ValueError(f'scale must be a positive finite length in metres, got {scale!r}')
    hdr = header(t_ns, frame_id)
    out = [Marker(header=hdr, ns=ns, id=0, action=Marker.DELETEALL)]
    shaft = 0.04 * scale
    if moments is not None and axes is not None:
        out += _body_markers(hdr, ns, vec3(moments, 'moments'), axes, scale, shaft)
    w_unit = None
    if omega is not None:
        w_vec = vec3(omega, 'omega')
        w_unit = _unit(w_vec)
        if w_unit is not None:
            out.append(_arrow(MARKER_IDS['omega'], ns, hdr, w_unit, 1.5 * scale,
                              _color(1.0, 0.85, 0.0), shaft))
        if inertia is not None:
            l_unit = _unit(matrix33(inertia, 'inertia') @ w_vec)
            if l_unit is not None:
                out.append(_arrow(MARKER_IDS['momentum'], ns, hdr, l_unit, 1.5 * scale,
                                  _color(1.0, 0.0, 1.0), shaft))
    if label:
        m = Marker(header=hdr, ns=ns, id=MARKER_IDS['label'], type=Marker.TEXT_VIEW_FACING,
                   action=Marker.ADD, text=label)
        m.pose.position.z = 1.8 * scale
        m.pose.orientation.w = 1.0
        m.scale.z = 0.15 * scale
        m.color = _color(1, 1, 1)
        out.append(m)
    for m in out[1:]:
        m.lifetime = Duration(sec=0, nanosec=0)
    return MarkerArray(markers=out)
