"""Recorded logs -> clean numpy arrays for the estimator.

:func:`read_log` reads a single ``.mcap`` file or a rosbag2 directory (``metadata.yaml`` plus
its storage files), finds the angular-velocity and torque topics by message type, decodes
them with the vectorised CDR path, and cleans what real recordings contain.  With ``joints``
it also reads a ``sensor_msgs/msg/JointState`` stream (wheel or rotor speeds) as a third
stream, cleaned by the same rules: a pause, a clock repair or a NaN treats it as it treats
the gyro and the torque.  Plain MCAP is read by our own bounded reader
(:mod:`inertia_ros.io.mcap_reader`); sqlite3 (``.db3``) and compressed bags go through
``rosbags`` (:mod:`inertia_ros.io.rosbags_source`) into the same batches; ``metadata.yaml``
is validated once (:mod:`inertia_ros.io.rosbag2`).

======================  ===================================================================
problem                 handling (each counted in :attr:`StreamCounts`)
======================  ===================================================================
malformed payload       dropped (``malformed``)
NaN / Inf sample        dropped (``nonfinite``)
unusable JointState     arrays of different lengths (``mismatched``), a wanted joint or the
                        velocity missing (``incomplete``), a joint named twice with
                        different speeds (``ambiguous``): dropped (:class:`JointCounts`)
wrong ``frame_id``      a few stray messages are dropped (``wrong_frame``); two frames in
                        earnest, or different frames on the gyro and torque streams, raise
                        :class:`LogError` unless ``ignore_frames`` (JointState's frame is
                        not checked: it is not the body's)
clock restart           every stream's stamps step back together (a looped or restarted
                        recording): the later part is placed one second after the earlier
                        and estimated as a separate segment (``clock_jumps``)
clock fault             one stream's stamps step back while the others run on, seen in
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
                        stream; the estimator's windows are the intersections of every
                        stream's gap-free runs (``gaps``)
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

The layer is split by job: :mod:`.log_types` (the records), :mod:`.log_topics` (which topic
is which), :mod:`.log_clocks` (clock steps and their repair), :mod:`.log_clean` (the
cleaning table above); this module reads the files and runs the stages in order.
"""
from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from inertia_ros.io import cdr_decode
from inertia_ros.io.log_clean import clean, prepare, prepare_joints
from inertia_ros.io.log_clocks import rate_hz, repair_clocks
from inertia_ros.io.log_topics import (
    JOINT_STATE,
    OMEGA_TYPES,
    TORQUE_TYPES,
    TRUTH_TOPIC,
    TRUTH_TYPE,
    choose_joint_topic,
    choose_topics,
    field_for,
)
from inertia_ros.io.log_types import (
    JointCounts,
    LogData,
    LogError,
    PreparedStream,
    RawTopic,
    Stream,
    StreamCounts,
)
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

if TYPE_CHECKING:          # (imported where used: a .mcap file needs neither, nor joint_state)
    from inertia_ros.io.rosbag2 import BagInfo
    from inertia_ros.io.rosbags_source import RosbagsSource

__all__ = ['JOINT_STATE', 'OMEGA_TYPES', 'TORQUE_TYPES', 'TRUTH_TOPIC', 'TRUTH_TYPE',
           'JointCounts', 'LogData', 'LogError', 'Stream', 'StreamCounts', 'log_files',
           'read_log']


def _bag(path: str | Path) -> BagInfo | None:
    """The validated metadata of a bag directory (None for a file or a bare directory)."""
    p = Path(path)
    if not p.is_dir():
        return None
    from inertia_ros.io.rosbag2 import BagMetadataError, read_bag_info

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
    if not p.is_dir():
        raise LogError(f'{p}: not a regular file or directory (a FIFO, socket or device); give '
                       'an .mcap file or a rosbag2 directory')
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
             progress: Callable[[int, int], None] | None = None,
             joints: Sequence[str] | None = None, joint_topic: str | None = None,
             joint_what: str = 'wheels') -> LogData:
    """Read a log into cleaned angular-velocity, torque and (optionally) joint-speed streams.

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
    joints : sequence of str, optional
        Joint names whose speeds (``JointState.velocity`` [rad/s]) are read as a third stream
        (:attr:`LogData.joints`, columns in this order), cleaned as the other two and
        covering them (the windows are where all three are gap-free).
    joint_topic : str, optional
        The JointState topic; found by type when there is exactly one.
    joint_what : {'wheels', 'rotors'}
        What the joints are (names the command-line options in the messages).

    Returns
    -------
    LogData

    Raises
    ------
    LogError
        Unreadable input, no or ambiguous topics, wrong message types, mismatched frames,
        empty streams, wanted joints that never appear.
    ValueError
        Invalid numeric arguments.
    """
    _check_args(torque_delay, gap_factor, max_backward_jump, min_window, max_gap)
    if joints is not None and len(joints) == 0:
        raise ValueError('joints: give at least one joint name, or None')
    files = log_files(path)
    info = _bag(path)
    want = list(joints) if joints is not None else None
    raws, topics, metadata, damage, warnings = _read_files(
        files, omega_topic, torque_topic, progress, info, want, joint_topic)
    if damage.any:
        warnings.extend(f'damaged log: {note}' for note in damage.notes)
    om_topic, tq_topic, js_topic = _choose_all(path, topics, (omega_topic, torque_topic,
                                                              joint_topic), want, joint_what)
    _check_counts(info, raws, (om_topic, tq_topic, js_topic), warnings)
    streams = _prepare_all(raws, topics, (om_topic, tq_topic, js_topic), ignore_frames,
                           want, joint_what, warnings)
    if torque_delay and tq_topic:
        streams[1].stamp = streams[1].stamp - int(round(torque_delay * 1e9))
    restarts = repair_clocks(streams, int(max_backward_jump * 1e9), gap_factor, warnings)
    data = clean(streams, gap_factor=gap_factor, max_backward_jump=max_backward_jump,
                 min_window=min_window, warnings=warnings, max_gap=max_gap)
    omega, torque, js = _outputs(streams, data.t, data.values, topics, want)
    return LogData(files, data.epoch, omega, torque, data.windows, data.jumps + restarts,
                   _truth(raws.get(TRUTH_TOPIC), data.epoch), topics, metadata, damage,
                   warnings, sum(st.counts.clock_faults for st in streams), data.pauses,
                   data.removed_ns / 1e9, js)


def _choose_all(path: str | Path, topics: dict[str, str],
                given: tuple[str | None, str | None, str | None], joints: list[str] | None,
                what: str) -> tuple[str, str, str]:
    """The angular-velocity, torque and JointState topics from the ones ``given`` (``''``
    for torque-free data, and for JointState when no ``joints`` are wanted)."""
    omega_topic, torque_topic, joint_topic = given
    no_torque = torque_topic is not None and torque_topic.lower() == 'none'
    om, tq = choose_topics(path, topics, omega_topic, None if no_torque else torque_topic,
                           need_torque=not no_torque)
    js = '' if joints is None else choose_joint_topic(path, topics, joint_topic, what)
    return om, tq, js


def _outputs(streams: list[PreparedStream], t: list[np.ndarray], values: list[np.ndarray],
             topics: dict[str, str], joints: list[str] | None
             ) -> tuple[Stream, Stream, Stream | None]:
    """The cleaned :class:`Stream` s: angular velocity, torque (empty for torque-free
    data), JointState (None when not wanted)."""
    out = [Stream(st.topic, topics.get(st.topic, ''), st.frame, tt, v, st.counts, rate_hz(tt))
           for st, tt, v in zip(streams, t, values, strict=True)]
    js = None
    if joints is not None:
        js = out.pop()
        js.names = tuple(joints)
    torque = out[1] if len(out) > 1 else Stream('', '', streams[0].frame, np.zeros(0),
                                                np.zeros((0, 3)), StreamCounts())
    return out[0], torque, js


def _check_args(torque_delay: float, gap_factor: float, max_backward_jump: float,
                min_window: int, max_gap: float) -> None:
    """Refuse invalid numeric arguments of :func:`read_log` (ValueError, one line)."""
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


def _check_counts(info: BagInfo | None, raws: dict[str, RawTopic], used: tuple[str, ...],
                  warnings: list[str]) -> None:
    """Warn when fewer messages were read than ``metadata.yaml`` lists for a topic used."""
    expected = info.message_counts if info is not None else {}
    for t in used:
        got = raws[t].count if t in raws else 0
        if t in expected and got < expected[t]:
            warnings.append(f'{t}: metadata.yaml lists {expected[t]} messages, {got} were read '
                            f'({expected[t] - got} lost)')


def _prepare_all(raws: dict[str, RawTopic], topics: dict[str, str],
                 chosen: tuple[str, str, str], ignore_frames: bool,
                 joints: list[str] | None, what: str, warnings: list[str]
                 ) -> list[PreparedStream]:
    """The streams to clean, bad messages marked: angular velocity, then torque (absent
    for torque-free data), then JointState (when ``joints`` are wanted)."""
    om_topic, tq_topic, js_topic = chosen
    om = prepare('angular velocity', om_topic, topics[om_topic], raws.get(om_topic),
                 ignore_frames, warnings)
    streams = [om]
    if not tq_topic:
        warnings.append('no torque stream (--torque-topic none): torque-free data, only the '
                        'ratios and principal axes are observable')
    else:
        tq = prepare('torque', tq_topic, topics[tq_topic], raws.get(tq_topic), ignore_frames,
                     warnings)
        if not ignore_frames and om.frame != tq.frame:
            raise LogError(f'frames differ: {om_topic} is in {om.frame!r} but {tq_topic} is '
                           f'in {tq.frame!r}; the torque must be expressed in the gyro frame '
                           '(or pass --ignore-frames if they are the same frame under two '
                           'names)')
        streams.append(tq)
    if js_topic:
        assert joints is not None
        streams.append(prepare_joints(js_topic, JOINT_STATE, raws.get(js_topic), joints,
                                      what, warnings))
    return streams


def _open(f: Path, info: BagInfo | None, prog: Callable[[int, int], None]
          ) -> McapReader | RosbagsSource:
    """A batch source for one MCAP file, or for the whole bag when rosbags must read it."""
    if info is not None and not info.own_mcap_path:
        from inertia_ros.io.rosbags_source import RosbagsError, RosbagsSource

        try:
            return RosbagsSource(info, progress=prog)
        except RosbagsError as exc:
            raise LogError(str(exc)) from None
    try:
        return McapReader(f, progress=prog)
    except McapError as exc:
        raise LogError(str(exc)) from None


def _read_files(files: list[Path], omega_topic: str | None, torque_topic: str | None,
                progress: Callable[[int, int], None] | None, info: BagInfo | None = None,
                joints: list[str] | None = None, joint_topic: str | None = None
                ) -> tuple[dict[str, RawTopic], dict[str, str], dict[str, dict[str, str]],
                           Damage, list[str]]:
    """One pass over every file: decode every topic of a type we can use.

    Plain MCAP goes through our own reader, file by file; any other rosbag2 storage (sqlite3,
    compressed) through :class:`~inertia_ros.io.rosbags_source.RosbagsSource`, once for the
    whole bag.  JointState topics (``joint_topic``, or all of them) are decoded only when
    ``joints`` are wanted.
    """
    if info is not None and not info.own_mcap_path:
        files = [info.directory]
    select = _selector(omega_topic, torque_topic, joints, joint_topic)
    raws: dict[str, RawTopic] = {}
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
            for b in _batches(reader, select):
                typ = cdr_decode.normalise_type(b.schema.name)
                raw = raws.setdefault(b.channel.topic, RawTopic(typ))
                if typ != raw.msg_type:
                    warnings.append(f'{b.channel.topic}: type changed from {raw.msg_type} to '
                                    f'{typ} in {f.name}; those messages are ignored')
                    continue
                _add_batch(raw, typ, b, ordinal_base + b.ordinal, joints)
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


def _selector(omega_topic: str | None, torque_topic: str | None, joints: list[str] | None,
              joint_topic: str | None) -> ChannelFilter:
    """The channels :func:`_read_files` decodes.

    With both topics named only those (and the truth) are decoded, else every candidate;
    JointState only when joints are wanted (the topic named, or every JointState topic).
    """
    wanted_types = set(OMEGA_TYPES) | set(TORQUE_TYPES) | {TRUTH_TYPE}
    if joints is not None:
        wanted_types.add(JOINT_STATE)
    named = {omega_topic, torque_topic} if omega_topic and torque_topic else set()

    def select(ch: Channel, schema: Schema | None) -> bool:
        typ = cdr_decode.normalise_type(schema.name) if schema else ''
        if ch.message_encoding != 'cdr' or typ not in wanted_types:
            return False
        if typ == JOINT_STATE:
            return joint_topic is None or ch.topic == joint_topic
        if named and ch.topic not in named and ch.topic != TRUTH_TOPIC:
            return False
        return True

    return select


def _add_batch(raw: RawTopic, typ: str, b: MessageBatch, ordinal: np.ndarray,
               joints: list[str] | None) -> None:
    """Decode one batch of ``typ`` messages into ``raw``."""
    if typ == JOINT_STATE:
        assert joints is not None
        from inertia_ros.io.joint_state import joint_rows

        stamp, speed, status, names = joint_rows(b.buf, b.starts, b.lengths, joints)
        raw.add_rows(stamp, speed, status, ordinal, b.sequence, names)
        return
    fname = field_for(typ, b.channel.topic)
    fields = None if typ == TRUTH_TYPE else (fname,)
    d = cdr_decode.decode_batch(typ, b.buf, b.starts, b.lengths, fields)
    if typ == TRUTH_TYPE:
        vals = np.concatenate([d.fields[k] for k, _ in cdr_decode.LAYOUTS[TRUTH_TYPE][2:]],
                              axis=1)
        d = cdr_decode.DecodedBatch(d.msg_type, d.stamp_ns, d.frame_index, d.frame_ids,
                                    {'inertia': vals}, d.ok)
        fname = 'inertia'
    raw.add(d, fname, ordinal, b.sequence)


def _batches(reader: McapReader | RosbagsSource, select: ChannelFilter
             ) -> Iterator[MessageBatch]:
    """``reader.iter_batches(select)`` with reader failures as one-line :class:`LogError`."""
    try:
        yield from reader.iter_batches(select)
    except CodecMissingError as exc:
        raise LogError(str(exc)) from None
    except _rosbags_error() as exc:     # (evaluated only when an exception propagates)
        raise LogError(str(exc)) from None


def _rosbags_error() -> type[Exception]:
    """:class:`~inertia_ros.io.rosbags_source.RosbagsError`, imported on first need."""
    from inertia_ros.io.rosbags_source import RosbagsError

    return RosbagsError




def _truth(raw: RawTopic | None, epoch: int) -> list[tuple[float, np.ndarray]]:
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
