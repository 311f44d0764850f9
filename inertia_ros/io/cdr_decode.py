"""Decoding of the CDR payloads of the stamped ROS 2 messages we read, one at a time or in bulk.

Every message type here is a ``std_msgs/Header`` followed only by float64 fields, so once the
length of ``header.frame_id`` is known the whole layout is fixed::

    offset 0   encapsulation (0x00 0x00 = CDR big-endian, 0x00 0x01 = CDR little-endian), 2 bytes
               of options
    offset 4   int32 stamp.sec        (CDR alignment is counted from offset 4)
    offset 8   uint32 stamp.nanosec
    offset 12  uint32 L = len(frame_id) + 1, then L bytes (frame_id and a NUL)
    offset 4 + align8(12 + L)    the float64 fields, back to back

:func:`decode_batch` uses that: it groups the messages of a batch by (endianness, L), and for
each group gathers the needed bytes of every message with one fancy index and views them as
float64, with no Python loop over messages.  :func:`decode_message` is the scalar reference
decoder (struct-based, one message), used for single messages and to cross-check the fast
path.  Both give bit-for-bit the values ``mcap_ros2``'s decoder gives (tested).

Only plain CDR (XCDR1) as ROS 2 writes it is supported; parameter-list encapsulations are
reported as malformed.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from inertia_ros.io.msgtypes import normalise_type

#: Float64 fields after the header, per message type: (name, number of float64).
LAYOUTS: dict[str, tuple[tuple[str, int], ...]] = {
    'sensor_msgs/msg/Imu': (
        ('orientation', 4), ('orientation_covariance', 9), ('angular_velocity', 3),
        ('angular_velocity_covariance', 9), ('linear_acceleration', 3),
        ('linear_acceleration_covariance', 9)),
    'geometry_msgs/msg/WrenchStamped': (('force', 3), ('torque', 3)),
    'geometry_msgs/msg/Vector3Stamped': (('vector', 3),),
    'geometry_msgs/msg/TwistStamped': (('linear', 3), ('angular', 3)),
    'geometry_msgs/msg/InertiaStamped': (
        ('m', 1), ('com', 3), ('ixx', 1), ('ixy', 1), ('ixz', 1), ('iyy', 1), ('iyz', 1),
        ('izz', 1)),
}

#: Order of the components of each multi-element field, for :func:`decode_message`.
_COMPONENTS = {
    'orientation': ('x', 'y', 'z', 'w'),
    'angular_velocity': ('x', 'y', 'z'), 'linear_acceleration': ('x', 'y', 'z'),
    'force': ('x', 'y', 'z'), 'torque': ('x', 'y', 'z'), 'vector': ('x', 'y', 'z'),
    'linear': ('x', 'y', 'z'), 'angular': ('x', 'y', 'z'), 'com': ('x', 'y', 'z'),
}

_HEAD = 16  # encapsulation + sec + nanosec + string length
_TEXT = 16  # frame_id bytes gathered with the fixed head (longer ones are gathered apart)


def _layout(msg_type: str) -> tuple[tuple[str, int], ...]:
    try:
        return LAYOUTS[normalise_type(msg_type)]
    except KeyError:
        raise ValueError(f'msg_type: {msg_type!r} is not supported; supported types are '
                         f'{", ".join(LAYOUTS)}') from None


def _field_offsets(msg_type: str) -> dict[str, tuple[int, int]]:
    """{field: (offset in float64 from the start of the body, count)}."""
    out = {}
    pos = 0
    for name, count in _layout(msg_type):
        out[name] = (pos, count)
        pos += count
    return out


def body_offset(frame_len: int) -> int:
    """Byte offset of the first float64 field for a CDR string length ``frame_len`` (with NUL).

    Parameters
    ----------
    frame_len : int
        The serialised string length L (len(frame_id) + 1, or 0 for an empty string written
        without its NUL).

    Returns
    -------
    int
        ``4 + align8(12 + L)`` [bytes].
    """
    return 4 + ((12 + frame_len + 7) // 8) * 8


def message_size(msg_type: str, frame_len: int) -> int:
    """Minimum payload size [bytes] of ``msg_type`` with a frame_id of serialised length L."""
    return body_offset(frame_len) + 8 * sum(c for _, c in _layout(msg_type))


# --------------------------------------------------------------------------------------------
# Scalar reference decoder


def decode_message(msg_type: str, data: bytes) -> dict:
    """Decode one CDR payload into a plain nested dict (the reference, scalar path).

    Parameters
    ----------
    msg_type : str
        One of :data:`LAYOUTS` (``pkg/Type`` also accepted).
    data : bytes
        The serialised message, encapsulation header included.

    Returns
    -------
    dict
        ``{'header': {'stamp': {'sec', 'nanosec'}, 'frame_id'}, field: ...}`` where vector
        fields are dicts of components (``x``, ``y``, ``z``[, ``w``]), covariances lists of 9
        floats and scalars floats.

    Raises
    ------
    ValueError
        Unsupported type, unknown encapsulation, or a payload too short for its layout.
    """
    layout = _layout(msg_type)
    if len(data) < _HEAD:
        raise ValueError(f'data: {len(data)} bytes is too short for a stamped message '
                         f'(at least {_HEAD})')
    if data[0] != 0 or data[1] not in (0, 1):
        raise ValueError(f'data: encapsulation 0x{data[0]:02x}{data[1]:02x} is not plain CDR')
    e = '<' if data[1] == 1 else '>'
    sec, nsec, flen = struct.unpack_from(e + 'iII', data, 4)
    need = message_size(msg_type, flen)
    if len(data) < need:
        raise ValueError(f'data: {len(data)} bytes is too short for {normalise_type(msg_type)} '
                         f'with a {flen}-byte frame_id (needs {need})')
    frame = data[16:16 + flen - 1].decode('utf-8') if flen > 1 else ''
    out: dict = {'header': {'stamp': {'sec': sec, 'nanosec': nsec}, 'frame_id': frame}}
    pos = body_offset(flen)
    for name, count in layout:
        vals = struct.unpack_from(f'{e}{count}d', data, pos)
        pos += 8 * count
        if name in _COMPONENTS:
            out[name] = dict(zip(_COMPONENTS[name], vals, strict=True))
        elif count == 1:
            out[name] = vals[0]
        else:
            out[name] = list(vals)
    return out


# --------------------------------------------------------------------------------------------
# Vectorised decoder


@dataclass(frozen=True)
class DecodedBatch:
    """Decoded messages of one type.

    Attributes
    ----------
    msg_type : str
        ROS 2 type name.
    stamp_ns : numpy.ndarray
        int64 (n,), ``header.stamp`` as ``sec * 1e9 + nanosec`` [ns]; 0 where not ``ok``.
    frame_index : numpy.ndarray
        int32 (n,), index of each message's ``header.frame_id`` in ``frame_ids``; -1 where
        not ``ok``.
    frame_ids : tuple of str
        The distinct frame ids of the batch.
    fields : dict of str to numpy.ndarray
        float64 (n, k) per requested field (k components, e.g. 3 for a Vector3); NaN where
        not ``ok``.
    ok : numpy.ndarray
        bool (n,), False for payloads that are malformed (too short, not plain CDR, frame_id
        not UTF-8).
    """

    msg_type: str
    stamp_ns: np.ndarray
    frame_index: np.ndarray
    frame_ids: tuple[str, ...]
    fields: dict[str, np.ndarray]
    ok: np.ndarray

    def __len__(self) -> int:
        return int(self.stamp_ns.shape[0])


def _gather(buf: np.ndarray, starts: np.ndarray, offset: int, nbytes: int) -> np.ndarray:
    """Bytes ``buf[s + offset : s + offset + nbytes]`` for every s, as a (n, nbytes) array.

    ``buf`` is seen as overlapping ``nbytes``-byte void items, one starting at every byte, so
    the gather copies one item per message (a memcpy each), not one index per byte; every
    ``s + offset + nbytes`` must be within ``buf``.
    """
    n = starts.shape[0]
    if nbytes <= 0 or n == 0:
        return np.zeros((n, max(nbytes, 0)), dtype=np.uint8)
    if not buf.flags.c_contiguous:
        return sliding_window_view(buf, nbytes)[starts + offset]
    items = np.ndarray(shape=(buf.shape[0] - nbytes + 1,), dtype=np.dtype(f'V{nbytes}'),
                       buffer=buf, strides=(1,))
    return items[starts + offset].view(np.uint8).reshape(n, nbytes)


def decode_batch(msg_type: str, buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray,
                 fields: tuple[str, ...] | None = None) -> DecodedBatch:
    """Decode many CDR payloads of one type at once.

    Parameters
    ----------
    msg_type : str
        One of :data:`LAYOUTS` (``pkg/Type`` also accepted).
    buf : numpy.ndarray
        uint8 (B,), the buffer holding the payloads.
    starts : numpy.ndarray
        int (n,), byte offset of each payload in ``buf``.
    lengths : numpy.ndarray
        int (n,), payload sizes [bytes]; payloads must lie inside ``buf``.
    fields : tuple of str, optional
        Fields to decode (default: all of the type's fields).

    Returns
    -------
    DecodedBatch
        Stamps, frame ids and fields, with ``ok`` marking malformed payloads.

    Raises
    ------
    ValueError
        Unsupported type, unknown field name, or inconsistent array shapes.
    """
    offs = _field_offsets(msg_type)
    names = tuple(offs) if fields is None else tuple(fields)
    for f in names:
        if f not in offs:
            raise ValueError(f'fields: {msg_type} has no field {f!r}; it has {", ".join(offs)}')
    buf, starts, lengths = _checked_arrays(buf, starts, lengths)
    n = starts.shape[0]
    total = sum(c for _, c in _layout(msg_type))
    stamp = np.zeros(n, dtype=np.int64)
    frame_index = np.full(n, -1, dtype=np.int32)
    out: dict[str, np.ndarray] = {}
    ok, cand, key, pre = _candidates(buf, starts, lengths, total)
    frame_table: dict[bytes, int] = {}
    if cand.size:
        if key.min() == key.max():  # the usual case: one layout for the whole batch
            groups = [(int(key[0]), cand, pre)]
        else:
            ukeys, inv = np.unique(key, return_inverse=True)
            groups = [(k, cand[inv == g], pre[inv == g]) for g, k in enumerate(ukeys.tolist())]
        # every row decodable as one layout: results go in whole, without a scatter
        single = cand.size == n and len(groups) == 1
        wanted = {f: offs[f] for f in names}
        for k, rows, head in groups:
            g_stamp, g_frame, g_vals, g_bad = _decode_group(buf, starts[rows], head, k, wanted,
                                                            frame_table)
            if single:
                stamp, frame_index, out = g_stamp, g_frame, g_vals
            else:
                stamp[rows] = g_stamp
                frame_index[rows] = g_frame
                for f, vals in g_vals.items():
                    if f not in out:
                        out[f] = np.full((n, vals.shape[1]), np.nan)
                    out[f][rows] = vals
            if g_bad is not None:
                ok[rows[g_bad]] = False
    for f in names:
        if f not in out:
            out[f] = np.full((n, offs[f][1]), np.nan)
    bad = ~ok
    if bad.any():
        stamp[bad] = 0
        frame_index[bad] = -1
        for f in names:
            out[f][bad] = np.nan
    frame_ids = tuple(b.decode('utf-8', errors='replace') for b in frame_table)
    return DecodedBatch(normalise_type(msg_type), stamp, frame_index, frame_ids, out, ok)


def _checked_arrays(buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`decode_batch`'s buffer and payload extents, checked: (buf, starts, lengths).

    Raises
    ------
    ValueError
        ``buf`` not 1-D uint8, ``starts`` and ``lengths`` not equal 1-D shapes, or a
        payload outside ``buf``.
    """
    buf = np.asarray(buf)
    if buf.dtype != np.uint8 or buf.ndim != 1:
        raise ValueError(f'buf: expected a 1-D uint8 array, got {buf.dtype} {buf.shape}')
    starts = np.asarray(starts, dtype=np.int64)
    lengths = np.asarray(lengths, dtype=np.int64)
    if starts.shape != lengths.shape or starts.ndim != 1:
        raise ValueError(f'starts, lengths: expected equal 1-D shapes, got {starts.shape} and '
                         f'{lengths.shape}')
    if starts.shape[0] and (starts.min() < 0
                            or int((starts + lengths).max()) > buf.shape[0]):
        raise ValueError('starts, lengths: a payload lies outside buf')
    return buf, starts, lengths


def _candidates(buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray, total: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The payloads whose fixed head is well formed and which are long enough for the type.

    Parameters
    ----------
    buf, starts, lengths : numpy.ndarray
        As for :func:`decode_batch` (checked).
    total : int
        Number of float64 values the type holds after its header.

    Returns
    -------
    ok : numpy.ndarray
        bool (n,), False for the payloads found malformed so far.
    cand : numpy.ndarray
        int64 (m,), the rows still decodable.
    key : numpy.ndarray
        int64 (m,), their layout: ``kind << 40 | L`` (kind 1 = little-endian, L the CDR
        length of ``frame_id``).
    pre : numpy.ndarray
        uint8 (m, 16 or 32), their first bytes (the fixed head, and when the buffer allows
        the next 16, so that a short ``frame_id`` is read from it).
    """
    ok = lengths >= _HEAD
    cand = np.flatnonzero(ok)
    if not cand.size:
        return ok, cand, np.zeros(0, np.int64), np.zeros((0, _HEAD), dtype=np.uint8)
    # one gather of the 16 fixed bytes (encapsulation, stamp, frame_id length) and, when
    # the buffer allows, the next 16 too: a frame_id that fits is then read from it
    wide = _HEAD + _TEXT if int(starts[cand].max()) + _HEAD + _TEXT <= buf.shape[0] \
        else _HEAD
    pre = _gather(buf, starts[cand], 0, wide)
    kind = pre[:, 1]
    good = (pre[:, 0] == 0) & (kind <= 1)
    raw_len = pre[:, 12:16].copy()
    flen = np.where(kind == 1, raw_len.view('<u4').ravel(),
                    raw_len.view('>u4').ravel()).astype(np.int64)
    need = 4 + ((12 + flen + 7) // 8) * 8 + 8 * total
    good &= lengths[cand] >= need
    if not good.all():
        ok[cand[~good]] = False
        cand, kind, flen, pre = cand[good], kind[good], flen[good], pre[good]
    return ok, cand, kind.astype(np.int64) << 40 | flen, pre


def _decode_group(buf: np.ndarray, s: np.ndarray, head: np.ndarray, key: int,
                  fields: dict[str, tuple[int, int]], frame_table: dict[bytes, int]
                  ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray | None]:
    """Decode the payloads of one layout (endianness and ``frame_id`` length).

    Parameters
    ----------
    buf : numpy.ndarray
        uint8 (B,), the buffer.
    s : numpy.ndarray
        int64 (m,), byte offsets of the group's payloads in ``buf``.
    head : numpy.ndarray
        uint8 (m, w), their first ``w`` >= 16 bytes.
    key : int
        The layout, ``kind << 40 | L`` (see :func:`_candidates`).
    fields : dict
        Field name -> (first float64, count) to decode.
    frame_table : dict
        ``frame_id`` bytes -> code, shared by the batch's groups (extended here).

    Returns
    -------
    stamp : numpy.ndarray
        int64 (m,), header stamps [ns].
    frame : numpy.ndarray
        int32 (m,), codes of the ``frame_id``s in ``frame_table``.
    values : dict
        Field name -> float64 (m, count).
    bad : numpy.ndarray or None
        bool (m,), rows whose ``frame_id`` is not UTF-8 (None when there are none).
    """
    L = key & ((1 << 40) - 1)
    e = '<' if (key >> 40) == 1 else '>'
    sec = head[:, 4:8].copy().view(e + 'i4').ravel().astype(np.int64)
    nsec = head[:, 8:12].copy().view(e + 'u4').ravel().astype(np.int64)
    stamp = sec * 1_000_000_000 + nsec
    # frame ids: usually one per group, so compare rows before paying for np.unique
    if L - 1 <= head.shape[1] - _HEAD:
        text = head[:, _HEAD:_HEAD + max(L - 1, 0)]   # in the prefix already
    else:
        text = _gather(buf, s, 16, max(L - 1, 0))
    if text.shape[1] == 0 or bool(np.all(text == text[0])):
        uniq_rows, uinv = text[:1], np.zeros(len(s), dtype=np.int64)
    else:
        uniq_rows, uinv = np.unique(text, axis=0, return_inverse=True)
        uinv = uinv.ravel()
    codes = np.empty(uniq_rows.shape[0], dtype=np.int32)
    bad_code = np.zeros(uniq_rows.shape[0], dtype=bool)
    for j, row in enumerate(uniq_rows):
        raw = row.tobytes()
        try:
            raw.decode('utf-8')
        except UnicodeDecodeError:
            bad_code[j] = True
        codes[j] = frame_table.setdefault(raw, len(frame_table))
    frame = (np.full(len(s), codes[0], dtype=np.int32) if codes.shape[0] == 1
             else codes[uinv])
    body = body_offset(L)
    values = {}
    for f, (first, count) in fields.items():
        cols = _gather(buf, s, body + 8 * first, 8 * count)
        values[f] = cols.view(e + 'f8').astype(np.float64, copy=False)
    return stamp, frame, values, (bad_code[uinv] if bad_code.any() else None)


def decode_payloads(msg_type: str, payloads: list[bytes],
                    fields: tuple[str, ...] | None = None) -> DecodedBatch:
    """Convenience: :func:`decode_batch` over a list of payloads (copies them into one buffer).

    Parameters
    ----------
    msg_type : str
        One of :data:`LAYOUTS`.
    payloads : list of bytes
        Serialised messages.
    fields : tuple of str, optional
        Fields to decode (default all).

    Returns
    -------
    DecodedBatch
    """
    lengths = np.array([len(p) for p in payloads], dtype=np.int64)
    starts = np.zeros(len(payloads), dtype=np.int64)
    if len(payloads) > 1:
        np.cumsum(lengths[:-1], out=starts[1:])
    buf = np.frombuffer(b''.join(payloads), dtype=np.uint8)
    return decode_batch(msg_type, buf, starts, lengths, fields)
