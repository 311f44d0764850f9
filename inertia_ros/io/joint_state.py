"""``sensor_msgs/msg/JointState`` (wheel speeds) in logs: CDR encoding, decoding and reading.

JointState has variable-length arrays, so it is decoded per message here rather than by the
fixed-layout vectorised decoder of :mod:`.cdr_decode`.  Wheel speeds are ``velocity`` [rad/s]
(the ROS convention for joint speeds), matched to the wheels by ``name``.  :func:`joint_rows`
turns messages into rows of the wanted joints' speeds, each with a status saying why a
message cannot be used; :func:`inertia_ros.io.logs.read_log` cleans those rows as the third
stream of a log (pauses, NaN, clock repair, gaps), as it does the gyro and torque.
"""
from __future__ import annotations

import struct
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .cdr_encode import split_stamp
from .log_topics import JOINT_STATE
from .log_types import LogError, missing_joints_error

__all__ = ['JOINT_STATE', 'ROW_AMBIGUOUS', 'ROW_INCOMPLETE', 'ROW_MALFORMED', 'ROW_MISMATCHED',
           'ROW_OK', 'decode_joint_state', 'encode_joint_message', 'encode_joint_state',
           'first_joint_names', 'joint_messages', 'joint_rows', 'joint_state_topics',
           'read_wheel_speeds']

#: :func:`joint_rows` status: usable, undecodable, name/velocity lengths differ, a wanted
#: joint absent (or no velocity at all), a wanted joint named twice with different speeds.
ROW_OK, ROW_MALFORMED, ROW_MISMATCHED, ROW_INCOMPLETE, ROW_AMBIGUOUS = range(5)


def _align(buf: bytearray, n: int) -> None:
    """Pad ``buf`` (payload after the 4-byte encapsulation header) to a multiple of ``n``."""
    buf.extend(b'\0' * ((-(len(buf) - 4)) % n))


def _put_string(buf: bytearray, s: str) -> None:
    b = s.encode('utf-8') + b'\0'
    _align(buf, 4)
    buf.extend(struct.pack('<I', len(b)))
    buf.extend(b)


def _put_doubles(buf: bytearray, x: np.ndarray) -> None:
    _align(buf, 4)
    buf.extend(struct.pack('<I', len(x)))
    if len(x):
        _align(buf, 8)
        buf.extend(np.asarray(x, dtype='<f8').tobytes())


def encode_joint_state(t_ns: Any, names: Sequence[str], velocity: Any, frame_id: str = '', *,
                       position: Any = None) -> list[bytes]:
    """Encode ``sensor_msgs/msg/JointState`` messages (little-endian CDR).

    Parameters
    ----------
    t_ns : array_like of int, shape (K,)
        Header stamps [ns].
    names : sequence of str, length n
        Joint names, the same in every message.
    velocity : array_like, shape (K, n)
        Joint speeds [rad/s].
    frame_id : str
        Header frame (JointState usually leaves it empty).
    position : array_like, shape (K, n), optional
        Joint angles [rad]; empty arrays when not given.  ``effort`` is always empty.

    Returns
    -------
    list of bytes, length K
    """
    t = np.asarray(t_ns, dtype=np.int64).reshape(-1)
    v = np.asarray(velocity, dtype=float).reshape(len(t), len(names))
    p = None if position is None else np.asarray(position, dtype=float).reshape(v.shape)
    return [encode_joint_message(int(t[k]), names, v[k], frame_id,
                                 position=() if p is None else p[k]) for k in range(len(t))]


def encode_joint_message(t_ns: int, names: Sequence[str], velocity: Any, frame_id: str = '',
                         *, position: Any = ()) -> bytes:
    """Encode one ``sensor_msgs/msg/JointState`` message, arrays of any lengths (also
    inconsistent ones, as a faulty driver sends them).

    Parameters
    ----------
    t_ns : int
        Header stamp [ns].
    names : sequence of str, length n
    velocity : array_like, shape (m,)
        Joint speeds [rad/s]; ``m`` need not equal ``n``.
    frame_id : str
    position : array_like, shape (p,)
        Joint angles [rad].

    Returns
    -------
    bytes
    """
    sec, nsec = split_stamp(np.array([t_ns], dtype=np.int64))
    buf = bytearray(b'\x00\x01\x00\x00')
    buf.extend(struct.pack('<iI', int(sec[0]), int(nsec[0])))
    _put_string(buf, frame_id)
    _align(buf, 4)
    buf.extend(struct.pack('<I', len(names)))
    for nm in names:
        _put_string(buf, nm)
    _put_doubles(buf, np.asarray(position, dtype=float).reshape(-1))
    _put_doubles(buf, np.asarray(velocity, dtype=float).reshape(-1))
    _put_doubles(buf, np.zeros(0))
    return bytes(buf)


def decode_joint_state(data: bytes) -> tuple[int, list[str], np.ndarray, np.ndarray]:
    """Decode one JointState payload.

    Returns
    -------
    stamp_ns : int
        Header stamp [ns].
    names : list of str
    position, velocity : ndarray
        As sent (each may be empty) [rad], [rad/s].

    Raises
    ------
    ValueError
        Not plain CDR, or truncated.
    """
    return _decode(data)[:4]


def _decode(data: bytes) -> tuple[int, list[str], np.ndarray, np.ndarray, list[int]]:
    """:func:`decode_joint_state`, and the layout: the byte offsets (count end, data start,
    data end) of the position and then of the velocity array."""
    if len(data) < 12 or data[0] != 0 or data[1] not in (0, 1):
        raise ValueError('JointState payload: not plain CDR or too short')
    e = '<' if data[1] == 1 else '>'
    pos = 4
    marks: list[int] = []

    def align(n: int) -> None:
        nonlocal pos
        pos += (-(pos - 4)) % n

    def u32() -> int:
        nonlocal pos
        align(4)
        (v,) = struct.unpack_from(e + 'I', data, pos)
        pos += 4
        return int(v)

    def string() -> str:
        nonlocal pos
        n = u32()
        s = data[pos:pos + n - 1].decode('utf-8') if n > 1 else ''
        pos += n
        return s

    def doubles() -> np.ndarray:
        nonlocal pos
        n = u32()
        marks.append(pos)
        if n == 0:
            marks.extend((pos, pos))
            return np.zeros(0)
        align(8)
        x = np.frombuffer(data, dtype=e + 'f8', count=n, offset=pos).astype(float)
        marks.extend((pos, pos + 8 * n))
        pos += 8 * n
        return x

    try:
        sec, nsec = struct.unpack_from(e + 'iI', data, pos)
        pos += 8
        string()
        names = [string() for _ in range(u32())]
        position = doubles()
        velocity = doubles()
    except (struct.error, ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f'JointState payload: truncated or malformed ({exc})') from None
    return int(sec) * 1_000_000_000 + int(nsec), names, position, velocity, marks


def joint_state_topics(path: str | Path) -> list[str]:
    """Topics of type ``sensor_msgs/msg/JointState`` in a log (file or rosbag2 directory)."""
    from .logs import log_files
    from .mcap_reader import McapReader
    from .msgtypes import normalise_type

    out: set[str] = set()
    for f in log_files(path):
        with McapReader(f) as r:
            for ch in r.channels.values():
                sc = r.schemas.get(ch.schema_id)
                if sc is not None and normalise_type(sc.name) == JOINT_STATE:
                    out.add(ch.topic)
    return sorted(out)


def joint_messages(path: str | Path, topic: str) -> Iterator[tuple[int, list[str], Any]]:
    """Every decodable JointState message of ``topic`` in a log, in file order.

    Yields
    ------
    (t_ns, names, velocity)
        Header stamp [ns], ``JointState.name`` and ``JointState.velocity`` [rad/s] (possibly
        shorter than the names); undecodable messages are skipped.
    """
    from .logs import log_files
    from .mcap_reader import McapReader
    from .msgtypes import normalise_type

    def select(ch: Any, sc: Any) -> bool:
        return ch.topic == topic and sc is not None and normalise_type(sc.name) == JOINT_STATE

    for f in log_files(path):
        with McapReader(f) as r:
            for _sc, _ch, _lt, data in r.iter_messages(select):
                try:
                    st, names, _p, vel = decode_joint_state(data)
                except ValueError:
                    continue
                yield st, list(names), vel


def first_joint_names(path: str | Path, topic: str) -> list[str] | None:
    """The names of the first JointState message of ``topic`` with a velocity for every name
    (None when there is none)."""
    for _t, names, vel in joint_messages(path, topic):
        if names and len(vel) == len(names):
            return names
    return None


def _match(names: list[str], velocity: np.ndarray, joints: Sequence[str]
           ) -> tuple[int, np.ndarray | None]:
    """The wanted joints' speeds in one message, or why there are none.

    Returns
    -------
    (status, speeds)
        A ``ROW_*`` status and, for ``ROW_OK``, the speeds (len(joints),) [rad/s] in the
        order of ``joints`` (possibly non-finite: the cleaning counts those).
    """
    if len(velocity) == 0:
        return ROW_INCOMPLETE, None
    if len(velocity) != len(names):
        return ROW_MISMATCHED, None
    where: dict[str, list[int]] = {}
    for i, nm in enumerate(names):
        where.setdefault(nm, []).append(i)
    out = np.empty(len(joints))
    for c, j in enumerate(joints):
        at = where.get(j)
        if at is None:
            return ROW_INCOMPLETE, None
        v = velocity[at]
        if v.size > 1 and not (np.all(v == v[0]) or np.all(np.isnan(v))):
            return ROW_AMBIGUOUS, None
        out[c] = v[0]
    return ROW_OK, out


def joint_rows(buf: Any, starts: np.ndarray, lengths: np.ndarray, joints: Sequence[str]
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, set[str]]:
    """Decode a batch of JointState payloads into rows of the wanted joints' speeds.

    Messages laid out as the first one (the same names, frame and array lengths: the usual
    stream) are read together by their byte offsets; any other message is decoded alone.

    Parameters
    ----------
    buf : numpy.ndarray or bytes
        uint8 (B,) buffer holding the payloads.
    starts, lengths : numpy.ndarray
        int (n,) byte offsets and lengths of the payloads in ``buf``.
    joints : sequence of str
        The joints wanted, k of them (the wheels or rotors file's ``joint`` entries).

    Returns
    -------
    stamp_ns : numpy.ndarray
        int64 (n,) header stamps [ns] (0 where undecodable).
    speed : numpy.ndarray
        float64 (n, k) [rad/s], NaN in rows that are not ``ROW_OK``.
    status : numpy.ndarray
        int8 (n,) ``ROW_*`` status of each message.
    names : set of str
        Every joint name seen.
    """
    b = buf if isinstance(buf, np.ndarray) else np.frombuffer(buf, np.uint8)
    starts = np.asarray(starts, dtype=np.int64)
    lengths = np.asarray(lengths, dtype=np.int64)
    n = starts.size
    stamp = np.zeros(n, np.int64)
    speed = np.full((n, len(joints)), np.nan)
    status = np.full(n, ROW_MALFORMED, np.int8)
    seen: set[str] = set()
    todo = np.ones(n, bool)
    if n:
        todo &= ~_like_first(b, starts, lengths, joints, stamp, speed, status, seen)
    for r in np.flatnonzero(todo).tolist():
        try:
            st, names, _pos, vel = decode_joint_state(b[starts[r]:starts[r] + lengths[r]]
                                                      .tobytes())
        except ValueError:
            continue
        seen.update(names)
        code, row = _match(names, vel, joints)
        stamp[r], status[r] = st, code
        if row is not None:
            speed[r] = row
    return stamp, speed, status, seen


def _like_first(b: np.ndarray, starts: np.ndarray, lengths: np.ndarray, joints: Sequence[str],
                stamp: np.ndarray, speed: np.ndarray, status: np.ndarray, seen: set[str]
                ) -> np.ndarray:
    """Fill the rows of the messages laid out byte for byte as the first one (every byte
    equal but the stamp and the array values); return which they are, bool (n,)."""
    none = np.zeros(starts.size, bool)
    first = b[starts[0]:starts[0] + lengths[0]].tobytes()
    try:
        _st, names, _pos, vel, marks = _decode(first)
    except ValueError:
        return none
    if any(names.count(j) > 1 for j in joints):
        return none                   # duplicated joints: value by value, message by message
    code, _row = _match(names, vel, joints)
    p_cnt, p_lo, p_hi, v_cnt, v_lo, v_hi = marks
    size = len(first)
    fixed = np.r_[0:4, 12:p_cnt, p_hi:v_cnt, v_hi:min(v_hi + 4, size)]
    cand = np.flatnonzero(lengths == size)
    s0 = starts[cand]
    tmpl = np.frombuffer(first, np.uint8)
    same = np.ones(cand.size, bool)
    for c in fixed.tolist():
        same &= b[s0 + c] == tmpl[c]
    rows, s0 = cand[same], s0[same]
    e = '<' if first[1] == 1 else '>'

    def field(lo: int, hi: int, dtype: str) -> np.ndarray:
        raw = np.stack([b[s0 + c] for c in range(lo, hi)], axis=1) if hi > lo \
            else np.zeros((s0.size, 0), np.uint8)
        return np.ascontiguousarray(raw).view(e + dtype)

    sec, nsec = field(4, 8, 'i4')[:, 0], field(8, 12, 'u4')[:, 0]
    stamp[rows] = sec.astype(np.int64) * 1_000_000_000 + nsec.astype(np.int64)
    status[rows] = code
    if code == ROW_OK:
        col = [names.index(j) for j in joints]
        speed[rows] = field(v_lo, v_hi, 'f8')[:, col].astype(float)
    seen.update(names)
    out = none.copy()
    out[rows] = True
    return out


def read_wheel_speeds(path: str | Path, joints: Sequence[str], topic: str | None = None,
                      what: str = 'wheels') -> tuple[str, np.ndarray, np.ndarray]:
    """Wheel speeds of the named joints from the JointState messages of a log, uncleaned
    (for tools that show or replay the stream; the estimate reads them with
    :func:`inertia_ros.io.logs.read_log`, which cleans them like the other streams).

    Parameters
    ----------
    path : str or Path
        ``.mcap`` file or rosbag2 directory.
    joints : sequence of str
        Joint names wanted (the wheels file's ``joint`` entries).
    topic : str, optional
        JointState topic; found by type when there is exactly one.
    what : {'wheels', 'rotors'}
        What the joints are (names the CLI option and the file in the messages).

    Returns
    -------
    topic : str
    t_ns : ndarray of int64, shape (K,)
        Header stamps [ns], sorted, duplicates removed; only messages carrying every joint.
    speed : ndarray, shape (K, len(joints))
        [rad/s].

    Raises
    ------
    LogError
        No or several JointState topics, a joint never present, no velocities.
    """
    if topic is None:
        found = joint_state_topics(path)
        if not found:
            raise LogError(f'{path}: no sensor_msgs/msg/JointState topic; record the '
                           f'{what[:-1]} speeds as JointState or drop --{what}')
        if len(found) > 1:
            raise LogError(f'{path}: several JointState topics {found}; choose one with '
                           f'--{what[:-1]}-topic')
        topic = found[0]
    stamps: list[int] = []
    rows: list[np.ndarray] = []
    seen: set[str] = set()
    for st, names, vel in joint_messages(path, topic):
        seen.update(names)
        code, row = _match(names, vel, joints)
        if row is not None:
            stamps.append(st)
            rows.append(row)
    missing = [j for j in joints if j not in seen]
    if missing:
        raise missing_joints_error(topic, missing, seen, what)
    if len(stamps) < 2:
        raise LogError(f'{topic}: fewer than 2 messages carry velocities for all of '
                       f'{list(joints)}')
    t = np.array(stamps, dtype=np.int64)
    v = np.array(rows)
    order = np.argsort(t, kind='stable')
    t, v = t[order], v[order]
    keep = np.append(True, np.diff(t) > 0)
    return topic, t[keep], v[keep]
