"""Recorded logs -> clean numpy arrays for the estimator.

:func:`read_log` reads a single ``.mcap`` file or a rosbag2 directory (``metadata.yaml`` plus
its storage files), finds the angular-velocity and torque topics by message type, decodes
them with the vectorised CDR path, and cleans what real recordings contain.  Plain MCAP is
read by our own bounded reader (:mod:`inertia_ros.io.mcap_reader`); sqlite3 (``.db3``) and
compressed bags go through ``rosbags`` (:mod:`inertia_ros.io.rosbags_source`) into the same
batches; ``metadata.yaml`` is validated once (:mod:`inertia_ros.io.rosbag2`).

======================  ===================================================================
problem                 handling (each counted in :attr:`StreamCounts`)
======================  ===================================================================
malformed payload       dropped (``malformed``)
NaN / Inf sample        dropped (``nonfinite``)
wrong ``frame_id``      a few stray messages are dropped (``wrong_frame``); two frames in
                        earnest, or different frames on the two streams, raise
                        :class:`LogError` unless ``ignore_frames``
clock restart           both streams' stamps step back together (a looped or restarted
                        recording): the later part is placed one second after the earlier
                        and estimated as a separate segment (``clock_jumps``)
clock fault             one stream's stamps step back while the other runs on, seen in
                        file order or, for files stored in stamp order, in the messages'
                        sequence numbers: the stream is realigned by continuity and the log
                        segmented there (``clock_faults``); without either order, samples
                        whose stamps collide or interleave are dropped from the first on
                        (``stamp_conflicts``)
out-of-order arrival    sorted by header stamp (``out_of_order`` counts late arrivals)
duplicate               same header stamp and same values twice: the first kept
                        (``duplicates``); same stamp, other values: both dropped
                        (``stamp_conflicts``)
gap                     a stamp step over ``gap_factor`` times the median step splits the
                        stream; the estimator's windows are the intersections of the two
                        streams' gap-free runs (``gaps``)
long pause              a pause between windows over ``max_gap`` is shortened to an
                        ordinary gap (1 s), moving the rest of the log earlier, so the
                        estimator's accumulated integrals never cross it
                        (``pauses_shortened``, ``time_removed_s``)
stream stops early      samples outside the common windows are dropped (``outside``)
======================  ===================================================================

Times are the messages' header stamps (never MCAP log times), returned as float seconds
relative to :attr:`LogData.epoch_ns`, the integer-nanosecond stamp of the first sample kept;
after a clock restart, a clock fault or a long pause, later times are shifted as described
(the warnings say by how much).
"""
from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from inertia_ros.core._numeric import median
from inertia_ros.io import cdr_decode
from inertia_ros.io.mcap_reader import (
    Channel,
    ChannelFilter,
    CodecMissingError,
    Damage,
    McapError,
    McapReader,
    MessageBatch,
    Schema,
)
from inertia_ros.io.rosbag2 import BagInfo, BagMetadataError, read_bag_info
from inertia_ros.io.rosbags_source import RosbagsError, RosbagsSource

#: Angular-velocity message types and the field holding omega [rad/s].
OMEGA_TYPES: dict[str, str] = {
    'sensor_msgs/msg/Imu': 'angular_velocity',
    'geometry_msgs/msg/TwistStamped': 'angular',
    'geometry_msgs/msg/Vector3Stamped': 'vector',
}
#: Torque message types and the field holding the torque [N m].
TORQUE_TYPES: dict[str, str] = {
    'geometry_msgs/msg/WrenchStamped': 'torque',
    'geometry_msgs/msg/Vector3Stamped': 'vector',
}
TRUTH_TYPE = 'geometry_msgs/msg/InertiaStamped'
#: Topic holding the true tensor in simulated logs.
TRUTH_TOPIC = '/truth/inertia'

_OMEGA_WORDS = ('omega', 'angular', 'gyro', 'rate', 'imu', 'twist')
_TORQUE_WORDS = ('torque', 'wrench', 'moment', 'tau')


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
class Stream:
    """One cleaned stream.

    Attributes
    ----------
    topic, msg_type, frame_id : str
        Where it came from.
    t : numpy.ndarray
        (n,) float64 header stamps [s] relative to the log epoch, strictly increasing.
    values : numpy.ndarray
        (n, 3) float64 angular velocity [rad/s] or torque [N m].
    counts : StreamCounts
        What cleaning did.
    rate_hz : float
        Median sample rate [Hz] (NaN with fewer than two samples).
    """

    topic: str
    msg_type: str
    frame_id: str
    t: np.ndarray
    values: np.ndarray
    counts: StreamCounts
    rate_hz: float = float('nan')


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
        Time windows [s] in which both streams are gap-free; samples outside were dropped.
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
        return {
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


def _r(x: float) -> float | None:
    return None if not np.isfinite(x) else round(float(x), 6)


# --------------------------------------------------------------------------------------------
# Reading


@dataclass
class _Raw:
    """Decoded but uncleaned messages of one topic, accumulated over batches."""

    msg_type: str
    stamp: list[np.ndarray] = field(default_factory=list)
    frame: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    ok: list[np.ndarray] = field(default_factory=list)
    ordinal: list[np.ndarray] = field(default_factory=list)
    seq: list[np.ndarray] = field(default_factory=list)
    frames: dict[str, int] = field(default_factory=dict)

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

    @property
    def count(self) -> int:
        """Messages accumulated."""
        return int(sum(a.size for a in self.stamp))

    def arrays(self) -> tuple[np.ndarray, ...]:
        """(stamp, frame, values, ok, ordinal, sequence) in file order."""
        if not self.stamp:
            z = np.zeros(0, np.int64)
            return z, z.astype(np.int32), np.zeros((0, 3)), z.astype(bool), z, z
        ordinal = np.concatenate(self.ordinal)
        parts = (self.stamp, self.frame, self.values, self.ok, self.ordinal, self.seq)
        if bool(np.all(ordinal[1:] > ordinal[:-1])):     # the usual case: already in order
            return tuple(np.concatenate(a) for a in parts)
        order = np.argsort(ordinal, kind='stable')
        return tuple(np.concatenate(a)[order] for a in parts)


def _bag(path: str | Path) -> BagInfo | None:
    """The validated metadata of a bag directory (None for a file or a bare directory)."""
    p = Path(path)
    if not p.is_dir():
        return None
    try:
        return read_bag_info(p)
    except BagMetadataError as exc:
        raise LogError(str(exc)) from None


def log_files(path: str | Path) -> list[Path]:
    """The storage files of a log: the file itself, or a rosbag2 directory's files in order.

    Parameters
    ----------
    path : str or Path
        A ``.mcap`` file or a rosbag2 directory (any storage: mcap, sqlite3, compressed).

    Returns
    -------
    list of Path

    Raises
    ------
    LogError
        Missing path, unusable ``metadata.yaml``, or a directory with no storage files.
    """
    p = Path(path)
    if not p.exists():
        raise LogError(f'{p}: no such file or directory')
    if p.is_file():
        if p.suffix == '.db3' or p.name.endswith(('.mcap.zstd', '.db3.zstd')):
            raise LogError(f'{p}: a {p.suffix} file is read as part of its rosbag2 bag; pass '
                           f'the bag directory {p.parent} (with its metadata.yaml)')
        return [p]
    info = _bag(p)
    if info is not None and info.files:
        present = [f for f in info.files if f.is_file()]
        if present:
            return present
    if info is not None and not info.own_mcap_path:
        raise LogError(f'{p}: none of the files metadata.yaml lists '
                       f'({", ".join(f.name for f in info.files) or "none"}) is in the '
                       'directory')
    files = sorted(p.glob('*.mcap'))
    if not files:
        raise LogError(f'{p}: directory holds no .mcap files (expected a rosbag2 bag)')
    return files


def read_log(path: str | Path, omega_topic: str | None = None,
             torque_topic: str | None = None, *, ignore_frames: bool = False,
             torque_delay: float = 0.0, gap_factor: float = 5.0,
             max_backward_jump: float = 0.5, min_window: int = 10, max_gap: float = 10.0,
             progress: Callable[[int, int], None] | None = None) -> LogData:
    """Read a log into cleaned angular-velocity and torque streams.

    Parameters
    ----------
    path : str or Path
        A ``.mcap`` file or a rosbag2 directory.  Never modified.
    omega_topic, torque_topic : str, optional
        Topics to use; found by message type when not given.  ``torque_topic='none'`` reads
        torque-free data (no torque stream; the torque arrays are empty).
    ignore_frames : bool
        Accept different ``frame_id`` values (between and within streams).
    torque_delay : float
        The torque stream's stamps lag the torque actually applied by this much [s]; it is
        subtracted from the torque stamps before alignment.
    gap_factor : float
        A stamp step larger than this many median steps is a gap (> 1).
    max_backward_jump : float
        A backward step of the merged stamps larger than this [s] is a clock jump (a new
        piece of the log); smaller ones are out-of-order arrival (> 0).
    min_window : int
        Windows with fewer gyro samples are dropped (>= 2).
    max_gap : float
        Pauses between windows longer than this [s] are shortened to an ordinary gap (1 s
        or 10 sample intervals), moving everything after them earlier, so that the
        estimator's accumulated integrals never cross hours of nothing (> 0).
    progress : callable, optional
        ``progress(bytes_done, bytes_total)`` while reading.

    Returns
    -------
    LogData

    Raises
    ------
    LogError
        Unreadable input, no or ambiguous topics, wrong message types, mismatched frames,
        empty streams.
    ValueError
        Invalid numeric arguments.
    """
    if not np.isfinite(torque_delay):
        raise ValueError(f'torque_delay: must be finite, got {torque_delay}')
    if not gap_factor > 1:
        raise ValueError(f'gap_factor: must be > 1, got {gap_factor}')
    if not max_backward_jump > 0:
        raise ValueError(f'max_backward_jump: must be > 0, got {max_backward_jump}')
    if min_window < 2:
        raise ValueError(f'min_window: must be >= 2, got {min_window}')
    if not (np.isfinite(max_gap) and max_gap > 0):
        raise ValueError(f'max_gap: must be > 0 s, got {max_gap}')
    files = log_files(path)
    info = _bag(path)
    raws, topics, metadata, damage, warnings = _read_files(files, omega_topic, torque_topic,
                                                           progress, info)
    if damage.any:
        for note in damage.notes:
            warnings.append(f'damaged log: {note}')
    no_torque = torque_topic is not None and torque_topic.lower() == 'none'
    om_topic, tq_topic = _choose_topics(path, topics, omega_topic,
                                        None if no_torque else torque_topic,
                                        need_torque=not no_torque)
    om_type = topics[om_topic]
    tq_type = topics.get(tq_topic, '')

    expected = info.message_counts if info is not None else {}
    for t in (om_topic, tq_topic):
        got = raws[t].count if t in raws else 0
        if t in expected and got < expected[t]:
            warnings.append(f'{t}: metadata.yaml lists {expected[t]} messages, {got} were read '
                            f'({expected[t] - got} lost)')
    om = _prepare(om_topic, om_type, raws.get(om_topic), ignore_frames, warnings)
    if no_torque:
        z = np.zeros(0, np.int64)
        tq = (z, np.zeros((0, 3)), z.astype(bool), StreamCounts(), om[4], z, z)
        warnings.append('no torque stream (--torque-topic none): torque-free data, only the '
                        'ratios and principal axes are observable')
    else:
        tq = _prepare(tq_topic, tq_type, raws.get(tq_topic), ignore_frames, warnings)
    if not ignore_frames and om[4] != tq[4]:
        raise LogError(f'frames differ: {om_topic} is in {om[4]!r} but {tq_topic} is in '
                       f'{tq[4]!r}; the torque must be expressed in the gyro frame (or pass '
                       '--ignore-frames if they are the same frame under two names)')
    if torque_delay:
        tq = (tq[0] - int(round(torque_delay * 1e9)), *tq[1:])
    om, tq, restarts = _repair_clocks(om, tq, int(max_backward_jump * 1e9), gap_factor,
                                      max_gap, (om_topic, tq_topic), warnings)
    data = _clean(om, tq, gap_factor=gap_factor, max_backward_jump=max_backward_jump,
                  min_window=min_window, warnings=warnings, max_gap=max_gap)
    epoch, (t_om, v_om, c_om), (t_tq, v_tq, c_tq), windows, jumps, (pauses, removed) = data
    jumps += restarts
    omega = Stream(om_topic, om_type, om[4], t_om, v_om, c_om, _rate(t_om))
    torque = Stream(tq_topic, tq_type, tq[4], t_tq, v_tq, c_tq, _rate(t_tq))
    truth = _truth(raws.get(TRUTH_TOPIC), epoch)
    return LogData(files, epoch, omega, torque, windows, jumps, truth, topics, metadata,
                   damage, warnings, c_om.clock_faults + c_tq.clock_faults, pauses,
                   removed / 1e9)


def _open(f: Path, info: BagInfo | None, prog: Callable[[int, int], None]
          ) -> McapReader | RosbagsSource:
    """A batch source for one MCAP file, or for the whole bag when rosbags must read it."""
    if info is not None and not info.own_mcap_path:
        try:
            return RosbagsSource(info, progress=prog)
        except RosbagsError as exc:
            raise LogError(str(exc)) from None
    try:
        return McapReader(f, progress=prog)
    except McapError as exc:
        raise LogError(str(exc)) from None


def _read_files(files: list[Path], omega_topic: str | None, torque_topic: str | None,
                progress: Callable[[int, int], None] | None, info: BagInfo | None = None
                ) -> tuple[dict[str, _Raw], dict[str, str], dict[str, dict[str, str]],
                           Damage, list[str]]:
    """One pass over every file: decode every topic of a type we can use.

    Plain MCAP goes through our own reader, file by file; any other rosbag2 storage (sqlite3,
    compressed) through :class:`~inertia_ros.io.rosbags_source.RosbagsSource`, once for the
    whole bag.
    """
    if info is not None and not info.own_mcap_path:
        files = [info.directory]
    wanted_types = set(OMEGA_TYPES) | set(TORQUE_TYPES) | {TRUTH_TYPE}
    # with both topics named only those (and the truth) are decoded; else every candidate
    named = {omega_topic, torque_topic} if omega_topic and torque_topic else set()
    raws: dict[str, _Raw] = {}
    topics: dict[str, str] = {}
    metadata: dict[str, dict[str, str]] = {}
    damage = Damage()
    warnings: list[str] = []
    sizes = [f.stat().st_size if f.is_file() else 0 for f in files]
    total = sum(sizes)
    done = 0
    ordinal_base = 0
    for f, size in zip(files, sizes, strict=True):
        def prog(b: int, _n: int, _done: int = done) -> None:
            if progress is not None:
                progress(_done + b, total)

        reader = _open(f, info, prog)
        with reader:
            def select(ch: Channel, schema: Schema | None) -> bool:
                typ = cdr_decode.normalise_type(schema.name) if schema else ''
                if ch.message_encoding != 'cdr' or typ not in wanted_types:
                    return False
                if named and ch.topic not in named and ch.topic != TRUTH_TOPIC:
                    return False
                return True

            for b in _batches(reader, select):
                typ = cdr_decode.normalise_type(b.schema.name)
                raw = raws.setdefault(b.channel.topic, _Raw(typ))
                if typ != raw.msg_type:
                    warnings.append(f'{b.channel.topic}: type changed from {raw.msg_type} to '
                                    f'{typ} in {f.name}; those messages are ignored')
                    continue
                fname = _field_for(typ, b.channel.topic)
                fields = None if typ == TRUTH_TYPE else (fname,)
                d = cdr_decode.decode_batch(typ, b.buf, b.starts, b.lengths, fields)
                if typ == TRUTH_TYPE:
                    vals = np.concatenate([d.fields[k] for k, _ in
                                           cdr_decode.LAYOUTS[TRUTH_TYPE][2:]], axis=1)
                    d = cdr_decode.DecodedBatch(d.msg_type, d.stamp_ns, d.frame_index,
                                                d.frame_ids, {'inertia': vals}, d.ok)
                    fname = 'inertia'
                raw.add(d, fname, ordinal_base + b.ordinal, b.sequence)
            for ch in reader.channels.values():
                sc = reader.schemas.get(ch.schema_id)
                topics.setdefault(ch.topic, cdr_decode.normalise_type(sc.name) if sc else '')
            for md in reader.metadata:
                metadata[md.name] = md.metadata
            ordinal_base += reader.messages_read
            d0 = reader.damage
            damage.truncated |= d0.truncated
            damage.corrupt_chunks += d0.corrupt_chunks
            damage.bytes_lost += d0.bytes_lost
            damage.messages_lost += d0.messages_lost
            damage.notes.extend(f'{f.name}: {n}' for n in d0.notes)
        done += size
    return raws, topics, metadata, damage, warnings


def _batches(reader: McapReader | RosbagsSource, select: ChannelFilter
             ) -> Iterator[MessageBatch]:
    """``reader.iter_batches(select)`` with reader failures as one-line :class:`LogError`."""
    try:
        yield from reader.iter_batches(select)
    except CodecMissingError as exc:
        raise LogError(str(exc)) from None
    except RosbagsError as exc:
        raise LogError(str(exc)) from None


def _field_for(msg_type: str, topic: str) -> str:
    if msg_type in OMEGA_TYPES and msg_type not in TORQUE_TYPES:
        return OMEGA_TYPES[msg_type]
    if msg_type in TORQUE_TYPES:
        return TORQUE_TYPES[msg_type]
    return 'inertia'


def _list_topics(topics: dict[str, str]) -> str:
    if not topics:
        return 'the log has no topics'
    return 'topics in the log: ' + ', '.join(f'{t} ({ty or "no schema"})'
                                              for t, ty in sorted(topics.items()))


def _choose_topics(path: str | Path, topics: dict[str, str], omega_topic: str | None,
                   torque_topic: str | None, *, need_torque: bool = True) -> tuple[str, str]:
    """Pick the angular-velocity and torque topics (given, or by type and name).

    With ``need_torque`` False the torque topic returned is ``''``.
    """
    for name, given, types, flag in (('angular velocity', omega_topic, OMEGA_TYPES,
                                      '--omega-topic'),
                                     ('torque', torque_topic, TORQUE_TYPES, '--torque-topic')):
        if given is None:
            continue
        if given not in topics:
            raise LogError(f'{path}: topic {given} ({flag}) is not in the log; '
                           f'{_list_topics(topics)}')
        if topics[given] not in types:
            raise LogError(f'{path}: topic {given} has type {topics[given] or "unknown"}, not '
                           f'a {name} type ({", ".join(types)})')
    usable = {t: ty for t, ty in topics.items() if not t.startswith('/truth/')}

    def pick(kind: str, types: dict[str, str], strong: tuple[str, ...],
             words: tuple[str, ...], other: str | None, flag: str) -> str:
        cands = [t for t, ty in usable.items() if ty in strong and t != other]
        if not cands:
            cands = [t for t, ty in usable.items() if ty in types and t != other
                     and any(w in t.lower() for w in words)]
        if not cands:
            cands = [t for t, ty in usable.items() if ty in types and t != other]
        if len(cands) == 1:
            return cands[0]
        if not cands:
            hint = ' (for torque-free data pass --torque-topic none)' if kind == 'torque' else ''
            raise LogError(f'{path}: no {kind} topic (types {", ".join(types)}); '
                           f'{_list_topics(topics)}{hint}')
        raise LogError(f'{path}: several {kind} topics ({", ".join(sorted(cands))}); choose '
                       f'one with {flag}')

    om = omega_topic or pick('angular velocity', OMEGA_TYPES,
                             ('sensor_msgs/msg/Imu', 'geometry_msgs/msg/TwistStamped'),
                             _OMEGA_WORDS, torque_topic, '--omega-topic')
    if not need_torque:
        return om, ''
    tq = torque_topic or pick('torque', TORQUE_TYPES, ('geometry_msgs/msg/WrenchStamped',),
                              _TORQUE_WORDS, om, '--torque-topic')
    if om == tq:
        raise LogError(f'{path}: the same topic {om} cannot be both angular velocity and '
                       'torque; give --omega-topic and --torque-topic')
    return om, tq


# --------------------------------------------------------------------------------------------
# Cleaning


def _prepare(topic: str, msg_type: str, raw: _Raw | None, ignore_frames: bool,
             warnings: list[str]) -> tuple:
    """(stamp, values, keep, counts, frame, ordinal-free arrays) with bad messages marked."""
    if raw is None:
        raise LogError(f'{topic}: no messages of type {msg_type} in the log (empty stream)')
    stamp, frame, values, ok, ordinal, seq = raw.arrays()
    raw.stamp, raw.frame, raw.values, raw.ok, raw.ordinal, raw.seq = [], [], [], [], [], []
    counts = StreamCounts(received=int(stamp.size))
    if stamp.size == 0:
        raise LogError(f'{topic}: the stream is empty')
    keep = ok.copy()
    counts.malformed = int((~ok).sum())
    if counts.malformed:
        warnings.append(f'{topic}: {counts.malformed} malformed messages dropped')
    finite = _finite_rows(values)
    counts.nonfinite = int((keep & ~finite).sum())
    keep &= finite
    names = {v: k for k, v in raw.frames.items()}
    frame_name = ''
    if keep.any():
        codes, n = np.unique(frame[keep], return_counts=True)
        main = int(codes[np.argmax(n)])
        frame_name = names.get(main, '')
        if codes.size > 1:
            stray = keep & (frame != main)
            n_stray = int(stray.sum())
            others = ', '.join(repr(names.get(int(c), '?')) for c in codes if c != main)
            if not ignore_frames and n_stray > max(3, 0.01 * keep.sum()):
                raise LogError(f'{topic}: messages in several frames ({frame_name!r} and '
                               f'{others}); record one frame per topic or pass '
                               '--ignore-frames')
            if not ignore_frames:
                keep &= ~stray
                counts.wrong_frame = n_stray
                warnings.append(f'{topic}: {n_stray} messages in frame(s) {others} instead of '
                                f'{frame_name!r} dropped')
    if counts.nonfinite:
        warnings.append(f'{topic}: {counts.nonfinite} samples with NaN or Inf dropped')
    if not keep.any():
        raise LogError(f'{topic}: no usable messages ({counts.received} received, all '
                       'malformed or non-finite)')
    return stamp, values, keep, counts, frame_name, ordinal, seq


def _finite_rows(values: np.ndarray) -> np.ndarray:
    """Rows of ``values`` (n, k) whose every element is finite, as bool (n,).

    Column by column: the same as ``np.isfinite(values).all(axis=1)``, without its slow
    reduction over a short axis.
    """
    if values.ndim != 2 or values.shape[1] == 0:
        return np.isfinite(values).all(axis=1)
    out = np.isfinite(values[:, 0])
    for j in range(1, values.shape[1]):
        out &= np.isfinite(values[:, j])
    return out


def _rows(values: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``values[idx]``, as a slice (no copy) when ``idx`` is a run of consecutive indexes."""
    if idx.size > 1 and int(idx[-1]) - int(idx[0]) == idx.size - 1 \
            and bool(np.all(idx[1:] - idx[:-1] == 1)):
        return values[int(idx[0]):int(idx[-1]) + 1]
    return values[idx]


def _median(d: np.ndarray) -> float:
    """``float(np.median(d))`` of a non-empty 1-D array, by counting for integer steps.

    Sample intervals [ns] of a log span a narrow range of integers, so the middle values
    are found from a histogram in two passes instead of a partition; the result is the
    same number (the mean of the two middle values for an even count, as np.median).
    """
    if d.dtype.kind in 'iu' and d.size > 64:
        lo, hi = int(d.min()), int(d.max())
        if hi - lo < 1 << 16:
            cum = np.cumsum(np.bincount((d - lo).astype(np.intp)))
            n = d.size
            v1 = lo + int(np.searchsorted(cum, (n - 1) // 2, side='right'))
            if n % 2:
                return float(v1)
            v2 = lo + int(np.searchsorted(cum, n // 2, side='right'))
            return float((np.float64(v1) + np.float64(v2)) / 2.0)
    return median(d)


def _median_step(s: np.ndarray) -> float:
    d = np.diff(s)
    d = d[d > 0]
    return _median(d) if d.size else float('nan')


def _rate(t: np.ndarray) -> float:
    step = _median_step(t)
    return 1.0 / step if np.isfinite(step) and step > 0 else float('nan')


def _runs(stamps: np.ndarray, limit: float) -> list[tuple[int, int]]:
    """Index ranges [a, b) of ``stamps`` (sorted) without a step above ``limit``."""
    if stamps.size == 0:
        return []
    cut = np.flatnonzero(np.diff(stamps) > limit) + 1
    edges = np.concatenate(([0], cut, [stamps.size]))
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def _clean(om: tuple, tq: tuple, *, gap_factor: float, max_backward_jump: float,
           min_window: int, warnings: list[str], max_gap: float = 10.0):
    """Pieces, sorting, de-duplication, gaps and windows; returns times relative to epoch."""
    s_om, v_om, k_om, c_om, _, o_om, _ = om
    s_tq, v_tq, k_tq, c_tq, _, o_tq, _ = tq
    idx_om = np.flatnonzero(k_om)
    idx_tq = np.flatnonzero(k_tq)
    free = s_tq.size == 0  # no torque stream: torque-free data
    # Pieces: backward clock jumps of the merged stamp sequence in arrival (file) order.
    which = np.concatenate((np.zeros(idx_om.size, np.int8), np.ones(idx_tq.size, np.int8)))
    pos = np.concatenate((idx_om, idx_tq))
    order = np.argsort(np.concatenate((o_om[idx_om], o_tq[idx_tq])), kind='stable')
    which, pos = which[order], pos[order]
    merged = np.empty(pos.size, np.int64)
    m0 = which == 0
    merged[m0] = s_om[pos[m0]]
    merged[~m0] = s_tq[pos[~m0]]
    piece, spikes = _pieces(merged, int(max_backward_jump * 1e9))
    for w, c, k in ((0, c_om, k_om), (1, c_tq, k_tq)):
        bad = pos[spikes & (which == w)]
        c.bad_stamps += int(bad.size)
        k[bad] = False
    keep = ~spikes
    which, pos, piece = which[keep], pos[keep], piece[keep]
    idx_om, piece_om = pos[which == 0], piece[which == 0]
    idx_tq, piece_tq = pos[which == 1], piece[which == 1]
    n_pieces = int(piece.max(initial=0)) + 1
    del which, pos, order, merged, piece, spikes, keep, m0
    jumps = n_pieces - 1
    if jumps:
        warnings.append(f'{jumps} backward clock jump(s) (restarted or looped recording): the '
                        'log is split into pieces estimated as separate segments')
    for name, c in (('angular velocity', c_om), ('torque', c_tq)):
        if c.bad_stamps:
            warnings.append(f'{name}: {c.bad_stamps} messages with a stamp far off its '
                            'neighbours dropped')
    out_t_om, out_v_om, out_t_tq, out_v_tq = [], [], [], []
    windows_ns: list[tuple[int, int]] = []
    steps: list[float] = []
    shift = 0
    last_end: int | None = None
    epoch: int | None = None
    for p in range(n_pieces):
        a = idx_om[piece_om == p]
        b = idx_tq[piece_tq == p]
        if a.size == 0 or (b.size == 0 and not free):
            c_om.outside += int(a.size)
            c_tq.outside += int(b.size)
            continue
        a, oo_a, dup_a = _sort_dedup(s_om, a, v_om, c_om, 'angular velocity', warnings)
        b, oo_b, dup_b = _sort_dedup(s_tq, b, v_tq, c_tq, 'torque', warnings)
        c_om.out_of_order += oo_a
        c_om.duplicates += dup_a
        c_tq.out_of_order += oo_b
        c_tq.duplicates += dup_b
        if a.size == 0 or (b.size == 0 and not free):
            continue  # everything of a stream in this piece was a conflict (counted)
        sa, sb = s_om[a], s_tq[b]
        step_a, step_b = _median_step(sa), _median_step(sb)
        steps.extend((step_a, step_b))
        runs_a = _runs(sa, gap_factor * step_a) if np.isfinite(step_a) else [(0, sa.size)]
        runs_b = (_runs(sb, gap_factor * step_b) if np.isfinite(step_b) else [(0, sb.size)]
                  ) if not free else [(0, 0)]
        c_om.gaps += len(runs_a) - 1
        c_tq.gaps += len(runs_b) - 1
        # windows: intersections of the gap-free runs of the two streams (a merge sweep)
        ia = [(int(sa[r0]), int(sa[r1 - 1])) for r0, r1 in runs_a]
        if free:
            wins = ia
        else:
            ib = [(int(sb[r0]), int(sb[r1 - 1])) for r0, r1 in runs_b]
            wins = []
            i = j = 0
            while i < len(ia) and j < len(ib):
                lo, hi = max(ia[i][0], ib[j][0]), min(ia[i][1], ib[j][1])
                if hi > lo:
                    wins.append((lo, hi))
                if ia[i][1] < ib[j][1]:
                    i += 1
                else:
                    j += 1
        wins.sort()
        ka = np.zeros(sa.size, bool)
        kb = np.zeros(sb.size, bool)
        good = []
        for lo, hi in wins:
            ma = (sa >= lo) & (sa <= hi)
            if ma.sum() < min_window:
                continue
            mb = (sb >= lo) & (sb <= hi)
            ka |= ma
            kb |= mb
            good.append((lo, hi))
            del ma, mb
        c_om.outside += int((~ka).sum())
        c_tq.outside += int((~kb).sum())
        if not good:
            continue
        if epoch is None:
            epoch = good[0][0]
        if last_end is not None and good[0][0] + shift <= last_end:
            # a later piece overlapping in time: place it after the previous one, one second on
            shift = last_end + 1_000_000_000 - good[0][0]
        out_t_om.append(sa[ka] + shift)
        out_v_om.append(_rows(v_om, a[ka]))
        out_t_tq.append(sb[kb] + shift)
        out_v_tq.append(_rows(v_tq, b[kb]))
        windows_ns.extend((lo + shift, hi + shift) for lo, hi in good)
        last_end = good[-1][1] + shift
        del a, b, sa, sb, ka, kb
    if epoch is None:
        if free:
            raise LogError('the angular-velocity stream has no window of at least '
                           f'{min_window} samples without a gap')
        if c_om.stamp_conflicts or c_tq.stamp_conflicts:
            raise LogError(f'no usable window: {c_om.stamp_conflicts + c_tq.stamp_conflicts} '
                           'samples lie where two runs of stamps collide or interleave (a clock '
                           'that stepped back, in a file stored in stamp order); record the '
                           'receive time as log time, or the sequence numbers, so that the runs '
                           'can be told apart')
        raise LogError('the angular-velocity and torque streams never overlap in time (header '
                       'stamps); check the clocks, or --torque-delay')
    del s_om, v_om, s_tq, v_tq, om, tq
    t_om_ns = _cat(out_t_om)
    t_tq_ns = _cat(out_t_tq) if out_t_tq else np.zeros(0, np.int64)
    windows_ns, pauses, removed = _shorten_pauses(windows_ns, (t_om_ns, t_tq_ns),
                                                  int(max_gap * 1e9), steps)
    if pauses:
        warnings.append(f'{pauses} pause(s) longer than {max_gap:g} s in the log: each is '
                        f'shortened to {_pause_ns(steps) / 1e9:g} s ({removed / 1e9:.6g} s '
                        'removed from the times after it) and ends a segment, so no equation '
                        'spans it')
    t_om = (t_om_ns - epoch) / 1e9
    t_tq = (t_tq_ns - epoch) / 1e9
    c_om.used = int(t_om.size)
    c_tq.used = int(t_tq.size)
    windows = [((lo - epoch) / 1e9, (hi - epoch) / 1e9) for lo, hi in windows_ns]
    for name, c in (('angular velocity', c_om), ('torque', c_tq)):
        if c.duplicates:
            warnings.append(f'{name}: {c.duplicates} duplicated messages dropped')
        if c.out_of_order:
            warnings.append(f'{name}: {c.out_of_order} messages arrived out of order (sorted)')
        if c.gaps:
            warnings.append(f'{name}: {c.gaps} gap(s) in the stream; estimation windows split')
    frac = c_om.outside / max(c_om.received, 1)
    if frac > 0.05:
        warnings.append(f'{100 * frac:.0f}% of the angular-velocity samples lie outside the '
                        'torque coverage (a stream stops early or starts late) and were dropped')
    v_tq = _cat(out_v_tq) if out_v_tq else np.zeros((0, 3))
    return (epoch, (t_om, _cat(out_v_om), c_om), (t_tq, v_tq, c_tq), windows, jumps,
            (pauses, removed))


def _pause_ns(steps: list[float]) -> int:
    """Length a long pause is shortened to [ns]: 1 s, or 10 sample intervals if longer.

    Longer than both the log's gap rule and the estimator's (5 median intervals), so the
    shortened pause still ends every window and segment.
    """
    finite = [x for x in steps if np.isfinite(x)]
    return int(max(1e9, 10.0 * max(finite, default=0.0)))


def _shorten_pauses(windows_ns: list[tuple[int, int]], streams: tuple[np.ndarray, ...],
                    max_gap_ns: int, steps: list[float]
                    ) -> tuple[list[tuple[int, int]], int, int]:
    """Shorten every pause between windows longer than ``max_gap_ns`` (in place).

    The estimator's integral equations accumulate from the start of the record, so a pause of
    hours inside a log is numerical cancellation (a one-day pause cost 22 %) even though no
    equation spans it.  Moving everything after such a pause earlier, by the same amount for
    both streams (their alignment is kept), leaves an ordinary gap that still ends every
    window and segment.

    Parameters
    ----------
    windows_ns : list of (int, int)
        Windows [ns], sorted; every kept sample lies in one.
    streams : tuple of numpy.ndarray
        int64 stamp arrays [ns], shifted in place.
    max_gap_ns : int
        Pauses longer than this are shortened [ns].
    steps : list of float
        Median sample intervals of the streams [ns].

    Returns
    -------
    (windows_ns, pauses, removed_ns)
    """
    if len(windows_ns) < 2:
        return windows_ns, 0, 0
    keep_ns = _pause_ns(steps)
    max_gap_ns = max(max_gap_ns, 2 * keep_ns)
    lo = np.array([w[0] for w in windows_ns], dtype=np.int64)
    hi = np.array([w[1] for w in windows_ns], dtype=np.int64)
    gap = lo[1:] - hi[:-1]
    cut = np.where(gap > max_gap_ns, gap - keep_ns, 0)
    if not cut.any():
        return windows_ns, 0, 0
    cum = np.concatenate(([0], np.cumsum(cut)))
    for st in streams:
        if st.size:
            k = np.clip(np.searchsorted(lo, st, side='right') - 1, 0, lo.size - 1)
            st -= cum[k]
    out = [(int(a - c), int(b - c)) for a, b, c in zip(lo, hi, cum, strict=True)]
    return out, int((cut > 0).sum()), int(cum[-1])


def _cat(parts: list[np.ndarray]) -> np.ndarray:
    """Concatenate, without a copy when there is one part (and emptying the list)."""
    out = parts[0] if len(parts) == 1 else np.concatenate(parts)
    parts.clear()
    return out


def _pieces(stamps: np.ndarray, jump_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """Split an arrival-ordered stamp sequence at backward clock jumps.

    A backward step larger than ``jump_ns`` starts a new piece, unless it only ends or is a
    one-sample spike (the stamps return to where they were): then that sample is flagged.

    Returns
    -------
    piece : (n,) int64 piece number of each stamp
    spike : (n,) bool, samples whose stamp is a lone outlier
    """
    n = stamps.size
    spike = np.zeros(n, bool)
    jump = np.zeros(n, bool)
    back = np.flatnonzero(stamps[1:] < stamps[:-1] - jump_ns) + 1
    for i in back.tolist():
        if spike[i - 1]:
            continue  # the step back from a spike already handled
        if i >= 2 and stamps[i] >= stamps[i - 2] - jump_ns and not jump[i - 1]:
            spike[i - 1] = True  # forward spike at i-1, back to normal at i
        elif i + 1 < n and stamps[i + 1] >= stamps[i - 1] - jump_ns:
            spike[i] = True  # backward spike at i
        else:
            jump[i] = True
    return np.cumsum(jump), spike


def _arrival(stamp: np.ndarray, keep: np.ndarray, seq: np.ndarray) -> tuple[np.ndarray, bool]:
    """Indexes of the kept samples in arrival order, and whether that differs from file order.

    Files written in log-time order lose the arrival order when log time is the header
    stamp; the Message records' sequence numbers keep it, when the writer set them (unique
    and not all zero on the stream).
    """
    idx = np.flatnonzero(keep)
    if seq.size and idx.size > 1:
        sq = seq[idx].astype(np.int64)
        step = np.diff(sq)
        if bool(np.all(step > 0)):
            return idx, False                  # the usual case: arrival order is file order
        if sq.any():
            order = np.argsort(sq, kind='stable')
            # unique (no two equal after sorting): np.unique's hashing is slow on 1e6 values
            if bool(np.all(np.diff(sq[order]) != 0)):
                return idx[order], True
    return idx, False


def _jumps(s: np.ndarray, jump_ns: int) -> list[tuple[int, int, int]]:
    """Backward clock steps of an arrival-ordered stamp sequence: (position, before, after).

    One-sample spikes are not steps (see :func:`_pieces`); ``before`` is the last stamp
    before the step that is not a spike, ``after`` the first stamp after it.
    """
    piece, spike = _pieces(s, jump_ns)
    out = []
    for k in (np.flatnonzero(np.diff(piece)) + 1).tolist():
        j = k - 1
        while j > 0 and spike[j]:
            j -= 1
        out.append((k, int(s[j]), int(s[k])))
    return out


def _repair_clocks(om: tuple, tq: tuple, jump_ns: int, gap_factor: float, max_gap: float,
                   topics: tuple[str, str], warnings: list[str]) -> tuple[tuple, tuple, int]:
    """Find backward clock steps per stream (in arrival order) and undo them.

    * A step in both streams by about the same amount is a restarted or looped recording:
      the later part of both streams is moved one second after the earlier part (the same
      shift for both, so their alignment is kept).  Counted as a clock jump.
    * A step in one stream only is a clock fault of that sensor (its clock was set back while
      the other ran on): its later samples are realigned by continuity (the first sample
      after the step is placed one median sample interval after the last before it), and the
      log is segmented there by moving everything after the step a gap further, so that no
      estimation window or equation spans the fault.  Counted in ``clock_faults``.

    Returns
    -------
    (om, tq, restarts) with the stamps of ``om`` and ``tq`` replaced (copies) and, when a
    stream's arrival order differs from file order, its ordinals replaced by the repaired
    stamps (so that the merged-order checks of :func:`_clean` see the repaired sequence).
    """
    s_om, s_tq = om[0].copy(), tq[0].copy()
    # file order is arrival order unless the file is stored in stamp order; then only the
    # sequence numbers show a step
    a_om, a_tq = np.flatnonzero(om[2]), np.flatnonzero(tq[2])
    re_om = re_tq = False
    j_om = _jumps(s_om[a_om], jump_ns)
    j_tq = _jumps(s_tq[a_tq], jump_ns) if a_tq.size else []
    if not j_om and not j_tq:
        a_om, re_om = _arrival(s_om, om[2], om[6])
        a_tq, re_tq = _arrival(s_tq, tq[2], tq[6])
        if not (re_om or re_tq):
            return om, tq, 0
        j_om = _jumps(s_om[a_om], jump_ns) if re_om else []
        j_tq = _jumps(s_tq[a_tq], jump_ns) if re_tq else []
        if not j_om and not j_tq:
            return om, tq, 0
    med = [_median_step(np.sort(s_om[a_om])), _median_step(np.sort(s_tq[a_tq]))]
    med = [int(m) if np.isfinite(m) else 0 for m in med]
    gap_ns = int(max(1e9, 2 * gap_factor * max(med)))
    # pair the steps of the two streams: similar size and similar place = a restart
    events: list[tuple[int, int | None, int | None]] = []  # (before, k_om, k_tq)
    used: set[int] = set()
    for k, b, a in j_om:
        d = b - a
        match = None
        for m, (_, b2, a2) in enumerate(j_tq):
            d2 = b2 - a2
            if m not in used and abs(d - d2) <= max(1e9, 0.1 * d) \
                    and abs(b - b2) <= max(2e9, 0.1 * d):
                match = m
                break
        if match is not None:
            used.add(match)
            events.append((b, k, j_tq[match][0]))
        else:
            events.append((b, k, None))
    events.extend((b, None, k) for m, (k, b, _) in enumerate(j_tq) if m not in used)
    events.sort(key=lambda e: e[0])
    restarts = faults = 0
    counts = (om[3], tq[3])
    for _, k_om, k_tq in events:
        if k_om is not None and k_tq is not None:
            before = max(int(s_om[a_om[k_om - 1]]), int(s_tq[a_tq[k_tq - 1]]))
            after = min(int(s_om[a_om[k_om]]), int(s_tq[a_tq[k_tq]]))
            shift = before + 1_000_000_000 - after
            s_om[a_om[k_om:]] += shift
            s_tq[a_tq[k_tq:]] += shift
            restarts += 1
            continue
        w = 0 if k_om is not None else 1
        s, a, k = ((s_om, a_om, k_om) if w == 0 else (s_tq, a_tq, k_tq))
        before, after = int(s[a[k - 1]]), int(s[a[k]])
        step = before - after
        s[a[k:]] += step + med[w]
        cut = before + med[w] // 2
        for ss, aa in ((s_om, a_om), (s_tq, a_tq)):
            later = aa[ss[aa] > cut]
            ss[later] += gap_ns
        counts[w].clock_faults += 1
        faults += 1
        warnings.append(
            f'{topics[w] or "torque"}: clock fault: the stamps step back {step / 1e9:.6g} s '
            f'after {(before - int(s_om[a_om[0]])) / 1e9:.6g} s of log while the other stream '
            'runs on; the later samples are realigned by continuity and the log is segmented '
            f'there (a {gap_ns / 1e9:g} s gap, so no equation spans the fault)')
    if restarts:
        warnings.append(f'{restarts} backward clock jump(s) in both streams (restarted or '
                        'looped recording): the later part is placed one second after the '
                        'earlier one and estimated as a separate segment')
    om = (s_om, *om[1:5], s_om.copy() if (re_om or re_tq) else om[5], om[6])
    tq = (s_tq, *tq[1:5], s_tq.copy() if (re_om or re_tq) else tq[5], tq[6])
    return om, tq, restarts


def _sort_dedup(stamps: np.ndarray, idx: np.ndarray, values: np.ndarray | None = None,
                counts: StreamCounts | None = None, name: str = '',
                warnings: list[str] | None = None) -> tuple[np.ndarray, int, int]:
    """Sort indexes ``idx`` by stamp (stable); drop exact duplicates and resolve conflicts.

    An exact duplicate (same stamp and same values as the sample before it) is dropped.
    Samples sharing a stamp with different values are a stamp conflict: two samples cannot
    both be right, so a few conflicts drop every sample of the conflicting stamps, and many
    (a clock that stepped back in a file stored in stamp order, where the two runs of stamps
    interleave and cannot be told apart) drop the stream from the first conflict on.  Both
    are counted in ``counts.stamp_conflicts`` (and the latter in ``counts.clock_faults``).

    Returns
    -------
    (idx, out_of_order, duplicates)
    """
    s = stamps[idx]
    if s.size < 2 or bool(np.all(s[1:] >= s[:-1])):
        late = 0                     # already in stamp order: the stable sort is the identity
    else:
        late = int((s[1:] < np.maximum.accumulate(s)[:-1]).sum())
        order = np.argsort(s, kind='stable')
        idx = idx[order]
        s = s[order]
    same = np.zeros(s.size, bool)
    same[1:] = s[1:] == s[:-1]
    if values is None:
        return idx[~same], late, int(same.sum())
    if not same.any():
        return _overlap(idx, s, counts, name, warnings), late, 0
    # exact duplicates: equal to the first sample of their stamp
    first = np.maximum.accumulate(np.where(~same, np.arange(s.size), 0))
    v = values[idx]
    equal = np.all((v == v[first]) | (np.isnan(v) & np.isnan(v[first])), axis=1)
    dup = same & equal
    conflict = same & ~equal
    if not conflict.any():
        keep = ~dup
        return _overlap(idx[keep], s[keep], counts, name, warnings), late, int(dup.sum())
    bad_stamp = np.isin(s, s[conflict])
    n_bad = int(bad_stamp.sum())
    keep = ~dup & ~bad_stamp
    unresolved = int(conflict.sum()) > max(3, 0.001 * s.size)
    if unresolved:
        cut = int(np.flatnonzero(bad_stamp)[0])
        keep[cut:] = False
    if counts is not None:
        counts.stamp_conflicts += int((~dup & ~keep).sum())
        counts.clock_faults += int(unresolved)
    if warnings is not None:
        if unresolved:
            warnings.append(
                f'{name}: clock fault: {int(conflict.sum())} samples share a stamp with a '
                'different sample (the clock stepped back and the file is stored in stamp '
                'order, so the two runs of stamps cannot be told apart); the stream from the '
                f'first conflict on ({int(s.size - cut)} samples) is dropped')
        else:
            warnings.append(f'{name}: {n_bad} samples sharing a stamp with different values '
                            'dropped (which one is right is unknown)')
    return idx[keep], late, int(dup.sum())


#: Overlap test of :func:`_overlap`: in any run of this many sample intervals ...
_DENSE_RUN = 20
#: ... at least this many shorter than half the median interval mean two interleaved clocks.
_DENSE_MIN = 8


def _window_counts(flags: np.ndarray, width: int) -> np.ndarray:
    """Number of True values in every run of ``width`` consecutive ``flags``.

    The same integers as ``np.convolve(flags, np.ones(width), 'valid')``, from one cumulative
    sum (O(n), not O(n * width)).

    Parameters
    ----------
    flags : numpy.ndarray
        bool (n,).
    width : int
        Window length (>= 1).

    Returns
    -------
    numpy.ndarray
        int64 (max(n - width + 1, 0),) counts.
    """
    if flags.size < width:
        return np.zeros(0, np.int64)
    cs = np.zeros(flags.size + 1, np.int64)
    np.cumsum(flags, out=cs[1:])
    return cs[width:] - cs[:-width]


def _overlap(idx: np.ndarray, s: np.ndarray, counts: StreamCounts | None, name: str,
             warnings: list[str] | None) -> np.ndarray:
    """Drop a stream from where two runs of its stamps interleave (a hidden clock fault).

    A clock that stepped back by a time that is not a whole number of sample intervals,
    in a file stored in stamp order without sequence numbers, leaves no equal stamps: the
    two runs interleave, and the stamp-sorted stream shows a stretch of doubled rate (every
    other interval under half the median).  The samples from that stretch on cannot be
    aligned with the other stream and are dropped; counted as a clock fault.

    Parameters
    ----------
    idx, s : numpy.ndarray
        Sample indexes and their stamps [ns], sorted by stamp, no repeated stamps.

    Returns
    -------
    numpy.ndarray
        The indexes kept.
    """
    if s.size < 4 * _DENSE_RUN:
        return idx
    d = np.diff(s)
    dense = d < 0.5 * _median(d)
    run = _window_counts(dense, _DENSE_RUN)
    hit = np.flatnonzero(run >= _DENSE_MIN)
    if hit.size == 0:
        # the whole stream interleaved (the median is halved too): consecutive intervals
        # alternate between two lengths (delta, T - delta) instead of repeating one
        lo, hi = np.minimum(d[1:], d[:-1]), np.maximum(d[1:], d[:-1])
        alt = np.zeros(d.size, bool)
        alt[1:] = lo < 0.7 * hi
        run = _window_counts(alt, _DENSE_RUN)
        hit = np.flatnonzero(run >= _DENSE_RUN - 2)
        dense = alt
    if hit.size == 0:
        return idx
    cut = int(hit[0] + np.argmax(dense[hit[0]:hit[0] + _DENSE_RUN]))
    if counts is not None:
        counts.clock_faults += 1
        counts.stamp_conflicts += int(s.size - cut)
    if warnings is not None:
        warnings.append(f'{name}: clock fault: from sample {cut} on the stamps of two runs '
                        'interleave (the clock stepped back and the file is stored in stamp '
                        f'order); the stream from there on ({int(s.size - cut)} samples) is '
                        'dropped, as it cannot be aligned')
    return idx[:cut]


def _truth(raw: _Raw | None, epoch: int) -> list[tuple[float, np.ndarray]]:
    """The true tensors recorded on /truth/inertia, as (t [s], (3, 3)) in stamp order."""
    if raw is None:
        return []
    stamp, _, vals, ok, _, _ = raw.arrays()
    out = []
    for k in np.argsort(stamp, kind='stable'):
        if not ok[k]:
            continue
        ixx, ixy, ixz, iyy, iyz, izz = vals[k]
        mat = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        out.append(((int(stamp[k]) - epoch) / 1e9, mat))
    return out
