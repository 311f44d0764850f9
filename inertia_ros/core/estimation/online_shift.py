"""The online torque-free segment shift: :class:`ShiftRows` and :func:`online_shift`.

The batch torque-free fit tests its tensor against a refit on anchored segments
:data:`.homogeneous.SHIFT_FACTOR` (8) x shorter, the difference against its exact covariance
``C_ll + C_ss - C_ls - C_sl`` (:func:`.homogeneous._shift`): the cross sandwich of the two
segmentations of the same equations, white gyro noise and gyroscopic walk.  The recursive
estimator keeps no rows, so it had only its accumulator's 4x shorter segmentation and the
bound ``C_ss`` (which at 8x cries wolf: 5 false alarms in 40 conforming 20 s tumbles), and
missed a 0.002 rad/s gyro bias (5 of 10 20 s tumbles ``scale_unobservable`` at |z| > 5).

:class:`ShiftRows` gives it the batch's test exactly.  The short segments are cut inside
each long one (the accumulator's own segmentation, mirrored), so a long segment's rows are
all its two segmentations need: they are kept while it is open (at most one segment, 10 s
by default) and, when it closes, folded into the cross Gram (86, 86) of both
segmentations' :func:`.homogeneous._walk_rows` (the segment-demeaned variables and the
walk's rows).  Every Gram the test needs is a block of it: the two fits' statistics and the
four cross Grams of :func:`.homogeneous._pair_meat`, so the estimate costs one Gram of the
open segment's rows, whatever the record's length.  The gyro-noise correction and a gyro
scale are linear in the variables (:func:`_read_map`), applied to the Gram at read time.

With forgetting (``window`` or ``forgetting < 1``) the weights of the two fits' sandwiches
are not kept here: the bound on the accumulator's 4x segmentation is used (:func:`_bound`).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .adequacy import segment_shift
from .history import segment_pieces
from .homogeneous import (
    SHIFT_FACTOR,
    OnlineTorqueFreeChecks,
    PairGrams,
    _fit_ratios,
    _shift_covariance,
    _walk_rows,
    _without_torque,
)
from .options import MIN_EQUATIONS
from .regressors import N_REGRESSOR_VARIABLES, lift
from .statistics import SufficientStats

__all__ = ['MAX_OPEN_ROWS', 'ShiftRows', 'online_checks', 'online_shift']

#: Rows an open segment may keep (memory: 13 floats each); a longer segment gives way to the
#: bound of :func:`_bound` for the rest of the run.
MAX_OPEN_ROWS = 200_000
#: Rows :meth:`ShiftRows.merge` queues before it cuts them into segments.
_MAX_QUEUED = 4096
_NX, _NR = 13, 3 * N_REGRESSOR_VARIABLES       # a segmentation's columns: [X | R]
_NZ = _NX + _NR

#: ``shift(gyro_var, W, gyro_scale_std, step)``: :attr:`.OnlineTorqueFreeChecks.shift`.
Shift = Callable[[np.ndarray, np.ndarray, float, float], tuple[float, int, float, float] | None]


class ShiftRows:
    """The cross Gram of the equations' two segmentations, long and :data:`SHIFT_FACTOR` x
    shorter, merged block by block (unit weights).

    Parameters
    ----------
    segment : float
        The accumulator's anchored segment length [s] (the long segmentation).
    keep : bool
        Keep the rows (False: forgetting, where :func:`online_shift` uses the bound).

    Attributes
    ----------
    M : ndarray, shape (86, 86)
        Gram of ``[X_l, R_l, X_s, R_s]`` (:func:`.homogeneous._walk_rows` of each
        segmentation) over the closed long segments, raw variables.
    n, n_long, n_short : int
        Their equations and segments of each segmentation.
    """

    def __init__(self, segment: float, keep: bool = True) -> None:
        self.segment = float(segment)
        self.keep = bool(keep)
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.M = np.zeros((2 * _NZ, 2 * _NZ))
        self.n = self.n_long = self.n_short = 0
        self.exact = self.keep
        self.seg_start: float | None = None
        self._t: list[np.ndarray] = []
        self._V: list[np.ndarray] = []
        self._n_open = 0
        self._queue: list[tuple[np.ndarray, np.ndarray, list[int]]] = []   # blocks not cut yet
        self._queued = 0

    def merge(self, t: np.ndarray, V: np.ndarray, breaks: list[int]) -> None:
        """Add equations ``V`` (n, >= 13) at ``t`` (n,) [s]; a new segment at each index of
        ``breaks`` (the gaps the recursive estimator closes its accumulators at).  Queued, cut
        into segments when read or when :data:`_MAX_QUEUED` rows wait (the same rows and
        segments, so the same Grams, bit for bit)."""
        if not self.exact:
            return
        self._queue.append((t, V[:, :_NX], breaks))
        self._queued += len(t)
        if self._queued > _MAX_QUEUED:
            self.flush()

    def flush(self) -> None:
        """Cut the queued blocks into segments (:meth:`_merge`), a run of blocks at a time."""
        queue, self._queue, self._queued = self._queue, [], 0
        run: list[tuple[np.ndarray, np.ndarray]] = []
        for t, V, breaks in [*queue, (None, None, [])]:
            lo = 0
            for k in breaks:
                run.append((t[lo:k], V[lo:k]))
                self._merge_run(run)
                run = []
                self.close(float(t[k]))
                lo = k
            if t is None:
                self._merge_run(run)
            else:
                run.append((t[lo:], V[lo:]))

    def _merge_run(self, run: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """:meth:`_merge` of consecutive blocks ``(t, V)`` as one."""
        if run:
            self._merge(np.concatenate([r[0] for r in run]), np.concatenate([r[1] for r in run]))

    def _merge(self, t: np.ndarray, V: np.ndarray) -> None:
        """As :meth:`.accumulator.OnlineStats.merge` (:func:`.history.segment_pieces`)."""
        if not len(t) or not self.exact:
            return
        if self.seg_start is None:
            self.seg_start = float(t[0])
        for lo, hi, closes in segment_pieces(t, self.seg_start, self.segment):
            if hi > lo:
                self._t.append(t[lo:hi])
                self._V.append(V[lo:hi])
                self._n_open += hi - lo
            if closes:
                self.close(float(t[hi]))
        if self._n_open > MAX_OPEN_ROWS:
            self.exact = False
            self._t, self._V = [], []

    def close(self, new_start: float) -> None:
        """End the open long segment (fold its rows into :attr:`M`); the next starts at
        ``new_start`` [s]."""
        if self._n_open and self.exact:
            Z, n_short = self._open_rows()
            self.M += Z.T @ Z
            self.n += len(Z)
            self.n_long += 1
            self.n_short += n_short
        self._t, self._V, self._n_open = [], [], 0
        self.seg_start = new_start

    def _open_rows(self) -> tuple[np.ndarray, int]:
        """The open segment's rows ``[X_l, R_l, X_s, R_s]`` (n, 86) and its short segments:
        cut every ``segment / SHIFT_FACTOR`` from its first equation (nested in it)."""
        t = np.concatenate(self._t)
        V = np.concatenate(self._V)
        edges = t[0] + self.segment / SHIFT_FACTOR * np.arange(int(np.ceil(SHIFT_FACTOR)))
        starts = np.unique(np.searchsorted(t, edges, side='left'))
        starts = starts[starts < len(t)]
        w = V[:, :3]
        long_rows = _walk_rows(V, t, w, np.zeros(1, dtype=int))
        short_rows = _walk_rows(V, t, w, starts)
        return np.hstack([*long_rows, *short_rows]), len(starts)

    def gram(self) -> tuple[np.ndarray, int, int, int]:
        """Raw Gram (86, 86) of everything merged (the open segment included), equations and
        segments of the long and the short segmentation."""
        self.flush()
        if not self._n_open:
            return self.M, self.n, self.n_long, self.n_short
        Z, n_short = self._open_rows()
        return self.M + Z.T @ Z, self.n + len(Z), self.n_long + 1, self.n_short + n_short


def online_checks(est: Any, nv: np.ndarray, n_eff: float, st: SufficientStats
                  ) -> OnlineTorqueFreeChecks:
    """The torque-free checks of the recursive estimator ``est``
    (:class:`.recursive.RecursiveEstimator`) on its statistics: ``nv`` (3,) the gyro noise
    variance [rad^2/s^2], ``n_eff`` the effective equations, ``st`` the estimate's
    statistics; its segment shift by :func:`online_shift` of its ``_shift_rows``."""
    ctx = est._context()
    return OnlineTorqueFreeChecks(
        lambda g: est._stats(nv, n_eff, g),
        lambda g: est._acc.group_stats(nv, gyro_scale=g, **ctx),
        est.policy.gyro_scale_std, est.policy.torque_scale_std, est._tf_memo,
        (est._schedule.estimates - 1) % est.reselect_every == 0,
        online_shift(est._acc, est._shift_rows, nv, ctx, st.CP is not None))


def online_shift(acc: Any, rows: ShiftRows, nv: np.ndarray, context: dict[str, Any],
                 walk_noise: bool) -> Shift | None:
    """:attr:`.homogeneous.OnlineTorqueFreeChecks.shift` of the recursive estimator.

    Parameters
    ----------
    acc : OnlineStats
        The accumulator of the estimate (``None`` is returned without its 4x ``short``: the
        stated inputs' rows, whose errors are correlated, get no segment shift).
    rows : ShiftRows
        The same equations' rows (:func:`_exact` when it kept them all, else
        :func:`_bound`).
    nv : ndarray, shape (3,)
        Gyro noise variance [rad^2/s^2].
    context : dict
        The noise model's stream figures (``torque_dt``, ``gyro_dt``, ``white_y_cov``).
    walk_noise : bool
        The estimate's statistics carry a torque-noise Gram (the bound's fits, as it).
    """
    if acc.short is None:
        return None
    rows.flush()
    if rows.exact:
        return lambda gv, W, gss, step: _exact(rows, gv, W, gss, step,
                                               context['white_y_cov'])

    def pair(g: float) -> list[tuple[SufficientStats, float]]:
        return [(a.stats(nv, a.n_eff(), walk_noise, gyro_scale=g, **context),
                 (a.w00 + a.w00c) / (a.w0 + a.wc)) for a in (acc, acc.short)]
    return lambda gv, W, gss, step: _bound(pair, gv, W, gss, step)


def _read_map(nv: np.ndarray, gyro_scale: float) -> np.ndarray:
    """The map (13, 13) of the raw variables ``[w, m, t, T]`` to the corrected ones
    (``m_c - sigma_c^2 t``, ``nv`` (3,) [rad^2/s^2]) of a gyro read ``gyro_scale`` times
    larger (``w`` and ``m`` scale), as the accumulator's read-back."""
    K = np.eye(_NX)
    K[9, 3:6] = -nv
    if gyro_scale != 1.0:
        K = np.diag(np.r_[np.full(3, gyro_scale), np.full(6, gyro_scale ** 2),
                          np.ones(4)]) @ K
    return K


def _exact(rows: ShiftRows, gyro_var: np.ndarray, W: np.ndarray, gyro_scale_std: float,
           step: float, white_y_cov: np.ndarray | None
           ) -> tuple[float, int, float, float] | None:
    """The batch's test (:func:`.homogeneous._shift`) on :class:`ShiftRows`: both fits with
    ``W`` on the blocks of the Gram, the difference against its exact covariance
    (:func:`.homogeneous._shift_covariance`), a stated gyro scale's share added."""
    M, n, n_long, n_short = rows.gram()
    if n == 0:
        return None
    K = _read_map(gyro_var, 1.0)
    Q = np.zeros((2 * _NZ, 2 * _NZ))
    nr = N_REGRESSOR_VARIABLES
    for o in (0, _NZ):
        Q[o:o + _NX, o:o + _NX] = K
        for i in range(3):
            a = o + _NX + i * nr
            Q[a:a + nr, a:a + nr] = K[:nr, :nr]
    Mr = Q.T @ M @ Q
    segs = (n_long, n_short)

    def fit(a: int, g: float) -> tuple[Any, np.ndarray] | None:
        Kg = _read_map(gyro_var, g)
        o = a * _NZ
        G = Kg.T @ M[o:o + _NX, o:o + _NX] @ Kg
        st = SufficientStats(lift(G), None, n, n - segs[a], segs[a], kind='anchored',
                             eiv_var=gyro_var, weighted=True, white_y_cov=white_y_cov)
        st = _without_torque(st)
        if st.n_eff < MIN_EQUATIONS:
            return None
        fk, _, th = _fit_ratios(st, gyro_var, W)
        return (fk, th) if 0.0 < fk.excess < np.inf else None

    fits = [fit(0, 1.0), fit(1, 1.0)]
    if fits[0] is None or fits[1] is None:
        return None

    def grams(a: int, b: int) -> PairGrams:
        x, y = a * _NZ, b * _NZ
        X, Y, R, S = slice(x, x + _NX), slice(y, y + _NX), slice(x + _NX, x + _NZ), \
            slice(y + _NX, y + _NZ)
        return Mr[X, Y], Mr[R, S], Mr[X, S], Mr[R, Y]

    cov_long, cov_short, cov_diff = _shift_covariance(
        [(f[0], f[1], white_y_cov) for f in fits], grams, W, gyro_var)   # type: ignore[index]
    if gyro_scale_std:
        scaled = [fit(0, 1.0 + step), fit(1, 1.0 + step)]
        if scaled[0] is not None and scaled[1] is not None:
            sens = [(s[0].beta - f[0].beta) / step
                    for s, f in zip(scaled, fits, strict=True)]   # type: ignore[index]
            dg = np.outer(*2 * [gyro_scale_std * (sens[1] - sens[0])])
            cov_short, cov_diff = cov_short + dg, cov_diff + dg
    return segment_shift(fits[0][0].beta, cov_long, fits[1][0].beta, cov_short, cov_diff)


def _bound(pair: Callable[[float], list[tuple[SufficientStats, float]]],
           gyro_var: np.ndarray, W: np.ndarray, gyro_scale_std: float,
           step: float = 1e-4) -> tuple[float, int, float, float] | None:
    """The segment shift on the accumulator's statistics (as the torque paths'): the ratios
    refitted with ``W`` on the merged equations and on their 4x shorter segments
    (``pair(g)``, the gyro read ``g`` times larger, with each one's covariance factor
    ``w00 / w0``), a stated gyro scale's share added, the shorter fit's covariance as the
    bound of :func:`.adequacy.segment_shift` (no rows for the exact covariance)."""
    def betas(g: float) -> list[tuple[np.ndarray, np.ndarray]] | None:
        out = []
        for st, factor in pair(g):
            st = _without_torque(st)
            if st.n_eff < MIN_EQUATIONS:
                return None
            fk, _, _ = _fit_ratios(st, gyro_var, W)
            if not 0.0 < fk.excess < np.inf:
                return None
            out.append((fk.beta, fk.cov * factor / max(fk.excess, 1.0)))
        return out

    fits = betas(1.0)
    if fits is None:
        return None
    cov_short = fits[1][1]
    scaled = betas(1.0 + step) if gyro_scale_std else None
    if scaled is not None:
        dg = gyro_scale_std * ((scaled[1][0] - fits[1][0]) - (scaled[0][0] - fits[0][0])) / step
        cov_short = cov_short + np.outer(dg, dg)
    return segment_shift(fits[0][0], fits[0][1], fits[1][0], cov_short)
