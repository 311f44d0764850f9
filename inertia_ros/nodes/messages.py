"""ROS 2 message objects <-> numpy arrays at the boundary between the nodes and the core.

Pure functions: they build and read message objects and never need ``rclpy.init()``, so the
tests construct messages directly.  Time at this boundary is integer nanoseconds (``t_ns``);
vectors are float64 arrays in SI units (rad/s, N m, kg m^2).  The nodes *read* their inputs
in batches with :mod:`inertia_ros.io.cdr_decode`; the builders here serve the players and the
outputs:

- inputs as published by the players: :func:`imu_msg` (``sensor_msgs/msg/Imu``),
  :func:`vector3_stamped`, :func:`wrench_msg` (``geometry_msgs/msg/WrenchStamped``),
  :func:`joint_state_msg` (``sensor_msgs/msg/JointState``: wheel or rotor speeds);
- outputs: :func:`inertia_stamped` (``geometry_msgs/msg/InertiaStamped``, read back by
  :func:`inertia_from_msg`), :func:`principal_moments_msg` (``Vector3Stamped``) and
  :func:`principal_axes_msg` (``QuaternionStamped``), :func:`covariance_msg` (the 6x6
  covariance of the tensor elements as a labelled ``std_msgs/Float64MultiArray``, from
  :func:`estimate_covariance`; read back by :func:`covariance_from_msg`).

Diagnostics and markers are in :mod:`inertia_ros.nodes.diagnostics` and
:mod:`inertia_ros.nodes.markers`.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (
    InertiaStamped,
    QuaternionStamped,
    Vector3,
    Vector3Stamped,
    WrenchStamped,
)
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray, Header, MultiArrayDimension, MultiArrayLayout

from inertia_ros.core.inertia import THETA_NAMES, axes_to_quaternion

__all__ = [
    'COVARIANCE_DIAGONAL',
    'COVARIANCE_FULL',
    'covariance_from_msg',
    'covariance_msg',
    'estimate_covariance',
    'header',
    'imu_msg',
    'inertia_from_msg',
    'inertia_stamped',
    'joint_state_msg',
    'ns_to_stamp',
    'principal_axes_msg',
    'principal_moments_msg',
    'stamp_to_ns',
    'vector3_stamped',
    'wrench_msg',
]

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


def vec3(v: Any, name: str) -> np.ndarray:
    """``v`` as a float64 array of shape (3,); ``ValueError`` naming ``name`` otherwise."""
    arr = np.asarray(v, dtype=float)
    if arr.shape != (3,):
        raise ValueError(f'{name} must have shape (3,), got {arr.shape}')
    return arr


def matrix33(m: Any, name: str) -> np.ndarray:
    """``m`` as a float64 array of shape (3, 3); ``ValueError`` naming ``name`` otherwise."""
    mat = np.asarray(m, dtype=float)
    if mat.shape != (3, 3):
        raise ValueError(f'{name} must have shape (3, 3), got {mat.shape}')
    return mat


def _vector3(x: np.ndarray) -> Vector3:
    return Vector3(x=float(x[0]), y=float(x[1]), z=float(x[2]))


# --------------------------------------------------------------------------- inputs
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
    msg = Imu(header=header(t_ns, frame_id))
    msg.angular_velocity = _vector3(vec3(omega, 'omega'))
    msg.orientation_covariance[0] = -1.0
    msg.linear_acceleration_covariance[0] = -1.0
    return msg


def vector3_stamped(t_ns: int, v: Any, frame_id: str) -> Vector3Stamped:
    """Build a ``geometry_msgs/Vector3Stamped`` from a (3,) array (any unit)."""
    return Vector3Stamped(header=header(t_ns, frame_id), vector=_vector3(vec3(v, 'v')))


def wrench_msg(t_ns: int, tau: Any, frame_id: str) -> WrenchStamped:
    """Build a ``geometry_msgs/WrenchStamped`` with torque ``tau`` (3,) [N m] and zero force."""
    msg = WrenchStamped(header=header(t_ns, frame_id))
    msg.wrench.torque = _vector3(vec3(tau, 'tau'))
    return msg


def joint_state_msg(t_ns: int, names: Any, velocity: Any, frame_id: str = '') -> JointState:
    """Build a ``sensor_msgs/JointState`` carrying joint speeds only.

    Parameters
    ----------
    t_ns : int
        Header stamp [ns].
    names : sequence of str, length n
        Joint names (the wheels or rotors file's ``joint`` entries).
    velocity : array_like, shape (n,)
        Joint speeds [rad/s], in the order of ``names``.
    frame_id : str, optional
        Header frame (JointState usually leaves it empty).

    Returns
    -------
    sensor_msgs.msg.JointState
        ``name`` and ``velocity`` filled; ``position`` and ``effort`` empty (not measured).

    Raises
    ------
    ValueError
        If ``velocity`` is not a 1-D array with one entry per name.
    """
    names = [str(n) for n in names]
    v = np.asarray(velocity, dtype=float)
    if v.shape != (len(names),):
        raise ValueError(f'velocity must have shape ({len(names)},) for joints {names}, '
                         f'got {v.shape}')
    return JointState(header=header(t_ns, frame_id), name=names, velocity=v.tolist())


# --------------------------------------------------------------------------- outputs
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
    mat = matrix33(inertia, 'inertia')
    c = vec3(com, 'com')
    msg = InertiaStamped(header=header(t_ns, frame_id))
    i = msg.inertia
    i.m = float(mass)
    i.com = _vector3(c)
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
        Unit quaternion with ``w >= 0`` (:func:`inertia_ros.core.inertia.axes_to_quaternion`).

    Raises
    ------
    ValueError
        If ``axes`` is not a proper rotation matrix.
    """
    x, y, z, w = axes_to_quaternion(axes)
    msg = QuaternionStamped(header=header(t_ns, frame_id))
    msg.quaternion.x, msg.quaternion.y = float(x), float(y)
    msg.quaternion.z, msg.quaternion.w = float(z), float(w)
    return msg


# --------------------------------------------------------------------------- uncertainty
#: Layout label prefixes of ``~/inertia_covariance`` (row and column dimensions).
COVARIANCE_FULL = 'full covariance'
COVARIANCE_DIAGONAL = 'diagonal only (theta_std^2; correlations not available)'


def estimate_covariance(est: Any) -> tuple[np.ndarray, bool] | None:
    """The 6x6 covariance of the tensor elements of an estimate, and whether it is full.

    Parameters
    ----------
    est : InertiaEstimate
        A core result.

    Returns
    -------
    (cov, full) or None
        ``cov`` (6, 6) [kg^2 m^4] in the parameter order ``[ixx, iyy, izz, ixy, ixz, iyz]``:
        ``est.covariance`` when the core gives it, else ``est.diagnostics['covariance']``,
        else ``diag(theta_std^2)`` from ``est.inertia_std`` (``full`` False: no
        correlations); None when the estimate has no standard errors.  Undetermined
        elements are NaN.
    """
    for cov in (getattr(est, 'covariance', None), (est.diagnostics or {}).get('covariance')):
        if cov is not None:
            cov = np.asarray(cov, dtype=float)
            if cov.shape == (6, 6):
                return cov, True
    if est.inertia_std is None:
        return None
    std = np.asarray(est.inertia_std, dtype=float)
    theta_std = np.array([std[0, 0], std[1, 1], std[2, 2], std[0, 1], std[0, 2], std[1, 2]])
    return np.diag(theta_std ** 2), False


def covariance_msg(cov: Any, full: bool = True) -> Float64MultiArray:
    """A 6x6 covariance as ``std_msgs/Float64MultiArray`` with labelled dimensions.

    Parameters
    ----------
    cov : array_like, shape (6, 6)
        Covariance of ``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg^2 m^4], row-major in ``data``.
    full : bool
        False when only the diagonal is known (the label says so; off-diagonals are 0).

    Returns
    -------
    std_msgs.msg.Float64MultiArray
        ``layout.dim[0]`` (rows) and ``dim[1]`` (columns), each of size 6 and labelled
        ``'<kind> rows|cols: ixx iyy izz ixy ixz iyz [kg^2 m^4]'``.
    """
    cov = np.asarray(cov, dtype=float)
    if cov.shape != (6, 6):
        raise ValueError(f'covariance must have shape (6, 6), got {cov.shape}')
    kind = COVARIANCE_FULL if full else COVARIANCE_DIAGONAL
    names = ' '.join(THETA_NAMES)
    layout = MultiArrayLayout(dim=[
        MultiArrayDimension(label=f'{kind} rows: {names} [kg^2 m^4]', size=6, stride=36),
        MultiArrayDimension(label=f'{kind} cols: {names} [kg^2 m^4]', size=6, stride=6)],
        data_offset=0)
    return Float64MultiArray(layout=layout, data=cov.ravel().tolist())


def covariance_from_msg(msg: Float64MultiArray) -> tuple[np.ndarray, bool]:
    """Read :func:`covariance_msg` back: ``(cov (6, 6), full)``."""
    if [d.size for d in msg.layout.dim] != [6, 6] or len(msg.data) != 36:
        raise ValueError('not a 6x6 covariance message')
    return (np.asarray(msg.data, dtype=float).reshape(6, 6),
            msg.layout.dim[0].label.startswith(COVARIANCE_FULL))
