"""Vectorised CDR encoding of the messages the simulator writes, and their ros2msg schemas.

ROS 2 serialises messages as XCDR1 little-endian ("CDR_LE", encapsulation header
``00 01 00 00``); primitives are aligned to their size relative to the end of that 4-byte
header.  The stamped messages written here have a fixed layout for a given ``frame_id``::

    encapsulation (4) | stamp.sec int32 | stamp.nanosec uint32 | frame_id: uint32 length
    (including the NUL), bytes, NUL | padding to 8 | float64 fields ...

so a whole stream is encoded at once as one ``(N, size)`` byte array.  The output is
byte-identical to ``rclpy.serialization.serialize_message`` (tested).

Schemas: :func:`schema_text` and :data:`MSG_FIELDS` (the ``ros2msg`` text rosbag2 stores in an
MCAP schema record) live in :mod:`inertia_ros.io.msgtypes` and are re-exported here.

Time at this boundary is integer nanoseconds; ``sec = floor(t_ns / 1e9)`` must fit in int32.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from inertia_ros.io.msgtypes import MSG_FIELDS, schema_text

__all__ = [
    'IMU',
    'INERTIA_STAMPED',
    'MSG_FIELDS',
    'WRENCH_STAMPED',
    'encode_imu',
    'encode_inertia_stamped',
    'encode_stamped_float64',
    'encode_wrench_stamped',
    'schema_text',
    'split_stamp',
]

IMU = 'sensor_msgs/msg/Imu'
WRENCH_STAMPED = 'geometry_msgs/msg/WrenchStamped'
INERTIA_STAMPED = 'geometry_msgs/msg/InertiaStamped'

_ENCAPSULATION_CDR_LE = np.array([0, 1, 0, 0], dtype=np.uint8)
_NS = 1_000_000_000
_INT32_MAX = 2**31 - 1


def split_stamp(t_ns: Any) -> tuple[np.ndarray, np.ndarray]:
    """Split integer-nanosecond stamps into ``builtin_interfaces/Time`` parts.

    Parameters
    ----------
    t_ns : array_like of int, shape (N,)
        Stamps [ns].

    Returns
    -------
    sec : numpy.ndarray of int32, shape (N,)
        ``floor(t_ns / 1e9)``.
    nanosec : numpy.ndarray of uint32, shape (N,)
        Remainder in ``[0, 1e9)``.

    Raises
    ------
    ValueError
        If the stamps are not integers or the seconds do not fit in int32.
    """
    t = np.asarray(t_ns)
    if t.dtype.kind not in 'iu':
        raise ValueError(f't_ns: stamps must be integer nanoseconds, got dtype {t.dtype}')
    t = t.astype(np.int64).reshape(-1)
    sec = np.floor_divide(t, _NS)
    if sec.size and (sec.min() < -_INT32_MAX - 1 or sec.max() > _INT32_MAX):
        raise ValueError('t_ns: stamp seconds do not fit in int32')
    return sec.astype(np.int32), (t - sec * _NS).astype(np.uint32)


def encode_stamped_float64(t_ns: Any, frame_id: str, values: Any) -> list[bytes]:
    """CDR-encode messages made of a ``std_msgs/Header`` followed only by float64 fields.

    Parameters
    ----------
    t_ns : array_like of int, shape (N,)
        Header stamps [ns].
    frame_id : str
        Header frame (the same for every message).
    values : array_like, shape (N, K)
        The float64 fields in declaration order (nested types flattened).

    Returns
    -------
    list of bytes, length N
        One serialised message (with the 4-byte encapsulation header) each.

    Raises
    ------
    ValueError
        If the shapes disagree, the frame is not a string, or a stamp is out of range.
    """
    if not isinstance(frame_id, str):
        raise ValueError(f'frame_id: must be a string, got {frame_id!r}')
    sec, nsec = split_stamp(t_ns)
    vals = np.asarray(values, dtype=np.float64)
    n = sec.size
    if vals.ndim != 2 or vals.shape[0] != n:
        raise ValueError(f'values: expected shape ({n}, K), got {vals.shape}')
    frame = frame_id.encode('utf-8') + b'\x00'
    head = 4 + 4 + 4 + 4 + len(frame)
    pad = (-(head - 4)) % 8
    off = head + pad
    size = off + 8 * vals.shape[1]
    buf = np.zeros((n, size), dtype=np.uint8)
    buf[:, 0:4] = _ENCAPSULATION_CDR_LE
    buf[:, 4:8] = sec.astype('<i4').view(np.uint8).reshape(n, 4)
    buf[:, 8:12] = nsec.astype('<u4').view(np.uint8).reshape(n, 4)
    buf[:, 12:16] = np.frombuffer(np.array([len(frame)], dtype='<u4').tobytes(), np.uint8)
    buf[:, 16:head] = np.frombuffer(frame, dtype=np.uint8)
    buf[:, off:] = np.ascontiguousarray(vals, dtype='<f8').view(np.uint8).reshape(n, -1)
    raw = buf.tobytes()
    return [raw[i * size:(i + 1) * size] for i in range(n)]


def _rows(x: Any, n: int, width: int, name: str) -> np.ndarray:
    arr = np.asarray(x, dtype=np.float64)
    if arr.shape == (width,):
        arr = np.broadcast_to(arr, (n, width))
    if arr.shape != (n, width):
        raise ValueError(f'{name}: expected shape ({n}, {width}) or ({width},), got {arr.shape}')
    return arr


def _count(t_ns: Any) -> int:
    return int(np.asarray(t_ns).reshape(-1).size)


def encode_imu(t_ns: Any, omega: Any, frame_id: str, *,
               angular_velocity_covariance: Sequence[float] | np.ndarray | None = None
               ) -> list[bytes]:
    """Encode ``sensor_msgs/msg/Imu`` messages carrying only an angular velocity.

    Parameters
    ----------
    t_ns : array_like of int, shape (N,)
        Header stamps [ns].
    omega : array_like, shape (N, 3)
        Angular velocity [rad/s] in ``frame_id``.
    frame_id : str
        Gyro frame.
    angular_velocity_covariance : array_like, shape (9,) or (3, 3), optional
        Row-major covariance [(rad/s)^2]; zeros (unknown) by default.

    Returns
    -------
    list of bytes, length N
        Orientation and linear acceleration are marked absent: identity quaternion with
        covariance[0] = -1 and zero acceleration with covariance[0] = -1 (REP 145).
    """
    n = _count(t_ns)
    w = _rows(omega, n, 3, 'omega')
    cov = np.zeros(9) if angular_velocity_covariance is None else \
        np.asarray(angular_velocity_covariance, dtype=np.float64).reshape(-1)
    if cov.shape != (9,):
        raise ValueError(f'angular_velocity_covariance: expected 9 values, got {cov.size}')
    vals = np.zeros((n, 37))
    vals[:, 3] = 1.0            # orientation.w
    vals[:, 4] = -1.0           # orientation_covariance[0]: no orientation
    vals[:, 13:16] = w          # angular_velocity
    vals[:, 16:25] = cov        # angular_velocity_covariance
    vals[:, 28] = -1.0          # linear_acceleration_covariance[0]: no acceleration
    return encode_stamped_float64(t_ns, frame_id, vals)


def encode_wrench_stamped(t_ns: Any, torque: Any, frame_id: str, *,
                          force: Any = None) -> list[bytes]:
    """Encode ``geometry_msgs/msg/WrenchStamped`` messages.

    Parameters
    ----------
    t_ns : array_like of int, shape (N,)
        Header stamps [ns].
    torque : array_like, shape (N, 3)
        Torque about the centre of mass [N m] in ``frame_id``.
    frame_id : str
        Frame of the wrench.
    force : array_like, shape (N, 3) or (3,), optional
        Force [N]; zero by default.

    Returns
    -------
    list of bytes, length N
    """
    n = _count(t_ns)
    vals = np.zeros((n, 6))
    vals[:, 3:6] = _rows(torque, n, 3, 'torque')
    if force is not None:
        vals[:, 0:3] = _rows(force, n, 3, 'force')
    return encode_stamped_float64(t_ns, frame_id, vals)


def encode_inertia_stamped(t_ns: Any, inertia: Any, frame_id: str, *, mass: Any = 0.0,
                           com: Any = (0.0, 0.0, 0.0)) -> list[bytes]:
    """Encode ``geometry_msgs/msg/InertiaStamped`` messages.

    Parameters
    ----------
    t_ns : array_like of int, shape (N,)
        Header stamps [ns].
    inertia : array_like, shape (N, 3, 3) or (3, 3)
        Tensor about the centre of mass [kg m^2]; ``ixy`` is the matrix element.
    frame_id : str
        Frame the tensor is expressed in.
    mass : float or array_like, shape (N,), optional
        ``inertia.m`` [kg]; 0.0 (unknown) by default.
    com : array_like, shape (N, 3) or (3,), optional
        ``inertia.com`` [m]; zero by default (the tensor is about the centre of mass).

    Returns
    -------
    list of bytes, length N
    """
    n = _count(t_ns)
    mats = np.asarray(inertia, dtype=np.float64)
    if mats.shape == (3, 3):
        mats = np.broadcast_to(mats, (n, 3, 3))
    if mats.shape != (n, 3, 3):
        raise ValueError(f'inertia: expected shape ({n}, 3, 3) or (3, 3), got {mats.shape}')
    m = np.broadcast_to(np.asarray(mass, dtype=np.float64), (n,))
    vals = np.empty((n, 10))
    vals[:, 0] = m
    vals[:, 1:4] = _rows(com, n, 3, 'com')
    vals[:, 4] = mats[:, 0, 0]
    vals[:, 5] = mats[:, 0, 1]
    vals[:, 6] = mats[:, 0, 2]
    vals[:, 7] = mats[:, 1, 1]
    vals[:, 8] = mats[:, 1, 2]
    vals[:, 9] = mats[:, 2, 2]
    return encode_stamped_float64(t_ns, frame_id, vals)
