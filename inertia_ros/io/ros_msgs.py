"""ROS 2 messages <-> numpy arrays, at the boundary between the nodes and the core.

Pure functions: they build and read message objects and never need ``rclpy.init()``, so the
tests construct messages directly.  Time at this boundary is integer nanoseconds (``t_ns``);
vectors are float64 arrays in SI units (rad/s, N m, kg m^2).

Inputs read by the estimator:

- ``sensor_msgs/msg/Imu`` (angular_velocity), ``geometry_msgs/msg/Vector3Stamped``
  -> ``(t_ns, omega (3,))`` in rad/s;
- ``geometry_msgs/msg/WrenchStamped`` (torque part), ``Vector3Stamped`` -> ``(t_ns, tau (3,))``
  in N m.

Outputs built from an estimate (see :func:`inertia_stamped`, :func:`principal_moments_msg`,
:func:`principal_axes_msg`, :func:`diagnostic_status`, :func:`inertia_markers`):
``geometry_msgs/msg/InertiaStamped``, ``Vector3Stamped``, ``QuaternionStamped``,
``diagnostic_msgs/msg/DiagnosticArray`` and ``visualization_msgs/msg/MarkerArray``.
"""
from __future__ import annotations

import json
import math
import os
import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import (
    InertiaStamped,
    Point,
    QuaternionStamped,
    Vector3,
    Vector3Stamped,
    WrenchStamped,
)
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

__all__ = [
    'DIAGNOSTIC_LEVELS',
    'THETA_NAMES',
    'diagnostic_array',
    'diagnostic_status',
    'header',
    'imu_msg',
    'imu_sample',
    'inertia_from_msg',
    'inertia_markers',
    'inertia_stamped',
    'level_name',
    'ns_to_stamp',
    'principal_axes_msg',
    'principal_moments_msg',
    'quaternion_to_axes',
    'schema_text_from_share',
    'stamp_to_ns',
    'vector3_sample',
    'vector3_stamped',
    'wrench_msg',
    'wrench_sample',
]

#: Parameter order of the tensor elements (docs/DESIGN.md contract).
THETA_NAMES: tuple[str, ...] = ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')

#: DiagnosticStatus level for each estimate status.  ``ok`` is OK; a warm-up
#: (``insufficient_data``) or a tensor with some elements undetermined is WARN; an estimate the
#: data can never give as it stands (no torque: scale unobservable; no excitation) is ERROR.
DIAGNOSTIC_LEVELS: dict[str, bytes] = {
    'ok': DiagnosticStatus.OK,
    'insufficient_data': DiagnosticStatus.WARN,
    'partially_identifiable': DiagnosticStatus.WARN,
    'model_mismatch': DiagnosticStatus.WARN,
    'scale_unobservable': DiagnosticStatus.ERROR,
    'insufficient_excitation': DiagnosticStatus.ERROR,
}

_LEVEL_NAMES = {DiagnosticStatus.OK: 'OK', DiagnosticStatus.WARN: 'WARN',
                DiagnosticStatus.ERROR: 'ERROR', DiagnosticStatus.STALE: 'STALE'}

_NS = 1_000_000_000


# --------------------------------------------------------------------------- time and headers
def stamp_to_ns(stamp: Time) -> int:
    """Convert a ``builtin_interfaces/Time`` to integer nanoseconds.

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        ``sec`` (int32) and ``nanosec`` (uint32, < 1e9).

    Returns
    -------
    int
        ``sec * 1e9 + nanosec`` [ns].
    """
    return int(stamp.sec) * _NS + int(stamp.nanosec)


def ns_to_stamp(t_ns: int) -> Time:
    """Convert integer nanoseconds to a ``builtin_interfaces/Time``.

    Parameters
    ----------
    t_ns : int
        Time [ns]; must be within the int32 seconds range of the message.

    Returns
    -------
    builtin_interfaces.msg.Time
        With ``0 <= nanosec < 1e9`` (negative times floor to the previous second).

    Raises
    ------
    ValueError
        If ``t_ns`` is not an integer or is outside the representable range.
    """
    if isinstance(t_ns, bool) or not isinstance(t_ns, (int, np.integer)):
        raise ValueError(f't_ns must be an integer number of nanoseconds, got {t_ns!r}')
    sec, nanosec = divmod(int(t_ns), _NS)
    if not -2**31 <= sec < 2**31:
        raise ValueError(f't_ns={t_ns} is outside the int32 seconds range of '
                         'builtin_interfaces/Time')
    return Time(sec=sec, nanosec=nanosec)


def header(t_ns: int, frame_id: str) -> Header:
    """Build a ``std_msgs/Header`` from integer nanoseconds and a frame id."""
    return Header(stamp=ns_to_stamp(t_ns), frame_id=str(frame_id))


def _vec3(v: Any, name: str) -> np.ndarray:
    arr = np.asarray(v, dtype=float)
    if arr.shape != (3,):
        raise ValueError(f'{name} must have shape (3,), got {arr.shape}')
    return arr


def _xyz(v: Vector3 | Point) -> np.ndarray:
    return np.array((v.x, v.y, v.z), dtype=float)


# --------------------------------------------------------------------------- inputs
def imu_sample(msg: Imu) -> tuple[int, np.ndarray]:
    """Read the angular velocity of a ``sensor_msgs/Imu``.

    Returns
    -------
    t_ns : int
        ``header.stamp`` [ns].
    omega : numpy.ndarray, shape (3,)
        ``angular_velocity`` [rad/s] (NaN passes through: the caller counts and drops it).
    """
    return stamp_to_ns(msg.header.stamp), _xyz(msg.angular_velocity)


def vector3_sample(msg: Vector3Stamped) -> tuple[int, np.ndarray]:
    """Read a ``geometry_msgs/Vector3Stamped`` as ``(t_ns [ns], vector (3,))``."""
    return stamp_to_ns(msg.header.stamp), _xyz(msg.vector)


def wrench_sample(msg: WrenchStamped) -> tuple[int, np.ndarray]:
    """Read the torque part of a ``geometry_msgs/WrenchStamped`` as ``(t_ns, tau (3,) [N m])``.

    The force part is ignored: only the torque about the centre of mass enters Euler's
    equations.
    """
    return stamp_to_ns(msg.header.stamp), _xyz(msg.wrench.torque)


def imu_msg(t_ns: int, omega: Any, frame_id: str) -> Imu:
    """Build a ``sensor_msgs/Imu`` carrying only an angular velocity.

    Parameters
    ----------
    t_ns : int
        Header stamp [ns].
    omega : array_like, shape (3,)
        Angular velocity [rad/s].
    frame_id : str
        Frame of the gyro.

    Returns
    -------
    sensor_msgs.msg.Imu
        Orientation and linear acceleration are marked absent (covariance[0] = -1, REP 145).
    """
    w = _vec3(omega, 'omega')
    msg = Imu(header=header(t_ns, frame_id))
    msg.angular_velocity = Vector3(x=float(w[0]), y=float(w[1]), z=float(w[2]))
    msg.orientation_covariance[0] = -1.0
    msg.linear_acceleration_covariance[0] = -1.0
    return msg


def vector3_stamped(t_ns: int, v: Any, frame_id: str) -> Vector3Stamped:
    """Build a ``geometry_msgs/Vector3Stamped`` from a (3,) array (any unit)."""
    x = _vec3(v, 'v')
    return Vector3Stamped(header=header(t_ns, frame_id),
                          vector=Vector3(x=float(x[0]), y=float(x[1]), z=float(x[2])))


def wrench_msg(t_ns: int, tau: Any, frame_id: str) -> WrenchStamped:
    """Build a ``geometry_msgs/WrenchStamped`` with torque ``tau`` (3,) [N m] and zero force."""
    x = _vec3(tau, 'tau')
    msg = WrenchStamped(header=header(t_ns, frame_id))
    msg.wrench.torque = Vector3(x=float(x[0]), y=float(x[1]), z=float(x[2]))
    return msg


# --------------------------------------------------------------------------- outputs
def _matrix(inertia: Any) -> np.ndarray:
    mat = np.asarray(inertia, dtype=float)
    if mat.shape != (3, 3):
        raise ValueError(f'inertia must have shape (3, 3), got {mat.shape}')
    return mat


def inertia_stamped(inertia: Any, t_ns: int, frame_id: str, *, mass: float = 0.0,
                    com: Any = (0.0, 0.0, 0.0)) -> InertiaStamped:
    """Build a ``geometry_msgs/InertiaStamped`` from a 3x3 tensor.

    Parameters
    ----------
    inertia : array_like, shape (3, 3)
        Tensor about the centre of mass [kg m^2]; ``ixy`` is the matrix element (DESIGN.md).
        Elements that are not identifiable (NaN) are written as NaN.
    t_ns : int
        Header stamp [ns].
    frame_id : str
        Frame the tensor is expressed in (the gyro frame).
    mass : float, optional
        ``inertia.m`` [kg].  The estimator does not observe the mass: 0.0 means unknown.
    com : array_like, shape (3,), optional
        ``inertia.com`` [m]; zero: the tensor is about the centre of mass.

    Returns
    -------
    geometry_msgs.msg.InertiaStamped
    """
    mat = _matrix(inertia)
    c = _vec3(com, 'com')
    msg = InertiaStamped(header=header(t_ns, frame_id))
    i = msg.inertia
    i.m = float(mass)
    i.com = Vector3(x=float(c[0]), y=float(c[1]), z=float(c[2]))
    i.ixx, i.iyy, i.izz = float(mat[0, 0]), float(mat[1, 1]), float(mat[2, 2])
    i.ixy, i.ixz, i.iyz = float(mat[0, 1]), float(mat[0, 2]), float(mat[1, 2])
    return msg


def inertia_from_msg(msg: InertiaStamped) -> tuple[int, np.ndarray]:
    """Read a ``geometry_msgs/InertiaStamped`` as ``(t_ns [ns], inertia (3, 3) [kg m^2])``."""
    i = msg.inertia
    mat = np.array([[i.ixx, i.ixy, i.ixz], [i.ixy, i.iyy, i.iyz], [i.ixz, i.iyz, i.izz]],
                   dtype=float)
    return stamp_to_ns(msg.header.stamp), mat


def principal_moments_msg(moments: Any, t_ns: int, frame_id: str) -> Vector3Stamped:
    """Principal moments ``[I1, I2, I3]`` (ascending) [kg m^2] as a ``Vector3Stamped``."""
    return vector3_stamped(t_ns, moments, frame_id)


def _check_rotation(axes: Any) -> np.ndarray:
    rot = _matrix(axes)
    if not np.all(np.isfinite(rot)):
        raise ValueError('axes must be finite')
    if not np.allclose(rot.T @ rot, np.eye(3), atol=1e-6) or np.linalg.det(rot) < 0:
        raise ValueError('axes must be a proper rotation matrix (orthonormal columns, det +1)')
    return rot


def principal_axes_msg(axes: Any, t_ns: int, frame_id: str) -> QuaternionStamped:
    """Principal axes as the ``QuaternionStamped`` rotating ``frame_id`` onto them.

    Parameters
    ----------
    axes : array_like, shape (3, 3)
        Columns are the principal axes (a proper rotation, DESIGN.md sign convention),
        expressed in ``frame_id``; column k is the image of unit vector k.
    t_ns : int
        Header stamp [ns].
    frame_id : str
        Frame of the gyro.

    Returns
    -------
    geometry_msgs.msg.QuaternionStamped
        Unit quaternion with ``w >= 0``.

    Raises
    ------
    ValueError
        If ``axes`` is not a proper rotation matrix.
    """
    rot = _check_rotation(axes)
    x, y, z, w = Rotation.from_matrix(rot).as_quat()
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    msg = QuaternionStamped(header=header(t_ns, frame_id))
    msg.quaternion.x, msg.quaternion.y = float(x), float(y)
    msg.quaternion.z, msg.quaternion.w = float(z), float(w)
    return msg


def quaternion_to_axes(msg: QuaternionStamped) -> np.ndarray:
    """Inverse of :func:`principal_axes_msg`: the (3, 3) rotation whose columns are the axes."""
    q = msg.quaternion
    return Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()


# --------------------------------------------------------------------------- diagnostics
def level_name(level: bytes) -> str:
    """Name of a ``DiagnosticStatus`` level byte: 'OK', 'WARN', 'ERROR' or 'STALE'."""
    return _LEVEL_NAMES.get(level, repr(level))


def _fmt(value: Any) -> str:
    """Render a diagnostic value as the string a KeyValue carries (JSON for containers)."""
    if value is None:
        return 'null'
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return 'nan' if math.isnan(v) else f'{v:.6g}'
    if isinstance(value, (int, np.integer, str)):
        return str(value)
    if isinstance(value, np.ndarray):
        value = value.tolist()
    try:
        return json.dumps(value, default=str, allow_nan=True)
    except (TypeError, ValueError):
        return str(value)


def _reason(result: Mapping[str, Any]) -> str:
    diag = result.get('diagnostics') or {}
    for key in ('reason', 'message'):
        if diag.get(key):
            return str(diag[key])
    warnings = diag.get('warnings')
    if warnings:
        return '; '.join(str(w) for w in warnings) if not isinstance(warnings, str) else warnings
    return ''


def diagnostic_status(result: Mapping[str, Any] | None, *, name: str, hardware_id: str = '',
                      extra: Mapping[str, Any] | None = None,
                      problems: Sequence[tuple[bytes, str]] = ()) -> DiagnosticStatus:
    """Build the estimator's ``DiagnosticStatus`` from an estimate in its JSON-contract form.

    Parameters
    ----------
    result : mapping or None
        ``InertiaEstimate.to_dict()`` (docs/DESIGN.md contract: status, inertia_std, model,
        method, samples, diagnostics, ...), or None before any estimate exists (then the
        status is ``insufficient_data``).
    name : str
        ``DiagnosticStatus.name`` (the node's name).
    hardware_id : str, optional
        ``DiagnosticStatus.hardware_id`` (e.g. the gyro frame).
    extra : mapping, optional
        Further key/values from the node (counts of received, NaN-dropped and refused
        messages, stream ages [s], ...); values are rendered as strings.
    problems : sequence of (level, message), optional
        Node-level conditions (stream timeout, frame mismatch, ...).  The reported level is
        the worst of the estimate's level and these; their messages are prepended.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticStatus
        ``level`` from :data:`DIAGNOSTIC_LEVELS`, ``message`` = ``status`` plus the reason,
        ``values``: status, model, method, condition_number, std_<element> [kg m^2],
        samples_used, samples_dropped, torque_bias, every scalar entry of ``diagnostics``,
        then ``extra``.
    """
    if result is None:
        result = {'status': 'insufficient_data', 'diagnostics': {'reason': 'no samples yet'}}
    status = str(result.get('status', 'insufficient_data'))
    if status not in DIAGNOSTIC_LEVELS:
        raise ValueError(f'result status {status!r} is not one of {sorted(DIAGNOSTIC_LEVELS)}')
    level = DIAGNOSTIC_LEVELS[status]
    reason = _reason(result)
    message = status + (f': {reason}' if reason and status != 'ok' else '')
    for p_level, _ in problems:
        level = max(level, p_level)
    if problems:
        message = '; '.join([m for _, m in problems] + [message])

    values: list[tuple[str, Any]] = [('status', status)]
    diag: Mapping[str, Any] = result.get('diagnostics') or {}
    for key in ('model', 'method'):
        if key in result:
            values.append((key, result[key]))
    cond = next((diag[k] for k in ('condition_number', 'condition', 'cond') if k in diag), None)
    values.append(('condition_number', cond))
    std = result.get('inertia_std')
    std_arr = None if std is None else np.asarray(
        [[np.nan if v is None else v for v in row] for row in std], dtype=float)
    idx = {'ixx': (0, 0), 'iyy': (1, 1), 'izz': (2, 2), 'ixy': (0, 1), 'ixz': (0, 2),
           'iyz': (1, 2)}
    for el in THETA_NAMES:
        values.append((f'std_{el}', None if std_arr is None else std_arr[idx[el]]))
    samples = result.get('samples') or {}
    values.append(('samples_used', samples.get('used')))
    values.append(('samples_dropped', samples.get('dropped')))
    for key in ('principal_moments_std', 'principal_ratios', 'principal_ratios_std'):
        if diag.get(key) is not None:
            values.append((key, diag[key]))
    axes_std = diag.get('principal_axes_std')
    if axes_std is not None:      # [deg]: how far each principal axis may be off (1 sigma)
        values.append(('principal_axes_std_deg',
                       [None if v is None else math.degrees(float(v)) for v in axes_std]))
    if 'torque_bias' in result:
        values.append(('torque_bias', result['torque_bias']))
    if 'identifiable' in result:
        values.append(('identifiable', result['identifiable']))
    if result.get('ratios') is not None and status != 'ok':
        values.append(('ratios', result['ratios']))  # what torque-free data still gives
        if result.get('ratios_std') is not None:
            values.append(('ratios_std', result['ratios_std']))
    values.append(('reason', reason))
    seen = {k for k, _ in values}
    for key, val in diag.items():
        if key not in seen and isinstance(val, (int, float, str, bool, np.number, np.bool_)):
            values.append((str(key), val))
            seen.add(str(key))
    for key, val in (extra or {}).items():
        values.append((str(key), val))
    return DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=_fmt(v)) for k, v in values])


def diagnostic_array(statuses: Iterable[DiagnosticStatus], t_ns: int) -> DiagnosticArray:
    """Wrap statuses in a ``diagnostic_msgs/DiagnosticArray`` stamped ``t_ns`` [ns]."""
    return DiagnosticArray(header=header(t_ns, ''), status=list(statuses))


# --------------------------------------------------------------------------- markers
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
    rot = None
    if moments is not None and axes is not None:
        mom = _vec3(moments, 'moments')
        rot = _check_rotation(axes)
        if np.all(np.isfinite(mom)) and np.all(mom > 0):
            semi = 1.0 / np.sqrt(mom)
            semi = semi * (scale / semi.max())
            m = Marker(header=hdr, ns=ns, id=MARKER_IDS['ellipsoid'], type=Marker.SPHERE,
                       action=Marker.ADD)
            x, y, z, w = Rotation.from_matrix(rot).as_quat()
            m.pose.orientation.x, m.pose.orientation.y = float(x), float(y)
            m.pose.orientation.z, m.pose.orientation.w = float(z), float(w)
            m.scale.x, m.scale.y, m.scale.z = (float(2.0 * s) for s in semi)
            m.color = _color(0.3, 0.6, 1.0, 0.35)
            out.append(m)
        colors = (_color(1, 0, 0), _color(0, 0.8, 0), _color(0, 0, 1))
        for k in range(3):
            out.append(_arrow(MARKER_IDS[f'axis{k + 1}'], ns, hdr, rot[:, k], 1.3 * scale,
                              colors[k], shaft))
    w_unit = None
    if omega is not None:
        w_vec = _vec3(omega, 'omega')
        w_unit = _unit(w_vec)
        if w_unit is not None:
            out.append(_arrow(MARKER_IDS['omega'], ns, hdr, w_unit, 1.5 * scale,
                              _color(1.0, 0.85, 0.0), shaft))
        if inertia is not None:
            l_unit = _unit(_matrix(inertia) @ w_vec)
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


# --------------------------------------------------------------------------- schemas
_PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring'})


def _msg_file(pkg: str, name: str) -> Path:
    """Locate ``<share>/<pkg>/msg/<name>.msg`` via AMENT_PREFIX_PATH, then ``sys.prefix``."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(sys.prefix)
    for prefix in prefixes:
        path = Path(prefix) / 'share' / pkg / 'msg' / f'{name}.msg'
        if path.is_file():
            return path
    raise ValueError(f'msgtype: no {pkg}/msg/{name}.msg under the share/ of {prefixes}')


def _field_types(text: str, pkg: str) -> list[str]:
    """The complex types ``pkg/Type`` used by the fields of a .msg text, in order."""
    out: list[str] = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line or '=' in line:
            continue  # blank, comment or constant (NAME=value)
        ftype = re.sub(r'\[.*\]$', '', line.split()[0])
        base = ftype.split('<=')[0]
        if base in _PRIMITIVES:
            continue
        if '/' not in base:
            base = 'std_msgs/Header' if base == 'Header' else f'{pkg}/{base}'
        else:
            parts = base.split('/')
            base = f'{parts[0]}/{parts[-1]}'
        if base not in out:
            out.append(base)
    return out


def schema_text_from_share(msgtype: str) -> str:
    """The ``ros2msg`` schema text of any installed message type, as rosbag2 stores it.

    The type's own ``.msg`` text, then for every (transitive) dependency a line of 80 ``=``,
    ``MSG: pkg/Type`` and that type's ``.msg`` text.  The ``.msg`` files are read from the
    ``share/`` directories of ``AMENT_PREFIX_PATH`` (a sourced ROS install) or of
    ``sys.prefix`` (the PyPI wheels).

    Parameters
    ----------
    msgtype : str
        ``pkg/msg/Type`` or ``pkg/Type``, e.g. ``visualization_msgs/msg/MarkerArray``.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        If the name is malformed or a ``.msg`` file cannot be found.
    """
    parts = msgtype.split('/')
    if len(parts) not in (2, 3) or (len(parts) == 3 and parts[1] != 'msg') or not all(parts):
        raise ValueError(f"msgtype: expected 'pkg/msg/Type', got {msgtype!r}")
    pkg, name = parts[0], parts[-1]
    texts: dict[str, str] = {}
    order: list[str] = []

    def visit(full: str) -> None:
        p, n = full.split('/')
        text = _msg_file(p, n).read_text()
        texts[full] = text
        for dep in _field_types(text, p):
            if dep not in texts:
                order.append(dep)
                visit(dep)

    visit(f'{pkg}/{name}')
    blocks = [texts[f'{pkg}/{name}'].rstrip('\n')]
    blocks += [f"{'=' * 80}\nMSG: {dep}\n{texts[dep].rstrip(chr(10))}" for dep in order]
    return '\n'.join(blocks) + '\n'
