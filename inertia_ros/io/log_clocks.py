"""Clock repair of the log layer: the stamp arithmetic shared by the cleaning stages (median
sample steps, gap-free runs), backward clock steps of the merged and of each stream's stamps,
and their repair (a restarted recording; one sensor's clock set back).

Every function takes any number of streams: the angular velocity first, then the torque
and the JointState streams when the log has them.
"""
from __future__ import annotations

import numpy as np

from inertia_ros.core._numeric import median
from inertia_ros.io.log_types import PreparedStream

__all__ = ['median_of', 'median_step', 'pieces', 'rate_hz', 'repair_clocks', 'runs']


def median_of(d: np.ndarray) -> float:
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


def median_step(s: np.ndarray) -> float:
    """Median positive step of the stamps ``s`` (n,) [ns] (NaN with none)."""
    d = np.diff(s)
    d = d[d > 0]
    return median_of(d) if d.size else float('nan')


def rate_hz(t: np.ndarray) -> float:
    """Median sample rate [Hz] of the times ``t`` (n,) [s] (NaN with fewer than two)."""
    step = median_step(t)
    return 1.0 / step if np.isfinite(step) and step > 0 else float('nan')


def runs(stamps: np.ndarray, limit: float) -> list[tuple[int, int]]:
    """Index ranges [a, b) of ``stamps`` (sorted) without a step above ``limit``."""
    if stamps.size == 0:
        return []
    cut = np.flatnonzero(np.diff(stamps) > limit) + 1
    edges = np.concatenate(([0], cut, [stamps.size]))
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def pieces(stamps: np.ndarray, jump_ns: int) -> tuple[np.ndarray, np.ndarray]:
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

    One-sample spikes are not steps (see :func:`pieces`); ``before`` is the last stamp
    before the step that is not a spike, ``after`` the first stamp after it.
    """
    piece, spike = pieces(s, jump_ns)
    out = []
    for k in (np.flatnonzero(np.diff(piece)) + 1).tolist():
        j = k - 1
        while j > 0 and spike[j]:
            j -= 1
        out.append((k, int(s[j]), int(s[k])))
    return out



def _pair_steps(jumps: list[list[tuple[int, int, int]]]) -> list[tuple[int, dict[int, int]]]:
    """Group the backward steps of the streams: steps of similar size at a similar place
    are one event (a restart when every stream has it).

    Parameters
    ----------
    jumps : list of list of (position, before, after)
        Each stream's steps (see :func:`_jumps`), stamps [ns].

    Returns
    -------
    list of (before, {stream: position})
        Sorted by the first stream's stamp before the step.
    """
    events: list[tuple[int, dict[int, int]]] = []
    used = [set() for _ in jumps]
    for w, steps in enumerate(jumps):
        for m, (k, b, a) in enumerate(steps):
            if m in used[w]:
                continue
            used[w].add(m)
            d = b - a
            event = {w: k}
            for v in range(w + 1, len(jumps)):
                for m2, (k2, b2, a2) in enumerate(jumps[v]):
                    if m2 not in used[v] and abs(d - (b2 - a2)) <= max(1e9, 0.1 * d) \
                            and abs(b - b2) <= max(2e9, 0.1 * d):
                        used[v].add(m2)
                        event[v] = k2
                        break
            events.append((b, event))
    events.sort(key=lambda e: e[0])
    return events


def _find_steps(streams: list[PreparedStream], jump_ns: int
                ) -> tuple[list[np.ndarray], list[bool], list[list[tuple[int, int, int]]]]:
    """Each stream's kept samples in arrival order, whether that order came from the
    sequence numbers, and its backward steps (all empty when there is none)."""
    arrival = [np.flatnonzero(st.keep) for st in streams]
    reordered = [False] * len(streams)
    # file order is arrival order unless the file is stored in stamp order; then only the
    # sequence numbers show a step
    jumps = [_jumps(st.stamp[a], jump_ns) if a.size else []
             for st, a in zip(streams, arrival, strict=True)]
    if any(jumps):
        return arrival, reordered, jumps
    for w, st in enumerate(streams):
        arrival[w], reordered[w] = _arrival(st.stamp, st.keep, st.seq)
    jumps = [_jumps(st.stamp[a], jump_ns) if re else []
             for st, a, re in zip(streams, arrival, reordered, strict=True)]
    return arrival, reordered, jumps


def repair_clocks(streams: list[PreparedStream], jump_ns: int, gap_factor: float,
                  warnings: list[str]) -> int:
    """Find backward clock steps per stream (in arrival order) and undo them.

    * A step in every stream by about the same amount is a restarted or looped recording:
      the later part of every stream is moved one second after the earlier part (the same
      shift for all, so their alignment is kept).  Counted as a clock jump.
    * A step in one stream only is a clock fault of that sensor (its clock was set back while
      the others ran on): its later samples are realigned by continuity (the first sample
      after the step is placed one median sample interval after the last before it), and the
      log is segmented there by moving everything after the step a gap further, so that no
      estimation window or equation spans the fault.  Counted in ``clock_faults``.

    Parameters
    ----------
    streams : list of PreparedStream
        The angular velocity first.  Their ``stamp`` arrays are replaced by repaired copies
        and, when a stream's arrival order differs from file order, every ``ordinal`` by the
        repaired stamps (so that the merged-order checks of the cleaning see the repaired
        sequence).
    jump_ns : int
        A backward step larger than this [ns] is a clock step.
    gap_factor : float
        The gap rule (sets the segmenting gap after a fault).
    warnings : list of str
        One line is appended per repair.

    Returns
    -------
    int
        Restarts found.
    """
    arrival, reordered, jumps = _find_steps(streams, jump_ns)
    if not any(jumps):
        return 0
    s = [st.stamp.copy() for st in streams]
    med = [median_step(np.sort(ss[a])) for ss, a in zip(s, arrival, strict=True)]
    med_ns = [int(m) if np.isfinite(m) else 0 for m in med]
    gap_ns = int(max(1e9, 2 * gap_factor * max(med_ns)))
    restarts = 0
    others = 'the other stream runs on' if len(streams) <= 2 else 'the other streams run on'
    for _, event in _pair_steps(jumps):
        if len(streams) > 1 and len(event) == len(streams):
            before = max(int(s[w][arrival[w][k - 1]]) for w, k in event.items())
            after = min(int(s[w][arrival[w][k]]) for w, k in event.items())
            for w, k in event.items():
                s[w][arrival[w][k:]] += before + 1_000_000_000 - after
            restarts += 1
            continue
        for w, k in event.items():
            a = arrival[w]
            before, after = int(s[w][a[k - 1]]), int(s[w][a[k]])
            step = before - after
            s[w][a[k:]] += step + med_ns[w]
            cut = before + med_ns[w] // 2
            for ss, aa in zip(s, arrival, strict=True):
                ss[aa[ss[aa] > cut]] += gap_ns
            streams[w].counts.clock_faults += 1
            warnings.append(
                f'{streams[w].topic or "torque"}: clock fault: the stamps step back '
                f'{step / 1e9:.6g} s after {(before - int(s[0][arrival[0][0]])) / 1e9:.6g} s '
                f'of log while {others}; the later samples are realigned by continuity and the '
                f'log is segmented there (a {gap_ns / 1e9:g} s gap, so no equation spans the '
                'fault)')
    if restarts:
        every = 'both streams' if len(streams) == 2 else 'every stream'
        warnings.append(f'{restarts} backward clock jump(s) in {every} (restarted or looped '
                        'recording): the later part is placed one second after the earlier '
                        'one and estimated as a separate segment')
    for st, ss in zip(streams, s, strict=True):
        st.stamp = ss
        if any(reordered):
            st.ordinal = ss.copy()
    return restarts
