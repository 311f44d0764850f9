"""Sufficient statistics of the equations: what the fits need, shared by batch and online.

A :class:`SufficientStats` holds the cross Gram matrices of the (segment-demeaned) equation
blocks, the cross Grams of the integrated torque noise, and the counts the covariance model
needs.  The batch estimator builds it from stacked :class:`~.equations.Equations`
(:func:`sufficient_stats`, any segmentation from one shared reduction); the recursive
estimator accumulates the same quantities sample by sample and builds it directly.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._numeric import median
from .equations import Equations, segment_starts
from .regressors import (
    N_REGRESSOR_VARIABLES,
    REGRESSOR_COLUMNS_WIDE,
    VARIABLE_MAP,
    VARIABLE_MAP_WIDE,
    gram,
    lift,
)

__all__ = ['WALK_BASIS', 'SufficientStats', 'range_sums', 'segment_rss', 'shared_raw',
           'sufficient_stats', 'torque_stats', 'window_raw']

_NREG = N_REGRESSOR_VARIABLES


def _regressors(n_var: int) -> slice | np.ndarray:
    """The regressor columns (all but the torque integral) of 13 or 22 variables: a slice
    of the 13 (views, as before the wide layout), the index array of the 22."""
    return slice(0, _NREG) if n_var == 13 else REGRESSOR_COLUMNS_WIDE


def _placed(G: np.ndarray, cols: slice | np.ndarray, n_var: int) -> np.ndarray:
    """``G`` (..., r, r) of the regressor columns ``cols`` placed in zeros (..., n_var,
    n_var) (the torque integral's rows and columns stay 0)."""
    out = np.zeros(G.shape[:-2] + (n_var, n_var))          # (np.pad: 10x the time)
    if isinstance(cols, slice):
        out[..., cols, cols] = G
    else:
        out[..., cols[:, None], cols[None, :]] = G
    return out


@dataclass
class SufficientStats:
    """Sufficient statistics of one segmentation of the equations.

    Attributes
    ----------
    C : ndarray, shape (3, 3, 10, 10)
        Cross Grams ``sum_b A_b[r]' A_b[s]`` of the (segment-demeaned) blocks ((3, 3, 13, 13)
        from the wide variables of a torque fixed in inertial axes, :mod:`.regressors`; so
        are ``CP`` and ``walk_grams``).
    CP : ndarray, shape (3, 3, 10, 10), optional
        Cross Grams of the torque-noise sums (anchored equations with torque noise).
    n : int
        Equations.
    n_eff : int
        Equations minus segment intercepts.
    n_seg : int
        Segments.
    kind : {'anchored', 'hac'}
        Covariance model (see :class:`~.equations.Equations`).
    eiv_var : ndarray, shape (3,), optional
        Gyro-noise variance in the regressor [rad^2/s^2] (bias compensation).
    weighted : bool
        Weighted, bias-compensated fit.
    hac_lag : int
        HAC lag (``kind='hac'``).
    A : ndarray, shape (n, 3, 10), optional
        The blocks themselves, kept for the HAC covariance.
    hac_shapes : ndarray, shape (2, m), optional
        Candidate autocorrelations of the equation error at lags ``0..m-1`` (the ``filtered``
        method's torque-like and gyro-like shapes), for the HAC small-sample correction
        (:func:`.fit.hac_small_sample`).
    walk_time : float
        ``sum`` over segments of ``n_s * duration_s / 6`` [s].
    torque_dt : float
        Median torque sample interval [s].
    omega_m2 : ndarray, shape (3, 3), optional
        ``mean(w w')`` of the gyro samples [rad^2/s^2] (the gyroscopic noise walk).
    gyro_dt : float
        Median gyro sample interval [s].
    white_y_cov : ndarray, shape (3, 3), optional
        White noise in ``y`` besides the gyro's (:attr:`.equations.Equations.white_y_cov`).
    walk_grams : ndarray, shape (Q, 3, 3, 10, 10), optional
        Cross Grams of the torque-noise sums weighted per torque interval by the components
        (:data:`WALK_BASIS`) of a time-varying walk covariance
        (:attr:`.equations.Equations.walk_cov`), Q = 6, then (Q = 15) by the products
        :attr:`.equations.Equations.walk_wh` (:func:`.fit.walk_bases`).
    walk_mean : ndarray, shape (Q,), optional
        Those weights' means over the torque intervals, time-weighted.
    """

    C: np.ndarray
    CP: np.ndarray | None
    n: int
    n_eff: int
    n_seg: int
    kind: str = 'anchored'
    eiv_var: np.ndarray | None = None
    weighted: bool = False
    hac_lag: int = 0
    A: np.ndarray | None = None
    walk_time: float = 0.0
    torque_dt: float = 0.0
    omega_m2: np.ndarray | None = None
    gyro_dt: float = 0.0
    white_y_cov: np.ndarray | None = None
    hac_shapes: np.ndarray | None = None
    walk_grams: np.ndarray | None = None
    walk_mean: np.ndarray | None = None


#: The symmetric basis of a 3 x 3 covariance, (6, 3, 3): ``S = sum_q S[WALK_PAIRS[q]] E_q``
#: (xx, yy, zz, then xy, xz, yz counted once with both off-diagonal entries).
WALK_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
WALK_BASIS = np.array([np.outer(np.eye(3)[a], np.eye(3)[b]) + (
    np.outer(np.eye(3)[b], np.eye(3)[a]) if a != b else 0.0) for a, b in WALK_PAIRS])


def _walk_components(cov: np.ndarray) -> np.ndarray:
    """The :data:`WALK_BASIS` coefficients (M, 6) of covariances ``cov`` (M, 3, 3)."""
    return np.stack([cov[:, a, b] for a, b in WALK_PAIRS], axis=1)


#: Mean rows per range from which :func:`range_sums` sums range by range (BLAS row sums);
#: below it, one ``reduceat`` pass over all ranges.
_ROWS_PER_BLAS_SUM = 256
#: Rows from which the ``reduceat`` pass's transposed copy no longer fits the cache: there the
#: BLAS sums take over from :data:`_LONG_ROWS_PER_BLAS_SUM` rows per range (one BLAS thread,
#: 720 001 x 13 rows in ranges of 250: 8.8 against 44.6 ms; of 128 rows at 100 001 rows: 1.7
#: against 2.0 ms; shorter records keep the threshold above, and their sums bit for bit).
_LONG_ROWS = 131_072
_LONG_ROWS_PER_BLAS_SUM = 128


def range_sums(V: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Sums of the row ranges ``V[bounds[k]:bounds[k+1]]``, shape (len(bounds) - 1, q).

    ``bounds`` is non-decreasing (an empty range sums to 0).  Long ranges (segments, windows)
    are one BLAS product ``ones @ V[a:b]`` each, at memory speed; many short ones one
    ``np.add.reduceat`` over the transposed rows.  numpy only: the ``integral`` path imports
    no scipy (whose base costs an hour-long log's command about 0.1 s of start-up).
    """
    V = np.asarray(V)
    bounds = np.asarray(bounds, dtype=np.intp)
    m = len(bounds) - 1
    out = np.zeros((m,) + V.shape[1:], dtype=np.result_type(V.dtype, float))
    if m <= 0 or len(V) == 0:
        return out
    lengths = np.diff(bounds)
    per = _LONG_ROWS_PER_BLAS_SUM if len(V) >= _LONG_ROWS else _ROWS_PER_BLAS_SUM
    if len(V) >= per * m:
        ones = np.ones(int(lengths.max()))
        for k in np.flatnonzero(lengths > 0).tolist():
            a, b = int(bounds[k]), int(bounds[k + 1])
            np.matmul(ones[:b - a], V[a:b], out=out[k])
        return out
    return _reduceat_rows(V, bounds, lengths, out)


def _reduceat_rows(V: np.ndarray, bounds: np.ndarray, lengths: np.ndarray,
                   out: np.ndarray) -> np.ndarray:
    """:func:`range_sums` of many short ranges: ``np.add.reduceat`` along the contiguous rows
    of ``V.T`` (several times faster than along the columns of the thin ``V``)."""
    nz = lengths > 0
    if not np.any(nz):
        return out
    VT = np.ascontiguousarray(V.reshape(len(V), -1).T)
    sums = np.add.reduceat(VT, bounds[:-1][nz], axis=1)          # (q, ranges with rows)
    out.reshape(len(out), -1)[nz] = sums.T
    return out


#: Equal-count torque intervals in a row from which :func:`_interval_sums` sums them as one
#: reshaped view (no copy); shorter runs are gathered by count.
_MIN_RUN = 32
#: Runs summed as views at most (beyond, the intervals are gathered by count).
_MAX_RUNS = 2000


def _interval_sums(V: np.ndarray, t: np.ndarray, t_tau: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per torque interval ``j``: ``sum V_b`` and ``sum (t_b - s_j) V_b`` over its rows.

    Interval ``j`` holds the rows ``first[j]:first[j + 1]`` (``s_j <= t_b < s_{j+1}``; rows
    before ``s_0`` count in interval 0).  Returns ``(S (M, q), St (M, q), first (M + 1,))``.

    Sampled at steady rates, the intervals hold the same number ``c`` of rows in long runs:
    such a run is the view ``(run, c, q)`` of its rows, summed over its middle axis.  The
    other intervals are gathered into ``(intervals, c, q)`` per count ``c``.
    """
    n, q = V.shape
    m = len(t_tau)
    first = np.searchsorted(t, t_tau, side='left')
    first[0] = 0                                      # (no sample precedes t_tau[0])
    indptr = np.append(first, n)
    counts = np.diff(indptr)
    u = t - np.repeat(t_tau, counts)                  # time since the interval's sample
    S = np.zeros((m, q))
    St = np.zeros((m, q))
    change = np.flatnonzero(np.diff(counts)) + 1
    starts = np.concatenate(([0], change))
    ends = np.append(change, m)
    long = (ends - starts >= _MIN_RUN) & (counts[starts] > 0)
    if np.count_nonzero(long) > _MAX_RUNS:
        long[:] = False
    rest = np.ones(m, dtype=bool)
    for j0, j1 in zip(starts[long].tolist(), ends[long].tolist(), strict=True):
        c = int(counts[j0])
        a, b = int(indptr[j0]), int(indptr[j1])
        Vr = V[a:b].reshape(j1 - j0, c, q)
        np.einsum('mkq->mq', Vr, out=S[j0:j1])            # 4x np.sum over the middle axis
        np.einsum('mk,mkq->mq', u[a:b].reshape(j1 - j0, c), Vr, out=St[j0:j1])
        rest[j0:j1] = False
    rest &= counts > 0
    for c in np.flatnonzero(np.bincount(counts[rest])).tolist():    # the distinct counts
        js = np.flatnonzero(rest & (counts == c))
        rows = indptr[js][:, None] + np.arange(c)                # (intervals, c)
        Vg = V[rows]
        S[js] = np.einsum('mkq->mq', Vg)
        St[js] = np.einsum('mk,mkq->mq', u[rows], Vg)
    return S, St, indptr


#: Torque intervals per block of :func:`_torque_sums` and :func:`_demeaned_torque_gram` (their
#: temporaries stay in cache).
_GRAM_BLOCK = 8192


def _torque_sums(S: np.ndarray, St: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``P_j = h_j sum_{j' > j} S_j' + St_j`` from the interval sums (see :func:`torque_stats`).

    The sums after each interval are accumulated from the last interval backwards, in blocks
    of :data:`_GRAM_BLOCK` intervals (the running sum carried from block to block in the same
    order, so the result is that of one backward cumulative sum), ``P`` written per block.
    """
    m = len(S)
    P = np.empty_like(S)
    carry = np.zeros(S.shape[1:])                  # sum of the intervals after the block
    for b in range(m, 0, -_GRAM_BLOCK):
        a = max(b - _GRAM_BLOCK, 0)
        after = np.empty((b - a,) + S.shape[1:])
        after[-1] = carry
        if b - a > 1:
            tail = S[a + 1:b][::-1].copy()        # S_(b-1) down to S_(a+1)
            tail[0] += carry
            np.cumsum(tail, axis=0, out=after[-2::-1])
            carry = after[0] + S[a]
        else:
            carry = carry + S[a]
        np.multiply(h[a:b, None], after, out=P[a:b])
        P[a:b] += St[a:b]
    return P


def torque_stats(V: np.ndarray, t: np.ndarray, t_tau: np.ndarray,
                  tau_end: float) -> np.ndarray:
    """``P_j = sum_b o_j(b) V_b`` for every torque interval ``j``, shape (M, q).

    Torque sample ``j`` carries white noise ``nu_j`` held over ``[s_j, s_{j+1})``; anchored
    equation ``b`` contains ``-sum_j o_j(b) nu_j`` with ``o_j(b) = clip(t_b - s_j, 0, h_j)``.
    With segment-demeaned variables the constant part of every segment cancels, so one global
    sum serves all segments.
    """
    ends = np.append(t_tau[1:], max(tau_end, t_tau[-1]))
    S, St, _ = _interval_sums(V, t, t_tau)
    return _torque_sums(S, St, ends - t_tau)


def shared_raw(eq: Equations, t_tau: np.ndarray, tau_end: float,
         torque_var: np.ndarray) -> dict[str, Any]:
    """Statistics of the (globally centred) variables that every segmentation shares."""
    if eq.raw is not None:
        return eq.raw
    # a constant shift cancels in segment demeaning (the mean as a BLAS product: 2x np.mean);
    # a view of an already centred set (the adequacy windows) keeps its parent's
    if not eq.centred:
        eq.V -= (np.ones(len(eq.V)) @ eq.V / len(eq.V))[None]
        eq.centred = True
    walk = (np.any(torque_var > 0) or eq.walk_cov is not None) and len(t_tau) > 1
    # (two threads overlapping the Gram and the torque sums no longer pay: with the sparse
    # interval sums a 1M-sample record is faster on one thread, measured 0.51 s against 0.65 s)
    raw: dict[str, Any] = {'G': gram(eq.V)}
    if walk:
        # the interval sums stay for the windows of the same rows (:func:`window_raw`)
        raw['interval_sums'] = _interval_sums(eq.V[:, _regressors(eq.V.shape[1])], eq.t,
                                              t_tau)
    _finish_raw(raw, eq.t, t_tau, tau_end, raw['interval_sums'][:2] if walk else None)
    if walk and eq.walk_cov is not None:    # on a prefix of the torque samples it was made on
        raw['walk'] = _walk_components(eq.walk_cov[:len(t_tau)])
        if eq.walk_wh is not None:
            raw['walk'] = np.hstack([raw['walk'], eq.walk_wh[:len(t_tau)]])
    eq.raw = raw
    return raw


def _finish_raw(raw: dict[str, Any], t: np.ndarray, t_tau: np.ndarray, tau_end: float,
                sums: tuple[np.ndarray, np.ndarray] | None) -> None:
    """The time prefix sums and, given the interval sums ``(S, St)`` (:func:`_interval_sums`),
    the torque-noise sums ``P`` and the intervals' bounds in equation rows."""
    raw['CT'] = np.concatenate([[0.0], np.cumsum(t)])
    if sums is not None:
        ends = np.append(t_tau[1:], max(tau_end, t_tau[-1]))
        h = ends - t_tau
        raw.update(P=_torque_sums(*sums, h), s=t_tau, h=h,
                   k0=np.searchsorted(t, t_tau, side='right'),
                   k1=np.searchsorted(t, ends, side='left'))


def window_raw(eq: Equations, a: int, b: int, t_tau: np.ndarray,
               torque_var: np.ndarray) -> tuple[Equations, np.ndarray]:
    """The equations ``a:b`` of ``eq`` with their shared statistics, from ``eq``'s own.

    ``eq``'s statistics (:func:`shared_raw`) are made first when it has none.  The window
    is its own record: the torque samples from the last one at or before its first equation
    to the last one at or before its last, the final interval ending at its last equation
    (as :func:`shared_raw` would treat the rows alone).  Its Gram is one BLAS product on a
    view of the centred rows; its torque-noise sums reuse ``eq``'s per-interval sums, only
    the (at most two) intervals the window's ends cut are summed again from their rows.

    Returns
    -------
    (Equations, numpy.ndarray)
        The window (a view, statistics cached) and its torque samples' index range
        ``[j0, j1)`` into ``t_tau`` as a 2-array.
    """
    raw = eq.raw if eq.raw is not None else shared_raw(eq, t_tau, float(eq.t[-1]), torque_var)
    if 'interval_sums' in raw and not (raw['s'] is t_tau or np.array_equal(raw['s'], t_tau)):
        raise ValueError('window_raw: the parent statistics were built on other torque samples')
    sub = eq.rows(a, b, view=True)
    j0 = max(int(np.searchsorted(t_tau, sub.t[0], side='right')) - 1, 0)
    j1 = int(np.searchsorted(t_tau, sub.t[-1], side='right'))
    tsk = t_tau[j0:j1]
    wr: dict[str, Any] = {'G': gram(sub.V)}
    sums = None
    if 'interval_sums' in raw and j1 - j0 >= 2:
        S, St, first = raw['interval_sums']
        S, St = S[j0:j1].copy(), St[j0:j1].copy()
        for k in {0, j1 - j0 - 1}:                  # the intervals the window's ends may cut
            j = j0 + k
            lo, hi = max(int(first[j]), a), min(int(first[j + 1]), b)
            if (lo, hi) != (int(first[j]), int(first[j + 1])):
                rows = eq.V[lo:hi][:, _regressors(eq.V.shape[1])]
                S[k] = rows.sum(axis=0)
                St[k] = (eq.t[lo:hi] - t_tau[j]) @ rows
        sums = S, St
    _finish_raw(wr, sub.t, tsk, float(sub.t[-1]), sums)
    if 'walk' in raw and sums is not None:
        wr['walk'] = raw['walk'][j0:j1]
    sub.raw = wr
    return sub, np.array([j0, j1])


def _demeaned_torque_gram(raw: dict[str, Any], starts: np.ndarray, m: np.ndarray,
                          Sp: np.ndarray, MTp: np.ndarray, CT: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray | None]:
    """Gram (r, r) of the torque-noise sums ``P`` of the segment-demeaned regressor variables
    (r = 10, or 19 wide), and (with ``raw['walk']``, (M, 6)) the six Grams (6, r, r) weighted
    per interval by it.

    Demeaning variable ``b`` by its segment's mean ``m_seg(b)`` changes ``P_j`` by
    ``h_j sum_{b >= k1_j} m + sum_{k0_j <= b < k1_j} (t_b - s_j) m`` (prefix sums over the
    segments, ``Sp`` of the sums and ``MTp`` of the time-weighted means).  Evaluated in
    blocks of :data:`_GRAM_BLOCK` intervals whose Grams add up: an hour-long record's 180 000
    intervals pass through the cache once instead of a dozen times.
    """
    P, k0_all, k1_all, h_all, s_all = raw['P'], raw['k0'], raw['k1'], raw['h'], raw['s']
    total = Sp[-1][None]

    def ZQ(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``sum_{b<k} m_seg(b)`` and ``sum_{b<k} t_b m_seg(b)`` (one segment search)."""
        sk = np.searchsorted(starts, k, side='right') - 1
        mk = m.take(sk, axis=0)               # take and in-place sums: 30 % less than [sk]
        st = starts.take(sk)
        z = (k - st)[:, None] * mk
        z += Sp.take(sk, axis=0)
        q = (CT.take(k) - CT.take(st))[:, None] * mk
        q += MTp.take(sk, axis=0)
        return z, q

    nr = P.shape[1]                                   # regressor variables (10 or 19)
    G = np.zeros((nr, nr))
    walk = raw.get('walk')
    Gw = None if walk is None else np.zeros((walk.shape[1], nr, nr))
    for a in range(0, len(P), _GRAM_BLOCK):
        b = min(a + _GRAM_BLOCK, len(P))
        k0, k1 = k0_all[a:b], k1_all[a:b]
        if np.array_equal(k1[:-1], k0_all[a + 1:b]):
            # an interval ends where the next begins (no gyro sample on a torque stamp): one
            # evaluation serves both ends
            z, q = ZQ(np.append(k0, k1[-1]))
            z0, q0, z1, q1 = z[:-1], q[:-1], z[1:], q[1:]
        else:                         # both ends in one evaluation (the same numbers)
            z, q = ZQ(np.concatenate((k0, k1)))
            z0, q0, z1, q1 = z[:b - a], q[:b - a], z[b - a:], q[b - a:]
        X = P[a:b] - h_all[a:b, None] * (total - z1)
        X -= q1 - q0
        X += s_all[a:b, None] * (z1 - z0)
        G += gram(X)
        if Gw is not None:
            for q in range(len(Gw)):       # (one (n, 60) product: 10-50x slower, threads)
                Gw[q] += X.T @ (walk[a:b, q, None] * X)
    return G, Gw


def sufficient_stats(eq: Equations, segment: float | None, t_tau: np.ndarray, tau_end: float,
           torque_var: np.ndarray) -> SufficientStats:
    """Reduce the equations of one segmentation to cross Gram matrices.

    Anchored methods: the per-segment demeaning is applied to shared raw statistics
    (``C - sum_s n_s m_s' m_s``; the torque-noise sums corrected with prefix sums of the
    segment means), so trying several segment lengths costs O(segments + torque samples).
    """
    n = len(eq.t)
    if eq.kind != 'anchored':
        return SufficientStats(lift(gram(eq.V)), None, n, n, 0, eq.kind, eq.eiv_var, eq.weighted,
                               eq.hac_lag, eq.A, hac_shapes=eq.info.get('hac_error_shapes'))
    raw = shared_raw(eq, t_tau, tau_end, torque_var)
    starts = segment_starts(eq.t, eq.breaks, segment)
    bounds = np.append(starts, n)
    ns = np.diff(bounds).astype(float)
    S = range_sums(eq.V, bounds)                             # (nseg, 13) segment sums
    m = S / ns[:, None]
    C = lift(raw['G'] - np.einsum('s,si,sj->ij', ns, m, m))
    CP = walk_grams = walk_mean = None
    if 'P' in raw:
        CT = raw['CT']
        nv = eq.V.shape[1]
        cols = _regressors(nv)
        S, m = S[:, cols], m[:, cols]                         # regressor variables only
        Sp = np.vstack([np.zeros(S.shape[1]), np.cumsum(S, axis=0)])
        TS = CT[bounds[1:]] - CT[starts]
        MTp = np.vstack([np.zeros(S.shape[1]), np.cumsum(m * TS[:, None], axis=0)])
        GPr, Gw = _demeaned_torque_gram(raw, starts, m, Sp, MTp, CT)
        CP = lift(_placed(GPr, cols, nv))
        if Gw is not None:
            walk_grams = np.array([lift(g) for g in _placed(Gw, cols, nv)])
            walk_mean = raw['h'] @ raw['walk'] / float(np.sum(raw['h']))
    dur = eq.t[bounds[1:] - 1] - eq.t[starts]
    if 'torque_dt' not in raw:              # the same for every segmentation: once
        raw['torque_dt'] = median(np.diff(t_tau)) if len(t_tau) > 1 else 0.0
    tdt = raw['torque_dt']
    m2, gdt = eq.motion if eq.motion is not None else (None, 0.0)
    return SufficientStats(C, CP, n, n - len(starts), len(starts), eq.kind, eq.eiv_var,
                           eq.weighted, eq.hac_lag, None, walk_time=float(np.sum(ns * dur)) / 6.0,
                           torque_dt=tdt, omega_m2=m2, gyro_dt=gdt, white_y_cov=eq.white_y_cov,
                           walk_grams=walk_grams, walk_mean=walk_mean)


def segment_rss(V: np.ndarray, starts: np.ndarray, c: np.ndarray, W: np.ndarray) -> np.ndarray:
    """``sum_b (e_b - mean_s e)' W (e_b - mean_s e)`` per segment, shape (len(starts),).

    ``e_b = A_b c`` (3,) is the residual of equation ``b`` (its 13 variables ``V`` (n, 13)
    through :data:`.regressors.VARIABLE_MAP`, ``c`` (10,) the coefficients ``[-psi, -d, 1]``;
    or the 22 of :data:`.regressors.VARIABLE_MAP_WIDE`, ``c`` (13,) ``[-psi, -d, 1, -d_i]``),
    ``W`` (3, 3) the weight; segment ``s`` holds the rows ``starts[s]:starts[s + 1]`` (the last
    to the end; ``starts[0] = 0``, increasing) and loses its mean (its initial momentum).  The
    same sums as ``c' sum_b A_b' W A_b c`` of the segment-demeaned blocks' Gram, without a
    Gram per segment (and without its cancellation).
    """
    E = VARIABLE_MAP if V.shape[1] == 13 else VARIABLE_MAP_WIDE
    R = np.ascontiguousarray(np.tensordot(E, c, axes=([2], [0])))       # (13 or 22, 3)
    n = len(V)
    e = np.empty((n, 3))
    # thin products in blocks: one (100 000, 13) x (13, 3) product wakes the BLAS threads,
    # which on a loaded machine cost 10-100 ms of waiting where the work takes 0.5 ms
    for a in range(0, n, _THIN_BLOCK):
        np.matmul(V[a:a + _THIN_BLOCK], R, out=e[a:a + _THIN_BLOCK])
    counts = np.diff(np.append(starts, n))
    e -= np.repeat(np.add.reduceat(e, starts, axis=0) / counts[:, None], counts, axis=0)
    eW = np.empty((n, 3))
    for a in range(0, n, _THIN_BLOCK):
        np.matmul(e[a:a + _THIN_BLOCK], W, out=eW[a:a + _THIN_BLOCK])
    q = np.einsum('bi,bi->b', eW, e)                # (a 3-operand einsum: 5x the time)
    return np.add.reduceat(q, starts)


#: Rows per product of :func:`segment_rss` (small enough for the BLAS to stay on one thread).
_THIN_BLOCK = 4096
