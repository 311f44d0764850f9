"""The online estimator's accumulator of sufficient statistics: :class:`OnlineStats`.

It owns its state (no estimator attribute is read): the exponentially weighted means and
centred Gram matrices of the 13 per-sample variables ``v_b = [w, m, t, T]`` of the open
anchored segment and the folded sums of the closed ones, the open segment's torque-noise
sums (accumulated per torque interval in closed form, :meth:`OnlineStats.walk_add`), the
closed segments kept apart for the adequacy test (:class:`.history.SegmentHistory`) and the
decayed side sums the noise model needs (``sum tau^2``, ``sum w w'``); with a momentum
input, the torque-noise Grams weighted per interval by its walk (:mod:`.online_walk`).
Blocks are merged by the parallel update of Chan, Golub and LeVeque, so the statistics do
not depend on how the streams were cut. :class:`.recursive.RecursiveEstimator` aligns the
streams into the variables and feeds them here; the fit reads the statistics back.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .adequacy import Adequacy, bias_split, check_adequacy, segment_shift
from .fit import Fit, fit_two_pass
from .history import SegmentHistory, SegmentStats, segment_pieces
from .online_walk import WalkSums
from .options import ADEQUACY_MIN_WINDOW_S, ADEQUACY_WINDOWS, MIN_EQUATIONS
from .regressors import gram, lift
from .statistics import SufficientStats

__all__ = ['OnlineStats', 'noise_map']

#: The sums decayed by the weights' factor at each merge (their squares' sums by its square).
_DECAYED = ('Cc', 'walkc', 'tq_ss', 'tq_n', 'm2_sum', 'm2_n', 'wc', 'neffc')

#: Rows a :attr:`OnlineStats.lazy` accumulator may queue before it merges them.
_MAX_QUEUED = 4096


class OnlineStats:
    """Weighted, segment-centred statistics of the anchored equations, merged block by block.

    Parameters
    ----------
    segment : float
        Anchored-segment length [s].
    window : float, optional
        Memory time constant [s] (weights ``exp(-age / window)``); takes precedence over
        ``forgetting``.
    forgetting : float
        Per-sample forgetting factor in (0, 1].
    width : int
        Variables read back: 13 ``[w, m, t, T]``, or 22 with the inertial torque's nine
        ``vec C`` after them (:mod:`.online_inertial`).

    Attributes
    ----------
    C, Cc : ndarray, shape (dim, dim)
        Centred Gram of the open segment and the sum over the closed ones.
    GPc : ndarray, shape (dim, dim)
        Closed segments' torque-noise Gram.
    w0, w00, wc, w00c, neffc : float
        Sum of weights and of squared weights (open; closed) and the closed effective count.
    t_last : float or None
        Time of the last merged equation [s].
    """

    def __init__(self, segment: float, window: float | None, forgetting: float,
                 shadow: bool = True, width: int = 13) -> None:
        self.segment = float(segment)
        self.window = window
        self.forgetting = float(forgetting)
        #: variables read back (13, or 22 with the inertial torque's)
        self.width = int(width)
        #: variables per row: the ``width`` read back and any extra columns of the same
        #: equations after them (:mod:`.online_stated`: the stated inputs' impulse changes)
        self.dim = self.width
        #: map (dim, 13) of the variables read back by :meth:`stats` and
        #: :meth:`group_stats` (None: the first ``width``), e.g. the inputs corrected
        self.correction: np.ndarray | None = None
        #: the same equations on anchored segments 4x shorter (the segment shift, the bias split;
        #: 8x made a false alarm on a correct 50 rad/s spin, chi2 53 on 6 dof)
        self.short = OnlineStats(segment / 4.0, window, forgetting, False,
                                 width) if shadow else None
        self._queue: list[Any] = []      # lazy: queued blocks (t, V, ts) and closes (start)
        self._queued = 0
        self._lazy = False
        #: whose side sums are these (a unit-weight :attr:`short`: the parent's, bit for bit)
        self._sides: OnlineStats | None = None
        if self.short is not None and window is None and self.forgetting == 1.0:
            self.short._sides = self
        #: a momentum input's per-interval walk weights by interval start
        #: (:meth:`track_walk`), and the noise levels to read them at (:func:`.online_walk.
        #: walk_model`, set before each read; None: the stationary walk alone)
        self.walk_of: Any = None
        self.walk_model: tuple[np.ndarray, np.ndarray] | None = None
        self.reset()

    def track_walk(self, lookup: Any) -> None:
        """Weight the torque-noise Gram per interval by ``lookup(ts)`` ((M, F) weights of
        the intervals starting at ``ts``, :class:`.online_walk.FeatureStore`); forgets all."""
        self.walk_of = lookup
        self.reset()

    def widen(self, dim: int) -> None:
        """Carry ``dim - 13`` extra columns after the 13 variables (forgets everything; no
        segment shift then: the stated inputs' errors are correlated, as in the batch)."""
        self.dim = int(dim)
        self.short = None
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self._queue, self._queued = [], 0
        self.w0 = 0.0                   # sum of weights
        self.w00 = 0.0                  # sum of squared weights
        d = self.dim
        self.mean = np.zeros(d)           # open segment: weighted mean and centred Gram of V
        self.C = np.zeros((d, d))
        self.Cc = np.zeros((d, d))        # closed segments
        self.wc = self.w00c = self.neffc = 0.0
        self.seg_start: float | None = None
        self.first_segment = True
        self._walk = None if self.walk_of is None else WalkSums(self.dim, self.walk_of)
        self._walk_reset()
        self.GPc = np.zeros((d, d))          # closed segments' torque-noise Gram
        self.walkc = 0.0
        self.m2_sum = np.zeros((3, 3))   # (decayed) sum of w w' [rad^2/s^2] and its count
        self.m2_n = 0.0
        self.history = SegmentHistory()  # closed segments apart, for the adequacy test
        self.clock = 0.0                 # decay clock: sum of log(decay factors)
        self.tq_ss = np.zeros(3)        # (decayed) sum of squared torque [N^2 m^2]
        self.tq_n = 0.0                 # and its (decayed) count
        self.torque_seen = False        # a torque sample has been added (add_torque_power)
        self.t_last: float | None = None
        if self.short is not None:
            self.short.reset()
            self.short.lazy = False      # until the groups test (:func:`window_test`)

    # ------------------------------------------------------------------ side sums
    def add_torque_power(self, tau: np.ndarray) -> None:
        """Add torque samples (n, 3) [N m] to the decayed ``sum tau^2`` (torque-free test)."""
        self.tq_ss = self.tq_ss + np.einsum('ij,ij->j', tau, tau)
        self.tq_n += len(tau)
        self.torque_seen = self.torque_seen or len(tau) > 0
        if self.short is not None and self.short._sides is None:
            self.short.add_torque_power(tau)

    def add_motion(self, w: np.ndarray) -> None:
        """Add gyro samples (n, 3) [rad/s] to the decayed ``sum w w'`` (gyroscopic walk)."""
        self.m2_sum = self.m2_sum + w.T @ w
        self.m2_n += len(w)
        if self.short is not None and self.short._sides is None:
            self.short.add_motion(w)

    def torque_rms(self) -> np.ndarray:
        """RMS (3,) of the merged torque [N m] (decayed as the weights)."""
        s = self._sides or self
        return np.sqrt(s.tq_ss / max(s.tq_n, 1e-300))

    def omega_m2(self) -> np.ndarray:
        """``mean(w w')`` of the merged gyro samples [rad^2/s^2] (decayed as the weights)."""
        s = self._sides or self
        return s.m2_sum / max(s.m2_n, 1e-300)

    def n_eff(self) -> float:
        """Effective number of equations after the per-segment intercepts."""
        self.flush()
        return self.neffc + (self.w0 - self.w00 / self.w0 if self.w0 > 0 else 0.0)

    # ------------------------------------------------------------------ equations
    def merge(self, t: np.ndarray, V: np.ndarray, ts: np.ndarray) -> None:
        """Merge equations ``V`` (n, dim) at ``t`` (n,) [s] (:attr:`lazy`: queue them), closing
        anchored segments at their boundaries; ``ts`` (M,): the held torque's times [s]."""
        if self.short is not None:
            self.short.merge(t, V, ts)
        wf = None if self._walk is None else self._walk.lookup(ts)
        if self.lazy:
            self._queue.append((t, V, ts, wf))
            self._queued += len(t)
            if self._queued > _MAX_QUEUED:
                self.flush()
            return
        self._merge_now(t, V, ts, wf)

    def _merge_now(self, t: np.ndarray, V: np.ndarray, ts: np.ndarray,
                   wf: np.ndarray | None = None) -> None:
        """:meth:`merge` of this segmentation, at once (``wf`` (M, F): the walk weights of
        the intervals starting at ``ts``)."""
        if self.seg_start is None:
            self.seg_start = float(t[0])
        for lo, hi, closes in segment_pieces(t, self.seg_start, self.segment):
            if hi > lo:
                self._merge_piece(t[lo:hi], V[lo:hi], ts, wf)
            if closes:
                self._fold(float(t[hi]))

    def flush(self) -> None:
        """Merge the queued blocks (:attr:`lazy`), each run between two :meth:`close` as one
        (the same equations and segments; the sums differ by rounding only)."""
        if not self._queue:
            return
        queue, self._queue, self._queued = self._queue, [], 0
        run: list[tuple[Any, ...]] = []
        for item in [*queue, None]:
            if isinstance(item, tuple):
                run.append(item)
                continue
            if run:
                self._merge_now(*_joined(run))
                run = []
            if item is not None:
                self._fold(item)

    @property
    def lazy(self) -> bool:
        """Queue :meth:`merge` and :meth:`close` until read (or :data:`_MAX_QUEUED` rows):
        one merge per run of blocks.  Only with unit weights (the side sums, added at once,
        are not decayed by merges); setting it False flushes."""
        return self._lazy

    @lazy.setter
    def lazy(self, on: bool) -> None:
        self._lazy = bool(on) and self.window is None and self.forgetting == 1.0
        if not self._lazy:
            self.flush()

    def _merge_piece(self, t: np.ndarray, V: np.ndarray, ts: np.ndarray,
                     wf: np.ndarray | None = None) -> None:
        """Merge equations of one segment into the weighted centred statistics."""
        n = len(t)
        self.walk_add(t, V, ts, wf)
        if self.window:
            wts = np.exp(-(t[-1] - t) / self.window)
            # nothing merged yet: nothing to decay (the torque statistics gathered before the
            # first merge must survive it)
            old = float(np.exp(-(t[-1] - self.t_last) / self.window)) \
                if self.t_last is not None else 1.0
        else:
            lam = self.forgetting
            wts = lam ** np.arange(n - 1, -1, -1, dtype=float)
            old = lam ** n
        self.t_last = float(t[-1])
        # unit weights (no forgetting, the node's default): the products by 1 and the decays
        # below are exact no-ops, skipped (the same numbers, bit for bit)
        unit = old == 1.0 and self.window is None and self.forgetting == 1.0
        self.clock += math.log(max(old, 1e-300))
        wb = float(np.sum(wts))
        mb = wts @ V / wb
        D = V - mb[None] if unit else (V - mb[None]) * np.sqrt(wts)[:, None]
        w_old = old * self.w0
        total = w_old + wb
        delta = mb - self.mean
        self.C = (self.C if unit else old * self.C) + gram(D) \
            + (w_old * wb / total) * np.outer(delta, delta)
        self.mean = self.mean + delta * (wb / total)
        self.w0 = total
        self.w00 = old * old * self.w00 + float(np.sum(wts * wts))
        if unit:
            return
        for name in _DECAYED:
            setattr(self, name, old * getattr(self, name))
        self.GPc = old * old * self.GPc
        self.w00c *= old * old
        if self._walk is not None:
            self._walk.decay(old)

    def close(self, new_start: float) -> None:
        """Fold the current segment's statistics into the closed ones; start a new one."""
        if self.lazy:
            self._queue.append(float(new_start))
        else:
            self._fold(new_start)
        if self.short is not None:
            self.short.close(new_start)

    def _fold(self, new_start: float) -> None:
        """:meth:`close` of this segmentation only (a boundary of its own length)."""
        if self.w0 > 0:
            self.Cc = self.Cc + self.C
            self.wc += self.w0
            self.w00c += self.w00
            self.neffc += self.w0 - self.w00 / self.w0
            gp, walk = self.segment_walk()
            if self._walk is not None:
                self._walk.fold(*_walk_open(self))
            self.GPc = self.GPc + gp
            self.walkc += walk
            self.history.add(self.open_segment(gp, walk))
        self.w0 = self.w00 = 0.0
        self.mean = np.zeros(self.dim)
        self.C = np.zeros((self.dim, self.dim))
        self._walk_reset()
        self.first_segment = False
        self.seg_start = new_start

    def open_segment(self, gp: np.ndarray, walk: float) -> SegmentStats:
        """The open segment's statistics as a :class:`SegmentStats` (at the current clock)."""
        neff = self.w0 - self.w00 / self.w0 if self.w0 > 0 else 0.0
        return SegmentStats(self.C.copy(), gp, walk, self.w0, self.w00, neff, self._wk_t0,
                            self._wk_tl, self.clock)

    def _walk_reset(self) -> None:
        """Empty the open segment's torque-noise accumulators (see :meth:`walk_add`)."""
        self._wk_s: float | None = None   # start of the open torque interval [s]
        self._wk_ntt = 0                  # torque samples of the segment up to the last gyro
        self._wk_n = 0                    # gyro samples of the segment
        self._wk_t0 = self._wk_tl = 0.0   # first and last gyro time of the segment [s]
        d = self.dim + 1
        self._wk_ref = np.zeros(d - 1)    # reference row: variables are kept relative to it
        self._wk_S = np.zeros(d)          # sum of x_b = [v_b - ref, 1]
        self._wk_St = np.zeros(d)         # open interval: sum of (t_b - s_J) x_b
        self._wk_h2 = 0.0                 # closed intervals: sum h_j^2, sum h_j Q_j,
        self._wk_hQ = np.zeros(d)         # sum Q_j Q_j'  (Q_j = St_j - h_j F_j, dim + 1)
        self._wk_QQ = np.zeros((d, d))
        if self._walk is not None:
            self._walk.open_reset()

    def walk_add(self, t: np.ndarray, V: np.ndarray, ts: np.ndarray,
                 wf: np.ndarray | None = None) -> None:
        """Accumulate the open segment's torque-noise statistics over new equations
        ``V`` (n, dim) at ``t`` (n,) [s] (:func:`_walk_add`)."""
        _walk_add(self, t, V, ts, wf)

    def segment_walk(self) -> tuple[np.ndarray, float]:
        """Torque-noise Gram (dim x dim) and walk time of the open segment (as statistics)."""
        d = self.dim
        if self._wk_n == 0 or not (self._sides or self).torque_seen or self._wk_ntt < 2:
            return np.zeros((d, d)), 0.0
        S, hQ = self._wk_S, self._wk_hQ
        RR = self._wk_h2 * np.outer(S, S) + np.outer(S, hQ) + np.outer(hQ, S) + self._wk_QQ \
            + np.outer(self._wk_St, self._wk_St)
        L = self._demean_map()
        G = L @ RR @ L.T
        return 0.5 * (G + G.T), self._wk_n * (self._wk_tl - self._wk_t0) / 6.0

    def _demean_map(self) -> np.ndarray:
        """``[1 | -mean]`` (dim, dim + 1): the open segment's sums of ``x_b`` demeaned."""
        d = self.dim
        L = np.empty((d, d + 1))
        L[:, :d] = np.eye(d)
        L[:, d] = -self._wk_S[:d] / self._wk_n
        return L

    # ------------------------------------------------------------------ reading back
    def stats(self, nv: np.ndarray, n_eff: float, walk_noise: bool, *, torque_dt: float,
              gyro_dt: float, white_y_cov: np.ndarray | None,
              gyro_scale: float = 1.0) -> SufficientStats:
        """The weighted statistics of everything merged, in the batch estimator's form.

        The gyro-noise correction of the squared-rate integrals, ``m_c -> m_c - sigma_c^2 s``,
        is linear in the 13 variables (``K``) and applied here with the noise variance ``nv``
        (3,) [rad^2/s^2].  ``walk_noise``: include the torque-noise Gram.  ``gyro_scale``
        gives the statistics of a gyro read that many times larger (``w`` and the
        squared-rate integrals scale exactly; for the gyro-scale sensitivity).  ``torque_dt``,
        ``gyro_dt`` [s] and ``white_y_cov`` (3, 3) are the noise model's stream figures.
        """
        self.flush()
        gp, walk = self.segment_walk()
        K, GP = self._read_map(nv, gyro_scale), self.GPc + gp
        grams = None
        if walk_noise and self._walk is not None and self.walk_model is not None:
            grams = self._walk.read(_walk_open(self, self.walk_model[0]), GP, self.walk_model)
        if grams is not None:       # the batch's time-varying walk (:mod:`.online_walk`)
            grams = {'walk_grams': np.array([lift(g) for g in K.T @ grams[0] @ K]),
                     'walk_mean': grams[1]}
        return self._read(K, self.C + self.Cc, GP if walk_noise else None, self.w0 + self.wc,
                          n_eff, self.walkc + walk, nv, torque_dt=torque_dt, gyro_dt=gyro_dt,
                          white_y_cov=white_y_cov, **(grams or {}))

    def _read(self, K: np.ndarray, C: np.ndarray, GP: np.ndarray | None, w0: float,
              n_eff: float, walk: float, nv: np.ndarray, **context: Any) -> SufficientStats:
        """Centred Grams (dim, dim) ``C`` and ``GP`` (None: no torque noise) of ``w0``
        weighted equations read through ``K`` (:meth:`_read_map`) as statistics."""
        return SufficientStats(lift(K.T @ C @ K), None if GP is None else lift(K.T @ GP @ K),
                               int(round(w0)), int(round(n_eff)), 1, kind='anchored',
                               eiv_var=nv, weighted=True, walk_time=walk,
                               omega_m2=self.omega_m2(), **context)

    def window_test(self, f: Fit, nv: np.ndarray, tv: np.ndarray, *, torque_dt: float,
                    gyro_dt: float, white_y_cov: np.ndarray | None) -> Adequacy:
        """The adequacy tests of ``f`` on these statistics (:func:`window_test`)."""
        return window_test(self, f, nv, tv, torque_dt=torque_dt, gyro_dt=gyro_dt,
                           white_y_cov=white_y_cov)

    def group_stats(self, nv: np.ndarray, *, torque_dt: float, gyro_dt: float,
                    white_y_cov: np.ndarray | None, gyro_scale: float = 1.0,
                    min_s: float = ADEQUACY_MIN_WINDOW_S
                    ) -> list[tuple[SufficientStats, float, float]]:
        """The adequacy test's groups of the kept segments, as statistics.

        Up to :data:`ADEQUACY_WINDOWS` consecutive groups (the open segment included), each
        of at least ``min_s`` [s] (:data:`ADEQUACY_MIN_WINDOW_S`) and :data:`MIN_EQUATIONS`, as
        the batch's windows (a 1 s open segment would give chi2 ~2000); else as :meth:`stats`.

        Returns
        -------
        list of (SufficientStats, float, float)
            Per group: its statistics, the factor ``w00 / w0`` of a fit's covariance (the
            meat of weighted sums) and its middle time [s].
        """
        self.flush()
        gp, walk = self.segment_walk()
        groups = [g for g in self.history.groups(ADEQUACY_WINDOWS, self.open_segment(gp, walk),
                                                 self.clock)
                  if g.neff >= MIN_EQUATIONS and g.t1 - g.t0 >= min_s]
        K = self._read_map(nv, gyro_scale)
        return [(self._read(K, g.C, g.GP, g.w0, g.neff, g.walk, nv, torque_dt=torque_dt,
                            gyro_dt=gyro_dt, white_y_cov=white_y_cov),
                 g.w00 / g.w0, 0.5 * (g.t0 + g.t1)) for g in groups]

    def _read_map(self, nv: np.ndarray, gyro_scale: float) -> np.ndarray:
        """The map (dim, width) from the accumulated variables to the ``width`` read back:
        the :attr:`correction` (or the first ``width``), then :func:`noise_map`."""
        K = noise_map(nv, gyro_scale, self.width)
        if self.correction is not None:
            return self.correction @ K
        return K if self.dim == self.width else np.eye(self.dim, self.width) @ K

    def totals(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Centred Gram (dim, dim) of everything merged, the torque-noise Gram and the
        walk time [s] (for fits of the extra columns: :mod:`.online_stated`)."""
        self.flush()
        gp, walk = self.segment_walk()
        return self.C + self.Cc, self.GPc + gp, self.walkc + walk


def noise_map(nv: np.ndarray, gyro_scale: float = 1.0, width: int = 13) -> np.ndarray:
    """The linear map (width, width) of the variables ``[w, m, t, T]`` (and, width 22, the
    inertial torque's ``vec C``) applying the gyro-noise correction ``m_c -> m_c - sigma_c^2
    s`` (``nv`` (3,) [rad^2/s^2]) and, for ``gyro_scale`` != 1, a gyro read that many times
    larger (``w`` and ``m`` scale; ``C`` kept: first order, as the batch's
    :func:`.refits.gyro_sensitivity`)."""
    K = np.eye(width)
    K[9, 3:6] = -nv
    if gyro_scale != 1.0:
        K = np.diag(np.r_[np.full(3, gyro_scale), np.full(6, gyro_scale ** 2),
                          np.ones(width - 9)]) @ K
    return K


def window_test(acc: OnlineStats, f: Fit, nv: np.ndarray, tv: np.ndarray, *,
                torque_dt: float, gyro_dt: float, white_y_cov: np.ndarray | None) -> Adequacy:
    """The adequacy tests of ``f``: its parameter set refitted on groups of segments.

    Up to :data:`ADEQUACY_WINDOWS` consecutive groups of the kept segments (the open one
    included), each fitted with the weights of ``f``'s tensor, as the batch estimator does
    on time windows; ``nv``, ``tv`` (3,) the gyro and torque noise variances.
    """
    p, k = len(f.beta), f.basis.shape[1]
    groups = acc.group_stats(nv, torque_dt=torque_dt, gyro_dt=gyro_dt,
                             white_y_cov=white_y_cov)
    if len(groups) >= 2 and acc.short is not None:
        # the short is read only by the shift test from now on (the bias split, ill-conditioned
        # enough to show rounding, ran before two groups on its block-by-block sums): lazy
        acc.short.lazy = True
    thetas, covs, mids = np.zeros((0, p)), np.zeros((0, p, p)), np.zeros(0)
    if len(groups) >= 2:
        theta0 = f.basis @ f.beta[:k]
        fits = []
        for st, factor, mid in groups:
            fk = fit_two_pass(st, f.basis, f.bias, nv, tv, None, theta0, inertial=f.inertial)
            fits.append((fk.beta, fk.cov * factor, mid))
        thetas = np.array([x[0] for x in fits])
        covs = np.array([x[1] for x in fits])
        mids = np.array([x[2] for x in fits])
    ctx = {'torque_dt': torque_dt, 'gyro_dt': gyro_dt, 'white_y_cov': white_y_cov}
    split = _split(acc, f, nv, tv, **ctx) if len(groups) < 2 and (f.bias or f.inertial) \
        else None
    return check_adequacy(thetas, covs, mids, f.excess, shift=_shift(acc, f, nv, tv, **ctx),
                          split=split)


def _split(acc: OnlineStats, f: Fit, nv: np.ndarray, tv: np.ndarray, **context: object
           ) -> tuple[float, int, float, int] | None:
    """Too short for the groups: the fitted torque bias (and / or inertial torque) tested
    over up to four groups of :attr:`OnlineStats.short`'s segments
    (:func:`.adequacy.bias_split`, as the batch's :func:`.refits.bias_split_test`); ``None``
    as :func:`_shift`."""
    s = acc.short
    if s is None or context['white_y_cov'] is not None:
        return None
    s.correction = acc.correction
    k = f.basis.shape[1]
    theta0 = f.basis @ f.beta[:k]
    fits = []
    for st, factor, _ in s.group_stats(nv, min_s=0.0, **context):  # type: ignore[arg-type]
        fk = fit_two_pass(st, f.basis, f.bias, nv, tv, None, theta0, theta0,
                          inertial=f.inertial)
        fk.cov = fk.cov * factor
        fits.append(fk)
    return bias_split(fits, k) if len(fits) >= 2 else None


def _shift(acc: OnlineStats, f: Fit, nv: np.ndarray, tv: np.ndarray, **context: object
           ) -> tuple[float, int, float, float] | None:
    """:func:`.adequacy.segment_shift` of ``f`` against the same fit of
    :attr:`OnlineStats.short` (segments 4x shorter), as the batch's
    :func:`.refits.shift_test`; ``None`` with a momentum input's white noise in ``y`` or too
    few equations."""
    s = acc.short
    if s is None or context['white_y_cov'] is not None or s.n_eff() < MIN_EQUATIONS:
        return None
    k = f.basis.shape[1]
    theta0 = f.basis @ f.beta[:k] + (0.0 if f.offset is None else f.offset)
    s.correction = acc.correction
    # both refitted: ``f``'s own covariance may have been widened since (a deferred test)
    fl, fs = (fit_two_pass(a.stats(nv, a.n_eff(), True, **context),  # type: ignore[arg-type]
                           f.basis, f.bias, nv, tv, f.offset, theta0, inertial=f.inertial)
              for a in (acc, s))
    rl, rs = ((a.w00 + a.w00c) / (a.w0 + a.wc) for a in (acc, s))   # meat of weighted sums
    return segment_shift(fl.beta[:k], fl.cov[:k, :k] * rl / max(fl.excess, 1.0),
                         fs.beta[:k], fs.cov[:k, :k] * rs / max(fs.excess, 1.0))


def _joined(run: list[tuple[Any, ...]]) -> tuple[Any, ...]:
    """Queued blocks ``(t, V, ts, wf)`` as one: the rows concatenated, the torque times
    (and their walk weights ``wf``, if any) united (each block's are the earlier ones' from
    some sample on, or newer: the aligner trims and appends, never modifies)."""
    ts, wf = run[0][2], run[0][3]
    for _, _, later, wl in run[1:]:
        i = np.searchsorted(later, ts[-1], 'right')
        ts = np.concatenate([ts, later[i:]])
        wf = None if wf is None or wl is None else np.concatenate([wf, wl[i:]])
    return np.concatenate([r[0] for r in run]), np.concatenate([r[1] for r in run]), ts, wf


def _walk_add(acc: OnlineStats, t: np.ndarray, V: np.ndarray, ts: np.ndarray,
              wf: np.ndarray | None) -> None:
    """Accumulate the open segment's torque-noise statistics over new equations.

    The segment's torque-noise sums (:func:`.statistics.torque_stats` on the segment-demeaned
    variables) are ``P_j = [1 | -mean] R_j`` with ``R_j = sum_b o_j(b) x_b``,
    ``o_j(b) = clip(t_b - s_j, 0, h_j)`` and ``x_b = [v_b - ref, 1]``.  Once torque interval
    ``j`` is closed (a gyro sample at or after its end has arrived), ``R_j = h_j S + Q_j``
    with the running segment sum ``S`` and a fixed ``Q_j``; so ``sum_j R_j R_j'`` needs only
    ``sum h_j^2``, ``sum h_j Q_j`` and ``sum Q_j Q_j'`` of the closed intervals plus the open
    one: O(new samples + new torque samples) per block, none per ``estimate()``.  With
    :meth:`OnlineStats.track_walk` the same sums weighted per interval by ``wf`` (M, F) (the
    intervals starting at ``ts``) go to :class:`.online_walk.WalkSums`.
    """
    n = len(t)
    if acc._wk_s is None:
        # (never before the first torque sample: such gyro samples are dropped)
        i = int(np.searchsorted(ts, t[0], side='right')) - 1
        acc._wk_s = float(ts[i])
        # the first segment's torque list starts at the first torque sample, later ones
        # at the last torque sample at or before their start
        acc._wk_ntt = i + 1 if acc.first_segment else 1
        acc._wk_ref = V[0].copy()
        acc._wk_t0 = float(t[0])
    d = acc.dim
    X = np.empty((n, d + 1))
    np.subtract(V, acc._wk_ref[None], out=X[:, :d])
    X[:, d] = 1.0
    lo = int(np.searchsorted(ts, acc._wk_s, side='right'))
    hi = int(np.searchsorted(ts, t[-1], side='right'))
    b = ts[lo:hi]                      # torque samples starting new intervals
    k = len(b)
    if k == 0:
        acc._wk_St = acc._wk_St + (t - acc._wk_s) @ X
        if acc._walk is not None:     # the open interval's weights
            acc._walk.add(None if wf is None else wf[lo - 1:hi], np.zeros(0), X[:0])
    else:
        bounds = np.concatenate([[acc._wk_s], b])
        first = np.searchsorted(t, bounds, side='left')
        counts = np.diff(np.append(first, n))
        nz = counts > 0
        u = t - np.repeat(bounds, counts)
        Sm = np.zeros((k + 1, d + 1))
        St = np.zeros((k + 1, d + 1))
        Sm[nz] = np.add.reduceat(X, first[nz], axis=0)
        St[nz] = np.add.reduceat(X * u[:, None], first[nz], axis=0)
        h = np.diff(bounds)
        St[0] += acc._wk_St
        # every earlier sample precedes the end of the block's first interval
        F = acc._wk_S + np.cumsum(Sm[:k], axis=0)
        Q = St[:k] - h[:, None] * F
        acc._wk_h2 += float(h @ h)
        acc._wk_hQ = acc._wk_hQ + h @ Q
        acc._wk_QQ = acc._wk_QQ + Q.T @ Q
        if acc._walk is not None:     # the same weighted, and the open interval's
            acc._walk.add(None if wf is None else wf[lo - 1:hi], h, Q)
        acc._wk_St = St[k]
        acc._wk_s = float(bounds[k])
        acc._wk_ntt += k
    acc._wk_S = acc._wk_S + X.sum(axis=0)
    acc._wk_n += n
    acc._wk_tl = float(t[-1])


def _walk_open(acc: OnlineStats, M: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, float]:
    """The open segment's Grams weighted per interval (:meth:`.online_walk.WalkSums.
    open_grams`, ``M`` its map; zero where :meth:`OnlineStats.segment_walk` is)."""
    assert acc._walk is not None
    d, F = acc.dim, len(acc._walk.ch) if M is None else M.shape[1]
    if acc._wk_n == 0 or not (acc._sides or acc).torque_seen or acc._wk_ntt < 2:
        return np.zeros((F, d, d)), np.zeros(F), 0.0
    return acc._walk.open_grams(acc._wk_S, acc._wk_St, acc._demean_map(),
                                max(acc._wk_tl - float(acc._wk_s or 0.0), 0.0), M)
