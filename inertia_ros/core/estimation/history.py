"""The online estimator's closed segments, kept apart so the adequacy test can compare them.

:class:`~.recursive.RecursiveEstimator` folds every closed anchored segment into running sums.
For the window-consistency test of :mod:`.adequacy` it also keeps each segment's statistics
here (at most :data:`MAX_SEGMENTS`; the oldest neighbours are merged beyond that), stamped with
the estimator's *decay clock* ``L`` (the running sum of ``log`` of every decay factor applied
since the start).  A segment stored at clock ``L_s`` is worth ``exp(L - L_s)`` of its weight
now, its squared-weight sums ``exp(2 (L - L_s))``: the same decay the running sums got.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ['MAX_SEGMENTS', 'SegmentHistory', 'SegmentStats', 'segment_pieces']

#: Closed segments kept apart (older ones are merged in pairs beyond this).
MAX_SEGMENTS = 32


@dataclass(frozen=True)
class SegmentStats:
    """Weighted statistics of one anchored segment (or a run of merged ones).

    Attributes
    ----------
    C, GP : ndarray, shape (13, 13)
        Centred weighted Gram of the 13 variables and the torque-noise Gram.
    walk : float
        ``n * duration / 6`` of the segment [s] (weighted).
    w0, w00, neff : float
        Sum of weights, of squared weights, and effective equations.
    t0, t1 : float
        First and last equation time [s].
    clock : float
        Decay clock when these sums were current.
    """

    C: np.ndarray
    GP: np.ndarray
    walk: float
    w0: float
    w00: float
    neff: float
    t0: float
    t1: float
    clock: float = 0.0

    def at(self, clock: float) -> SegmentStats:
        """The statistics decayed to ``clock`` (>= their own)."""
        f = math.exp(max(clock - self.clock, -700.0))
        return SegmentStats(self.C * f, self.GP * f * f, self.walk * f, self.w0 * f,
                            self.w00 * f * f, self.neff * f, self.t0, self.t1, clock)

    def __add__(self, other: SegmentStats) -> SegmentStats:
        """Two runs at the same clock, ``self`` the earlier: one run."""
        return SegmentStats(self.C + other.C, self.GP + other.GP, self.walk + other.walk,
                            self.w0 + other.w0, self.w00 + other.w00, self.neff + other.neff,
                            self.t0, other.t1, other.clock)


class SegmentHistory:
    """Bounded list of closed segments in time order."""

    def __init__(self) -> None:
        self._segs: list[SegmentStats] = []

    def add(self, seg: SegmentStats) -> None:
        """Append a closed segment; merge the oldest pair beyond :data:`MAX_SEGMENTS`."""
        self._segs.append(seg)
        if len(self._segs) > MAX_SEGMENTS:
            a, b = self._segs[0], self._segs[1]
            self._segs[:2] = [a.at(b.clock) + b]

    def groups(self, k: int, open_seg: SegmentStats | None = None, clock: float = 0.0,
               min_share: float = 0.05) -> list[SegmentStats]:
        """Up to ``k`` consecutive groups of (about) equal numbers of segments.

        Segments whose weight, decayed to ``clock``, is below ``min_share`` of the largest are
        forgotten (the estimate no longer rests on them).  Each group is summed at the clock
        of its last segment: the decay *within* a group is kept, the decay since then is not
        (a group's estimate and covariance do not depend on a common factor).
        """
        segs = list(self._segs)
        if open_seg is not None and open_seg.w0 > 0:
            segs.append(open_seg)
        if not segs:
            return []
        now = [s.at(clock).w0 for s in segs]
        segs = [s for s, w in zip(segs, now, strict=True) if w >= min_share * max(now)]
        k = min(k, len(segs))
        edges = np.linspace(0, len(segs), k + 1).round().astype(int)
        out = []
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            g = segs[a]
            for s in segs[a + 1:b]:
                g = g.at(s.clock) + s
            out.append(g)
        return out


def segment_pieces(t: np.ndarray, start: float, segment: float
                   ) -> list[tuple[int, int, bool]]:
    """Cut rows at times ``t`` (n,) [s] into anchored segments of ``segment`` [s], the open
    one started at ``start`` [s]: a segment ends before the first row at or after its start
    plus ``segment``, and the next starts at that row.

    Returns
    -------
    list of (int, int, bool)
        ``(lo, hi, closes)``: rows ``lo:hi`` join the open segment (none when ``lo == hi``),
        then, when ``closes``, it ends and the next starts at ``t[hi]``.  The one splitter of
        :meth:`.accumulator.OnlineStats.merge` and :class:`.online_shift.ShiftRows`.
    """
    out: list[tuple[int, int, bool]] = []
    lo, n = 0, len(t)
    while lo < n:
        k = lo + int(np.searchsorted(t[lo:], start + segment, side='left'))
        out.append((lo, k, k < n))
        if k < n:
            start = float(t[k])
        lo = k
    return out
