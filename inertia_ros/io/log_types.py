"""The records of the log layer: :class:`LogError`, :class:`StreamCounts`, :class:`Stream` and
:class:`LogData` (what :func:`inertia_ros.io.logs.read_log` returns).
"""
from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inertia_ros.io import cdr_decode
from inertia_ros.io.mcap_reader import Damage

__all__ = ['JointCounts', 'LogData', 'LogError', 'PreparedStream', 'RawTopic', 'Stream',
           'StreamCounts']


class LogError(ValueError):
    """A problem with the input log that the user can fix; the message is one line."""


@dataclass
class StreamCounts:
    """What cleaning did to one stream (numbers of messages)."""

    received: int = 0
    malformed: int = 0
    nonfinite: int = 0
    wrong_frame: int = 0
    duplicates: int = 0
    out_of_order: int = 0
    bad_stamps: int = 0
    outside: int = 0
    used: int = 0
    gaps: int = 0
    clock_faults: int = 0
    stamp_conflicts: int = 0

    @property
    def dropped(self) -> int:
        """Messages received but not used."""
        return self.received - self.used

    def as_dict(self) -> dict[str, int]:
        """Plain dict including ``dropped``."""
        d = {k: int(getattr(self, k)) for k in self.__dataclass_fields__}
        d['dropped'] = self.dropped
        return d


@dataclass
class JointCounts(StreamCounts):
    """What cleaning did to the JointState stream: the counts of every stream, and the
    messages dropped because their arrays cannot be matched to the wanted joints."""

    mismatched: int = 0
    incomplete: int = 0
    ambiguous: int = 0


@dataclass
class Stream:
    """One cleaned stream.

    Attributes
    ----------
    topic, msg_type, frame_id : str
        Where it came from.
    t : numpy.ndarray
        (n,) float64 header stamps [s] relative to the log epoch, strictly increasing.
    values : numpy.ndarray
        (n, 3) float64 angular velocity [rad/s] or torque [N m]; (n, k) joint speeds
        [rad/s] of the JointState stream, columns in the order of ``names``.
    counts : StreamCounts
        What cleaning did.
    rate_hz : float
        Median sample rate [Hz] (NaN with fewer than two samples).
    names : tuple of str
        The joints of the columns of ``values`` (JointState stream only; else empty).
    """

    topic: str
    msg_type: str
    frame_id: str
    t: np.ndarray
    values: np.ndarray
    counts: StreamCounts
    rate_hz: float = float('nan')
    names: tuple[str, ...] = ()


@dataclass
class LogData:
    """A log ready for estimation.

    Attributes
    ----------
    paths : list of Path
        The MCAP files read.
    epoch_ns : int
        Header stamp [ns] that ``t = 0`` stands for.
    omega, torque : Stream
        The cleaned angular-velocity and torque streams.
    windows : list of (float, float)
        Time windows [s] in which every stream is gap-free; samples outside were dropped.
        Windows are separated by gaps, so no estimation window should span two of them.
    clock_jumps : int
        Backward clock jumps found (each starts a new piece of the log).
    truth : list of (float, numpy.ndarray)
        ``(t [s], inertia (3, 3) [kg m^2])`` from ``/truth/inertia``, if the log has it.
    topics : dict of str to str
        Every topic in the log and its type.
    metadata : dict of str to dict
        MCAP metadata records by name (e.g. ``inertia_ros.scene``).
    damage : Damage
        What could not be read from damaged files (summed over files).
    warnings : list of str
        One line per thing the user should know.
    clock_faults : int
        Backward clock steps of one stream alone (realigned and segmented), plus streams
        dropped from an unresolvable stamp conflict on (see :func:`_repair_clocks`).
    pauses_shortened : int
        Pauses longer than ``max_gap`` shortened (everything after moved earlier).
    time_removed_s : float
        Total time those pauses lost [s]: the stamps after a pause are ``t + removed``.
    joints : Stream or None
        The cleaned JointState stream (wheel or rotor speeds of the joints asked for), on
        the same time axis and windows as the other two; None when not asked for.
    """

    paths: list[Path]
    epoch_ns: int
    omega: Stream
    torque: Stream
    windows: list[tuple[float, float]]
    clock_jumps: int = 0
    truth: list[tuple[float, np.ndarray]] = field(default_factory=list)
    topics: dict[str, str] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    damage: Damage = field(default_factory=Damage)
    warnings: list[str] = field(default_factory=list)
    clock_faults: int = 0
    pauses_shortened: int = 0
    time_removed_s: float = 0.0
    joints: Stream | None = None

    @property
    def scene(self) -> dict | None:
        """The scene dict recorded by our simulator, if present."""
        md = self.metadata.get('inertia_ros.scene', {})
        try:
            return json.loads(md['scene_json']) if 'scene_json' in md else None
        except ValueError:
            return None

    def summary(self) -> dict:
        """Counts and facts for reports (JSON-ready)."""
        out: dict = {
            'files': [str(p) for p in self.paths],
            'epoch_ns': int(self.epoch_ns),
            'omega': {'topic': self.omega.topic, 'type': self.omega.msg_type,
                      'frame_id': self.omega.frame_id, 'rate_hz': _r(self.omega.rate_hz),
                      **self.omega.counts.as_dict()},
            'torque': {'topic': self.torque.topic, 'type': self.torque.msg_type,
                       'frame_id': self.torque.frame_id, 'rate_hz': _r(self.torque.rate_hz),
                       **self.torque.counts.as_dict()},
            'windows': len(self.windows),
            'clock_jumps': self.clock_jumps,
            'clock_faults': self.clock_faults,
            'pauses_shortened': self.pauses_shortened,
            'time_removed_s': round(float(self.time_removed_s), 9),
            'damage': {'truncated': self.damage.truncated,
                       'corrupt_chunks': self.damage.corrupt_chunks,
                       'bytes_lost': self.damage.bytes_lost,
                       'messages_lost': self.damage.messages_lost},
        }
        if self.joints is not None:
            js = self.joints
            out['joints'] = {'topic': js.topic, 'type': js.msg_type, 'names': list(js.names),
                             'rate_hz': _r(js.rate_hz), **js.counts.as_dict()}
        return out


def _r(x: float) -> float | None:
    return None if not np.isfinite(x) else round(float(x), 6)



@dataclass
class PreparedStream:
    """One stream between decoding and cleaning (internal to the log layer).

    Attributes
    ----------
    label : str
        What the stream is, for warnings (``angular velocity``, ``torque``, the JointState
        topic).
    topic : str
    stamp : numpy.ndarray
        int64 (n,) header stamps [ns], file order.
    values : numpy.ndarray
        float64 (n, k) values.
    keep : numpy.ndarray
        bool (n,), False for samples already dropped.
    counts : StreamCounts
    frame : str
        The stream's ``frame_id``.
    ordinal : numpy.ndarray
        int64 (n,) position of each message in the log (arrival order).
    seq : numpy.ndarray
        int64 (n,) the Message records' sequence numbers (0 when unset).
    """

    label: str
    topic: str
    stamp: np.ndarray
    values: np.ndarray
    keep: np.ndarray
    counts: StreamCounts
    frame: str
    ordinal: np.ndarray
    seq: np.ndarray


@dataclass
class RawTopic:
    """Decoded but uncleaned messages of one topic, accumulated over batches."""

    msg_type: str
    stamp: list[np.ndarray] = field(default_factory=list)
    frame: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    ok: list[np.ndarray] = field(default_factory=list)
    ordinal: list[np.ndarray] = field(default_factory=list)
    seq: list[np.ndarray] = field(default_factory=list)
    frames: dict[str, int] = field(default_factory=dict)
    status: list[np.ndarray] = field(default_factory=list)
    names_seen: set[str] = field(default_factory=set)

    def add(self, d: cdr_decode.DecodedBatch, field_name: str, ordinal: np.ndarray,
            sequence: np.ndarray | None = None) -> None:
        remap = np.array([self.frames.setdefault(f, len(self.frames)) for f in d.frame_ids]
                         + [-1], dtype=np.int32)
        self.stamp.append(d.stamp_ns)
        self.frame.append(remap[d.frame_index])  # -1 indexes the appended -1
        v = d.fields[field_name]
        self.values.append(v if v.shape[1] != 1 else v.reshape(-1, 1))
        self.ok.append(d.ok)
        self.ordinal.append(ordinal)
        self.seq.append(np.zeros(ordinal.size, np.int64) if sequence is None
                        else sequence.astype(np.int64))

    def add_rows(self, stamp: np.ndarray, values: np.ndarray, status: np.ndarray,
                 ordinal: np.ndarray, sequence: np.ndarray | None, names: set[str]) -> None:
        """Add decoded JointState messages (no frame; ``status`` 0 for usable rows, see
        :func:`inertia_ros.io.joint_state.joint_rows`)."""
        self.frames.setdefault('', 0)
        self.stamp.append(stamp)
        self.frame.append(np.zeros(stamp.size, np.int32))
        self.values.append(values)
        self.ok.append(status == 0)
        self.status.append(status)
        self.ordinal.append(ordinal)
        self.seq.append(np.zeros(ordinal.size, np.int64) if sequence is None
                        else sequence.astype(np.int64))
        self.names_seen |= names

    @property
    def count(self) -> int:
        """Messages accumulated."""
        return int(sum(a.size for a in self.stamp))

    def arrays(self) -> tuple[np.ndarray, ...]:
        """(stamp, frame, values, ok, ordinal, sequence) in file order."""
        if not self.stamp:
            z = np.zeros(0, np.int64)
            return z, z.astype(np.int32), np.zeros((0, 3)), z.astype(bool), z, z
        parts = (self.stamp, self.frame, self.values, self.ok, self.ordinal, self.seq)
        order = self._order()
        if order is None:                                # the usual case: already in order
            return tuple(np.concatenate(a) for a in parts)
        return tuple(np.concatenate(a)[order] for a in parts)

    def status_array(self) -> np.ndarray:
        """int8 (n,) JointState row status in file order (zeros for other topics)."""
        if not self.status:
            return np.zeros(self.count, np.int8)
        order = self._order()
        st = np.concatenate(self.status)
        return st if order is None else st[order]

    def _order(self) -> np.ndarray | None:
        """The permutation into file order, None when the batches are already in it."""
        ordinal = np.concatenate(self.ordinal)
        if bool(np.all(ordinal[1:] > ordinal[:-1])):
            return None
        return np.argsort(ordinal, kind='stable')



def missing_joints_error(topic: str, missing: Sequence[str], seen: Iterable[str],
                         what: str) -> LogError:
    """The one-line error for wanted joints that no JointState message names.

    At most five names of each list are shown, with the counts, so that a file of many joints
    still gives a short line.
    """
    def few(names: Sequence[str]) -> str:
        shown = ', '.join(repr(n[:64]) for n in names[:5])
        return f'[{shown}, ...] ({len(names)} in all)' if len(names) > 5 else f'[{shown}]'
    return LogError(f'{topic}: joint(s) {few(list(missing))} never appear in JointState.name '
                    f'(names seen: {few(sorted(seen))}); fix the {what} file\'s joint names')
