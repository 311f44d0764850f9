"""A momentum input's time-varying torque-noise walk in the online statistics (issue 27).

The batch weights the Gram of the demeaned torque-noise sums per torque interval by the
covariance of the ``w x h`` integral's white noise there (:func:`.momentum.walk_cov` held
over the interval by :func:`.momentum.interval_walk`; :attr:`.statistics.SufficientStats.
walk_grams`, :func:`.fit.walk_bases`).  Online, that covariance's noise levels (the gyro's,
the momentum's, the gyro samples sharing a momentum sample) are estimates that change as the
data arrive, while the intervals are merged once.  The covariance is linear in them, so each
interval carries the covariance of each unit noise level, its :data:`FEATURES` weights
(:func:`interval_features`, from the batch's functions on the grid), and the accumulator sums
a Gram per weight (:class:`WalkSums`); an estimate combines them with the current levels
(:func:`walk_model`) into the batch's fifteen, less the record-mean diagonal the torque noise
variance already holds (the batch's ``walk_cov`` is the same deviation).

The tracker (:class:`.recursive_momentum.MomentumTrackingEstimator`) carries the same walk in
its Kalman filter's process noise: each block's momentum walk from the mean weights of its
intervals (:meth:`FeatureStore.mean`) read at the current levels (:func:`walk_deviation`).
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .momentum import interval_walk, walk_cov
from .statistics import WALK_BASIS, WALK_PAIRS

__all__ = ['FEATURES', 'FeatureStore', 'WalkSums', 'interval_features', 'walk_deviation',
           'walk_model']

_NC = len(WALK_PAIRS)                     # 6 covariance components
_ROWS, _COLS = np.array(WALK_PAIRS).T
#: Weights per torque interval: the covariance components (6) of the gyro's walk ``n x h``
#: for a unit variance of each gyro axis (3), of the momentum's ``w x e`` for each unit
#: component of its covariance (6), then the products ``w_i h_c`` (9, the cross term).
FEATURES = 3 * _NC + _NC * _NC + 9


def interval_features(grid: np.ndarray, hg: np.ndarray, wg: np.ndarray) -> np.ndarray:
    """The :data:`FEATURES` weights (G - 1, F) of the grid intervals ``grid`` (G,) [s] from
    the momentum ``hg`` [N m s] and rate ``wg`` [rad/s] (G, 3) at the grid times."""
    g, nb = len(grid), 3 + _NC
    # one call on the grid repeated for each unit level (the levels broadcast per row)
    gv = np.zeros((nb, g, 1, 3))
    gv[np.arange(3), :, 0, np.arange(3)] = 1.0
    hc = np.zeros((nb, g, 3, 3))
    hc[3:] = WALK_BASIS[:, None]
    covs = walk_cov(np.tile(hg, (nb, 1)), np.tile(wg, (nb, 1)), gv.reshape(-1, 1, 3),
                    hc.reshape(-1, 3, 3), 1.0).reshape(nb, g, 3, 3)
    at = np.empty((g, FEATURES))
    at[:, :nb * _NC] = covs[:, :, _ROWS, _COLS].transpose(1, 0, 2).reshape(g, -1)
    at[:, nb * _NC:] = (wg[:, :, None] * hg[:, None, :]).reshape(g, 9)
    return interval_walk(grid, at, grid)[:-1]


def walk_model(gyro_var: np.ndarray, h_cov: np.ndarray, share: float,
               mean: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The map (F, 15) from the :data:`FEATURES` weights to the batch's fifteen walk weights
    (:func:`.fit.walk_bases`) at the noise levels ``gyro_var`` (3,) [rad^2/s^2], ``h_cov``
    (3, 3) [N^2 m^2 s^2] shared by ``share`` gyro samples, and the weights' offset (15,):
    the record-mean diagonal ``mean`` (3,) [N^2 m^2] (in the torque noise variance)."""
    M = np.zeros((FEATURES, _NC + 9))
    for k in range(3):
        M[k * _NC:(k + 1) * _NC, :_NC] = gyro_var[k] * np.eye(_NC)
    for q, (a, b) in enumerate(WALK_PAIRS):
        r = 3 * _NC + q * _NC
        M[r:r + _NC, :_NC] = share * h_cov[a, b] * np.eye(_NC)
    M[3 * _NC + _NC * _NC:, _NC:] = np.eye(9)
    return M, np.concatenate([mean, np.zeros(_NC - 3 + 9)])


def walk_deviation(f: np.ndarray, model: tuple[np.ndarray, np.ndarray],
                   bases: np.ndarray) -> np.ndarray:
    """The walk's covariance (3, 3) [N^2 m^2] of the weights ``f`` (F,) (an interval's, or
    their mean over a block) at the levels of ``model`` (:func:`walk_model`), less its
    offset (the record-mean diagonal the torque noise variance holds): the batch's fifteen
    weights on their matrices ``bases`` (15, 3, 3) (:func:`.fit.walk_bases`)."""
    M, off = model
    return np.einsum('q,qab->ab', f @ M - off, bases)


class FeatureStore:
    """The grid intervals' weights by start time, for the accumulators' lookups.

    Each reduced run's grid, momentum and rate are kept as they come (:meth:`add`) and
    turned into weights (:func:`interval_features`) all at once when looked up: one call
    for the runs of many blocks.
    """

    def __init__(self) -> None:
        self.t = np.empty(0)
        self.f = np.empty((0, FEATURES))
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []

    def add(self, grid: np.ndarray, hg: np.ndarray, wg: np.ndarray,
            keep_from: float | None) -> None:
        """A run's grid (G,) [s] with the momentum ``hg`` and rate ``wg`` (G, 3) there; the
        intervals before ``keep_from`` [s] are dropped (no accumulator looks them up; the
        pending runs ending by then too: a tracker that has not started looks nothing up)."""
        if keep_from is not None and len(self.t) and self.t[0] < keep_from:
            i = int(np.searchsorted(self.t, keep_from, side='left'))
            self.t, self.f = self.t[i:], self.f[i:]
        if keep_from is not None:
            self._pending = [r for r in self._pending if r[0][-1] > keep_from]
        self._pending.append((grid, hg, wg))

    def lookup(self, ts: np.ndarray) -> np.ndarray | None:
        """The weights (len(ts), F) of the intervals starting at ``ts``; None if any is
        unknown (the accumulator then keeps the stationary walk)."""
        self._flush()
        i = np.searchsorted(self.t, ts)
        if len(ts) and (i[-1] >= len(self.t) or not np.array_equal(self.t[i], ts)):
            return None
        return self.f[i]

    def mean(self, lo: float, hi: float) -> np.ndarray | None:
        """The time-weighted mean weights (F,) of the intervals starting in ``[lo, hi)`` [s]
        (each counted up to the next start or ``hi``); None without any."""
        self._flush()
        a, b = np.searchsorted(self.t, [lo, hi], side='left')
        if b <= a:
            return None
        ends = np.append(self.t[a + 1:b + 1], hi)[:b - a]      # the next start, or hi
        dt = np.minimum(ends, hi) - self.t[a:b]                 # > 0: every start < hi
        return (dt @ self.f[a:b]) / float(np.sum(dt))

    def _flush(self) -> None:
        """Turn the pending runs into weights (one :func:`interval_features` call)."""
        if self._pending:
            runs, self._pending = self._pending, []
            grid = np.concatenate([r[0] for r in runs])
            f = interval_features(grid, np.concatenate([r[1] for r in runs]),
                                  np.concatenate([r[2] for r in runs]))
            seams = np.cumsum([len(r[0]) for r in runs])[:-1] - 1   # a run's end to the next
            keep = np.ones(len(f), dtype=bool)
            keep[seams] = False
            self.t = np.concatenate([self.t, grid[:-1][keep]])
            self.f = np.concatenate([self.f, f[keep]])


class WalkSums:
    """The open segment's and the closed segments' torque-noise Grams weighted per interval.

    With the accumulator's ``R_j = h_j S + Q_j`` (:meth:`.accumulator.OnlineStats.walk_add`),
    ``sum_j c_jf R_j R_j'`` needs the weighted ``sum c h^2``, ``sum c h Q`` and ``sum c Q Q'``
    of the closed intervals plus the open one's ``c St St'``; ``sum c h`` and ``sum h`` give
    the time-weighted mean weights.
    """

    lookup: Callable[[np.ndarray], np.ndarray | None]

    def __init__(self, dim: int, lookup: Callable[[np.ndarray], np.ndarray | None]) -> None:
        self.lookup = lookup
        d = dim + 1
        self.broken = False                # an interval's weights unknown: stationary walk
        self.Gc = np.zeros((FEATURES, dim, dim))
        self.chc = np.zeros(FEATURES)
        self.hc = 0.0
        self.ch2 = np.zeros(FEATURES)
        self.chQ = np.zeros((FEATURES, d))
        self.cQQ = np.zeros((FEATURES, d * d))
        self.ch = np.zeros(FEATURES)
        self.h = 0.0
        self.copen = np.zeros(FEATURES)

    def open_reset(self) -> None:
        """Empty the open segment's sums."""
        self.ch2 = np.zeros_like(self.ch2)
        self.chQ = np.zeros_like(self.chQ)
        self.cQQ = np.zeros_like(self.cQQ)
        self.ch = np.zeros_like(self.ch)
        self.h = 0.0

    def add(self, c: np.ndarray | None, h: np.ndarray, Q: np.ndarray) -> None:
        """Closed intervals of lengths ``h`` (k,) [s], sums ``Q`` (k, d), weights ``c``
        (k + 1, F) with the now open interval's last (None: unknown)."""
        if c is None or len(c) != len(h) + 1:
            self.broken = True
            return
        ck = c[:-1]
        self.ch2 += (h * h) @ ck
        self.chQ += (ck * h[:, None]).T @ Q
        self.cQQ += ck.T @ (Q[:, :, None] * Q[:, None, :]).reshape(len(Q), self.cQQ.shape[1])
        self.ch += h @ ck
        self.h += float(np.sum(h))
        self.copen = c[-1]

    def open_grams(self, S: np.ndarray, St: np.ndarray, L: np.ndarray, t_open: float,
                   M: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
        """The open segment's weighted Grams (F, dim, dim) (``S``, ``St``, ``L`` as in
        :meth:`.accumulator.OnlineStats.segment_walk`), ``sum c h`` (F,) and ``sum h`` [s]
        (the open interval ``t_open`` [s] long so far); with ``M`` (F, P) (:func:`walk_model`)
        the Grams and sums of the P weights ``c M`` instead (4x fewer products to make)."""
        d = len(S)
        sums = (self.ch2, self.chQ, self.cQQ, self.copen, self.ch + t_open * self.copen)
        if M is not None:       # the Grams are linear in the weights: combined first
            sums = tuple(M.T @ x for x in sums)
        ch2, chQ, cQQ, copen, ch = sums
        RR = ch2[:, None, None] * np.outer(S, S)[None]
        SQ = S[None, :, None] * chQ[:, None, :]
        RR += SQ + SQ.transpose(0, 2, 1) + cQQ.reshape(-1, d, d)
        RR += copen[:, None, None] * np.outer(St, St)[None]
        G = L @ RR @ L.T
        return 0.5 * (G + G.transpose(0, 2, 1)), ch, self.h + t_open

    def fold(self, G: np.ndarray, ch: np.ndarray, h: float) -> None:
        """Add a closed segment's :meth:`open_grams`."""
        self.Gc += G
        self.chc += ch
        self.hc += h

    def decay(self, old: float) -> None:
        """Decay the closed sums by a merge's weight factor ``old`` (Grams by its square)."""
        self.Gc *= old * old
        self.chc *= old
        self.hc *= old

    def read(self, open_: tuple[np.ndarray, np.ndarray, float], GP: np.ndarray,
             model: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
        """The batch's fifteen walk Grams (15, dim, dim) and mean weights (15,) with the
        noise levels of ``model`` (:func:`walk_model`), less its offset (on ``GP``, the
        unweighted torque-noise Gram), from the closed sums and the open segment's
        (:meth:`open_grams` with the model's map): None when an interval's weights were
        unknown."""
        if self.broken:
            return None
        G, ch, h = open_
        M, off = model
        Gw = np.einsum('fp,fab->pab', M, self.Gc) + G - off[:, None, None] * GP[None]
        mean = (self.chc @ M + ch) / max(self.hc + h, 1e-300) - off
        return Gw, mean
