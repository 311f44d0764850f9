"""Stream cleaning of the log layer: bad messages, pieces, sorting, duplicates, gaps, windows
and long pauses, for the angular-velocity stream and every stream that covers it (torque,
JointState).  The rules are in the table of :mod:`inertia_ros.io.logs`; every stream gets
the same ones.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from inertia_ros.io.log_clocks import median_of, median_step, pieces, runs
from inertia_ros.io.log_types import (
    JointCounts,
    LogError,
    PreparedStream,
    RawTopic,
    StreamCounts,
    missing_joints_error,
)

__all__ = ['Cleaned', 'clean', 'prepare', 'prepare_joints']

#: JointState row status (see :func:`inertia_ros.io.joint_state.joint_rows`) -> the counter
#: of :class:`JointCounts` and the warning of the messages dropped for it.
_JOINT_DROPS = {
    1: ('malformed', 'malformed messages dropped'),
    2: ('mismatched', 'messages whose name and velocity arrays differ in length dropped '
                      '(which speed belongs to which joint is unknown)'),
    3: ('incomplete', 'messages without a velocity for every joint of the {what} file '
                      'dropped'),
    4: ('ambiguous', 'messages naming a joint twice with different speeds dropped'),
}


def prepare(label: str, topic: str, msg_type: str, raw: RawTopic | None, ignore_frames: bool,
            warnings: list[str], counts: StreamCounts | None = None) -> PreparedStream:
    """The decoded messages of one topic with bad ones marked (malformed, NaN/Inf, stray
    frames), each counted.

    Parameters
    ----------
    label : str
        What the stream is (for the cleaning's warnings).
    topic, msg_type : str
    raw : RawTopic or None
        Its decoded messages (emptied here); None when the log has none.
    ignore_frames : bool
        Keep messages in other frames.
    warnings : list of str
        One line per kind of message dropped is appended.
    counts : StreamCounts, optional
        Counts already filled in (``received``, ``malformed``...: the JointState stream); the
        frame check is then skipped (JointState's frame is not the body's).

    Raises
    ------
    LogError
        No messages, or none usable.
    """
    if raw is None:
        raise LogError(f'{topic}: no messages of type {msg_type} in the log (empty stream)')
    stamp, frame, values, ok, ordinal, seq = raw.arrays()
    raw.stamp, raw.frame, raw.values, raw.ok, raw.ordinal, raw.seq = [], [], [], [], [], []
    if stamp.size == 0:
        raise LogError(f'{topic}: the stream is empty')
    keep = ok.copy()
    frame_name = ''
    if counts is None:
        counts = StreamCounts(received=int(stamp.size))
        counts.malformed = int((~ok).sum())
        if counts.malformed:
            warnings.append(f'{topic}: {counts.malformed} malformed messages dropped')
    finite = _finite_rows(values)
    counts.nonfinite = int((keep & ~finite).sum())
    keep &= finite
    if not isinstance(counts, JointCounts):
        frame_name = _check_frames(topic, raw, frame, keep, counts, ignore_frames, warnings)
    if counts.nonfinite:
        warnings.append(f'{topic}: {counts.nonfinite} samples with NaN or Inf dropped')
    if not keep.any():
        raise LogError(f'{topic}: no usable messages ({counts.received} received, all '
                       'malformed or non-finite)')
    return PreparedStream(label, topic, stamp, values, keep, counts, frame_name, ordinal, seq)


def _check_frames(topic: str, raw: RawTopic, frame: np.ndarray, keep: np.ndarray,
                  counts: StreamCounts, ignore_frames: bool, warnings: list[str]) -> str:
    """The stream's frame (the most common of the kept messages); a few stray messages in
    other frames are dropped from ``keep`` (counted), many refused unless ``ignore_frames``."""
    names = {v: k for k, v in raw.frames.items()}
    if not keep.any():
        return ''
    codes, n = np.unique(frame[keep], return_counts=True)
    main = int(codes[np.argmax(n)])
    frame_name = names.get(main, '')
    if codes.size > 1:
        stray = keep & (frame != main)
        n_stray = int(stray.sum())
        others = ', '.join(repr(names.get(int(c), '?')) for c in codes if c != main)
        if not ignore_frames and n_stray > max(3, 0.01 * keep.sum()):
            raise LogError(f'{topic}: messages in several frames ({frame_name!r} and '
                           f'{others}); record one frame per topic or pass --ignore-frames')
        if not ignore_frames:
            keep &= ~stray
            counts.wrong_frame = n_stray
            warnings.append(f'{topic}: {n_stray} messages in frame(s) {others} instead of '
                            f'{frame_name!r} dropped')
    return frame_name


def prepare_joints(topic: str, msg_type: str, raw: RawTopic | None, joints: Sequence[str],
                   what: str, warnings: list[str]) -> PreparedStream:
    """The JointState messages of ``topic`` with unusable ones marked and counted.

    Raises
    ------
    LogError
        No messages, a wanted joint in no message's ``name``, fewer than two usable
        messages.
    """
    if raw is None:
        raise LogError(f'{topic}: no messages of type {msg_type} in the log (empty stream)')
    missing = [j for j in joints if j not in raw.names_seen]
    if missing:
        raise missing_joints_error(topic, missing, raw.names_seen, what)
    status = raw.status_array()
    counts = JointCounts(received=int(status.size))
    for code, (name, text) in _JOINT_DROPS.items():
        n = int((status == code).sum())
        setattr(counts, name, n)
        if n:
            warnings.append(f'{topic}: {n} {text.format(what=what)}')
    try:
        st = prepare(topic, topic, msg_type, raw, True, warnings, counts)
    except LogError:
        st = None
    if st is None or int(st.keep.sum()) < 2:
        raise LogError(f'{topic}: fewer than 2 JointState messages carry finite velocities '
                       f'for all of {list(joints)} ({counts.received} received); check the '
                       f'{what} file\'s joint names and the recording')
    return st


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


def _cat(parts: list[np.ndarray]) -> np.ndarray:
    """Concatenate, without a copy when there is one part (and emptying the list)."""
    out = parts[0] if len(parts) == 1 else np.concatenate(parts)
    parts.clear()
    return out


@dataclass
class Cleaned:
    """What :func:`clean` returns.

    Attributes
    ----------
    epoch : int
        Header stamp [ns] that ``t = 0`` stands for (the start of the first window).
    t : list of numpy.ndarray
        Per stream, float64 (n_i,) times [s] relative to ``epoch``, increasing.
    values : list of numpy.ndarray
        Per stream, (n_i, k_i) the samples kept.
    windows : list of (float, float)
        Windows [s] in which every stream is gap-free.
    jumps : int
        Backward clock jumps of the merged stamps (pieces - 1).
    pauses : int
        Long pauses shortened.
    removed_ns : int
        Time those pauses lost [ns].
    """

    epoch: int
    t: list[np.ndarray]
    values: list[np.ndarray]
    windows: list[tuple[float, float]]
    jumps: int
    pauses: int
    removed_ns: int


def clean(streams: list[PreparedStream], *, gap_factor: float, max_backward_jump: float,
          min_window: int, warnings: list[str], max_gap: float = 10.0) -> Cleaned:
    """Pieces, sorting, de-duplication, gaps, windows and pauses of every stream.

    Parameters
    ----------
    streams : list of PreparedStream
        The angular velocity first (its samples count towards ``min_window``), then the
        streams that must cover it (torque, JointState); the counts are updated in place.
    gap_factor, max_backward_jump, min_window, max_gap
        As in :func:`inertia_ros.io.logs.read_log`.
    warnings : list of str
        One line per thing the user should know is appended.

    Raises
    ------
    LogError
        No window of ``min_window`` gyro samples in which every stream is gap-free.
    """
    idx, piece_of, n_pieces = _split_pieces(streams, int(max_backward_jump * 1e9), warnings)
    out_t: list[list[np.ndarray]] = [[] for _ in streams]
    out_v: list[list[np.ndarray]] = [[] for _ in streams]
    windows_ns: list[tuple[int, int]] = []
    steps: list[float] = []
    shift = 0
    last_end: int | None = None
    epoch: int | None = None
    for p in range(n_pieces):
        sel = [i[pc == p] for i, pc in zip(idx, piece_of, strict=True)]
        got = _piece(streams, sel, gap_factor, min_window, steps, warnings)
        if got is None:
            continue
        good, kept = got
        if epoch is None:
            epoch = good[0][0]
        if last_end is not None and good[0][0] + shift <= last_end:
            # a later piece overlapping in time: place it after the previous one, one second on
            shift = last_end + 1_000_000_000 - good[0][0]
        for w, (s_k, i_k) in enumerate(kept):
            out_t[w].append(s_k + shift)
            out_v[w].append(_rows(streams[w].values, i_k))
        windows_ns.extend((lo + shift, hi + shift) for lo, hi in good)
        last_end = good[-1][1] + shift
    if epoch is None:
        raise _no_window(streams, min_window)
    t_ns = [_cat(parts) for parts in out_t]
    values = [_cat(parts) for parts in out_v]
    for st in streams:          # the raw arrays are no longer needed
        st.stamp = st.values = np.zeros(0)
    windows_ns, pauses, removed = _shorten_pauses(windows_ns, tuple(t_ns), int(max_gap * 1e9),
                                                  steps)
    if pauses:
        warnings.append(f'{pauses} pause(s) longer than {max_gap:g} s in the log: each is '
                        f'shortened to {_pause_ns(steps) / 1e9:g} s ({removed / 1e9:.6g} s '
                        'removed from the times after it) and ends a segment, so no equation '
                        'spans it')
    t = [(s - epoch) / 1e9 for s in t_ns]
    for st, tt in zip(streams, t, strict=True):
        st.counts.used = int(tt.size)
    windows = [((lo - epoch) / 1e9, (hi - epoch) / 1e9) for lo, hi in windows_ns]
    _final_warnings(streams, warnings)
    return Cleaned(epoch, t, values, windows, n_pieces - 1, pauses, removed)


def _kinds(streams: list[PreparedStream]) -> list[str]:
    """What each stream is, as in messages: angular-velocity, torque, JointState."""
    return ['angular-velocity'] + ['torque' if st.label == 'torque' else 'JointState'
                                   for st in streams[1:]]


def _and(words: list[str]) -> str:
    return words[0] if len(words) == 1 else ', '.join(words[:-1]) + ' and ' + words[-1]


def _final_warnings(streams: list[PreparedStream], warnings: list[str]) -> None:
    """The per-stream warnings of the cleaning (duplicates, order, gaps, coverage)."""
    for st in streams:
        c = st.counts
        if c.duplicates:
            warnings.append(f'{st.label}: {c.duplicates} duplicated messages dropped')
        if c.out_of_order:
            warnings.append(f'{st.label}: {c.out_of_order} messages arrived out of order '
                            '(sorted)')
        if c.gaps:
            warnings.append(f'{st.label}: {c.gaps} gap(s) in the stream; estimation windows '
                            'split')
    c_om = streams[0].counts
    frac = c_om.outside / max(c_om.received, 1)
    if frac > 0.05:
        cover = _and(_kinds(streams)[1:]) if len(streams) > 1 else 'torque'
        warnings.append(f'{100 * frac:.0f}% of the angular-velocity samples lie outside the '
                        f'{cover} coverage (a stream stops early or starts late) and were '
                        'dropped')


def _no_window(streams: list[PreparedStream], min_window: int) -> LogError:
    """The one-line error for a log in which no window survives."""
    if len(streams) == 1:
        return LogError('the angular-velocity stream has no window of at least '
                        f'{min_window} samples without a gap')
    conflicts = sum(st.counts.stamp_conflicts for st in streams)
    if conflicts:
        return LogError(f'no usable window: {conflicts} samples lie where two runs of stamps '
                        'collide or interleave (a clock that stepped back, in a file stored in '
                        'stamp order); record the receive time as log time, or the sequence '
                        'numbers, so that the runs can be told apart')
    kinds = _kinds(streams)
    hint = ', or --torque-delay' if 'torque' in kinds else ''
    return LogError(f'the {_and(kinds)} streams never overlap in time (header stamps); check '
                    f'the clocks{hint}')


def _split_pieces(streams: list[PreparedStream], jump_ns: int, warnings: list[str]
                  ) -> tuple[list[np.ndarray], list[np.ndarray], int]:
    """Pieces: backward clock jumps of the merged stamp sequence in arrival (file) order.

    Lone outlying stamps are dropped (``bad_stamps``).

    Returns
    -------
    (idx, piece, n_pieces)
        Per stream, the kept sample indexes and the piece of each; the number of pieces.
    """
    kept = [np.flatnonzero(st.keep) for st in streams]
    which = np.concatenate([np.full(k.size, w, np.int8) for w, k in enumerate(kept)])
    pos = np.concatenate(kept)
    order = np.argsort(np.concatenate([st.ordinal[k] for st, k in
                                       zip(streams, kept, strict=True)]), kind='stable')
    which, pos = which[order], pos[order]
    merged = np.empty(pos.size, np.int64)
    for w, st in enumerate(streams):
        m = which == w
        merged[m] = st.stamp[pos[m]]
    piece, spikes = pieces(merged, jump_ns)
    for w, st in enumerate(streams):
        bad = pos[spikes & (which == w)]
        st.counts.bad_stamps += int(bad.size)
        st.keep[bad] = False
    which, pos, piece = which[~spikes], pos[~spikes], piece[~spikes]
    n_pieces = int(piece.max(initial=0)) + 1
    if n_pieces > 1:
        warnings.append(f'{n_pieces - 1} backward clock jump(s) (restarted or looped '
                        'recording): the log is split into pieces estimated as separate '
                        'segments')
    for st in streams:
        if st.counts.bad_stamps:
            warnings.append(f'{st.label}: {st.counts.bad_stamps} messages with a stamp far off '
                            'its neighbours dropped')
    return ([pos[which == w] for w in range(len(streams))],
            [piece[which == w] for w in range(len(streams))], n_pieces)


def _piece(streams: list[PreparedStream], sel: list[np.ndarray], gap_factor: float,
           min_window: int, steps: list[float], warnings: list[str]
           ) -> tuple[list[tuple[int, int]], list[tuple[np.ndarray, np.ndarray]]] | None:
    """One piece of the log: sorted and de-duplicated streams, their gap-free runs, and the
    windows (intersections of every stream's runs with ``min_window`` gyro samples).

    Parameters
    ----------
    sel : list of numpy.ndarray
        Per stream, the sample indexes of the piece (replaced).
    steps : list of float
        Each stream's median step [ns] is appended.

    Returns
    -------
    (windows, kept) or None
        Windows [ns] (lo, hi), and per stream the (stamps [ns], indexes) in them; None when
        the piece has none.
    """
    if any(s.size == 0 for s in sel):
        for st, s in zip(streams, sel, strict=True):
            st.counts.outside += int(s.size)
        return None
    for w, st in enumerate(streams):
        sel[w], late, dup = _sort_dedup(st.stamp, sel[w], st.values, st.counts, st.label,
                                        warnings)
        st.counts.out_of_order += late
        st.counts.duplicates += dup
    if any(s.size == 0 for s in sel):
        return None  # everything of a stream in this piece was a conflict (counted)
    ss = [st.stamp[s] for st, s in zip(streams, sel, strict=True)]
    wins: list[tuple[int, int]] | None = None
    for st, sk in zip(streams, ss, strict=True):
        step = median_step(sk)
        steps.append(step)
        rr = runs(sk, gap_factor * step) if np.isfinite(step) else [(0, sk.size)]
        st.counts.gaps += len(rr) - 1
        spans = [(int(sk[r0]), int(sk[r1 - 1])) for r0, r1 in rr]
        wins = spans if wins is None else _intersect(wins, spans)
    assert wins is not None
    wins.sort()
    masks = [np.zeros(sk.size, bool) for sk in ss]
    good = []
    for lo, hi in wins:
        m0 = (ss[0] >= lo) & (ss[0] <= hi)
        if m0.sum() < min_window:
            continue
        masks[0] |= m0
        for w in range(1, len(ss)):
            masks[w] |= (ss[w] >= lo) & (ss[w] <= hi)
        good.append((lo, hi))
    for st, m in zip(streams, masks, strict=True):
        st.counts.outside += int((~m).sum())
    if not good:
        return None
    return good, [(sk[m], s[m]) for sk, s, m in zip(ss, sel, masks, strict=True)]


def _intersect(ia: list[tuple[int, int]], ib: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Intersections of two sorted lists of closed spans (a merge sweep); empty and
    single-point intersections are left out."""
    out = []
    i = j = 0
    while i < len(ia) and j < len(ib):
        lo, hi = max(ia[i][0], ib[j][0]), min(ia[i][1], ib[j][1])
        if hi > lo:
            out.append((lo, hi))
        if ia[i][1] < ib[j][1]:
            i += 1
        else:
            j += 1
    return out


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
    dense = d < 0.5 * median_of(d)
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


