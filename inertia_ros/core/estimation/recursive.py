"""Recursive (online) inertia estimation for the ROS node: :class:`RecursiveEstimator`.

The same anchored momentum equations as the batch ``integral`` method,
``I w_b + int w x (I w) dt - d t_b - h0 = int tau dt``, accumulated in information form:
exponentially weighted means and centred Gram matrices of the 13 per-sample variables
``v_b = [w, m, t, T]`` (angular velocity, integrated squared rates, time, integrated torque)
from which every equation block is a fixed linear map.  The record is cut into anchored
segments (``segment`` seconds), each with its own momentum intercept ``h0``, so removing the
segment's weighted mean is the exact elimination of ``h0`` and a momentum jump (payload
release) only disturbs one segment.  Statistics are merged block by block (the parallel
update of Chan, Golub and LeVeque): the cost per sample is a few small matrix products
amortised over the block, and ``estimate()`` projects the same 13 x 13 statistics onto any
parameter set, with the batch estimator's identifiability, model selection and covariance
(white gyro noise plus the integrated torque noise of each segment).  The gyro-noise
correction of the squared-rate integrals is linear in ``v`` and applied at ``estimate()`` with
the running noise estimate, so the answer does not depend on how the streams were cut into
blocks.  Forgetting (``window`` time constant or per-sample ``forgetting`` factor) lets the
estimate follow a changing tensor.

Everything ``estimate()`` needs is kept up to date as samples are merged, so its cost does not
grow with the record: closed segments are folded into fixed sums, and the open segment's
torque-noise statistics (:func:`.statistics.torque_stats` of its demeaned variables) are
accumulated per torque interval in closed form (see :meth:`RecursiveEstimator._walk_add`)
instead of being recomputed from the segment's samples, which are no longer stored.
Torque-free data (:func:`.homogeneous.is_torque_free`, the batch rule) gives
``scale_unobservable`` with the ratios and principal axes from the null vector of the same
statistics, as the batch estimator does.

The two streams arrive asynchronously: gyro samples are buffered until torque covering them
has arrived (a torque sample at or after the gyro time), then integrated exactly under the
zero-order hold (or linear interpolation) of the torque samples.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._validate import MAX_TIME_S, as_noise_std, as_sample_block, require_after
from .adequacy import Adequacy, check_adequacy
from .assemble import conclude, status_only
from .config import require, unapplied
from .fit import Fit, fit_two_pass
from .history import SegmentHistory, SegmentStats
from .homogeneous import homogeneous_estimate, is_torque_free
from .model import symmetry_axis as unit_axis
from .noise import StreamingNoise, median_rows
from .options import (
    ADEQUACY_MIN_WINDOW_S,
    ADEQUACY_WINDOWS,
    ALPHA,
    GAP_FACTOR,
    MIN_EQUATIONS,
    MIN_GYRO_SAMPLES,
)
from .regressors import cumulative_torque, gram, lift, monomials
from .result import InertiaEstimate
from .selection import SelectionPolicy
from .statistics import SufficientStats

__all__ = ['RecursiveEstimator']

_MAX_BUFFER = 400_000                      # gyro samples kept waiting for torque
_DT_HISTORY = 64        # recent sample intervals kept per stream for the nominal interval


class RecursiveEstimator:
    """Online inertia estimator with forgetting, fed sample by sample or in blocks.

    Parameters
    ----------
    model : {'full', 'diagonal', 'axisymmetric', 'auto'}
        Parameter set (``auto``: Wald-test selection as in the batch estimator).
    torque_bias : bool or {'auto', 'on', 'off'}
        Estimate a constant disturbance torque [N m].
    forgetting : float
        Per-sample forgetting factor ``lambda`` in (0, 1]; 1 keeps everything.
    window : float, optional
        Memory time constant [s]: sample weights decay as ``exp(-age / window)``.  Takes
        precedence over ``forgetting``.
    hold : {'zoh', 'linear'}
        Torque between samples.
    symmetry_axis : {'x', 'y', 'z'} or array_like (3,), optional
        For the axisymmetric model.
    gyro_noise : float or array_like (3,), optional
        Gyro white-noise std [rad/s]; estimated from the stream when omitted.
    alpha : float
        Model-selection test level.
    block : int
        Gyro samples buffered before an update of the statistics (``estimate`` always flushes).
    segment : float, optional
        Anchored-segment length [s]: each segment has its own momentum intercept, so a
        momentum jump (payload change) only affects one segment.  Default ``window`` or 10 s.
    reselect_every : int
        With ``model`` or ``torque_bias`` ``'auto'``: run the model-selection tests on every
        ``reselect_every``-th call of :meth:`estimate` and reuse the parameter set they chose
        in between (one fit instead of two or more per call; the node re-selects about once
        a second).  1 (default) selects on every call.
    torque_scale_std, gyro_scale_std : float
        Relative one-sigma scale uncertainty of the torque and the gyro (0.01 = 1 %),
        propagated into the standard errors as by :func:`~.batch.estimate`.
    defer_adequacy : bool
        A test estimate (every ``reselect_every``-th) reports the previous adequacy verdict and
        leaves its own test to :meth:`refresh` (the node: after publishing), for the estimates
        that follow: each verdict one estimate later, the tensor unchanged.  The first test, and
        one not refreshed, run inside :meth:`estimate`.  Default False.
    nuisance : str
        Only ``'off'``: any other value is refused by :func:`.config.require` (one line).
    """

    #: White noise in the equations' right-hand side besides the gyro's (a momentum input's,
    #: set by :class:`.recursive_momentum.MomentumRecursiveEstimator`) [N^2 m^2 s^2].
    _white_y_cov: np.ndarray | None = None

    def __init__(self, model: str = 'full', torque_bias: bool | str = False,
                 forgetting: float = 1.0, window: float | None = None, hold: str = 'zoh',
                 symmetry_axis: Any = None, gyro_noise: Any = None, alpha: float = ALPHA,
                 block: int = 256, segment: float | None = None,
                 reselect_every: int = 1, torque_scale_std: float = 0.0,
                 gyro_scale_std: float = 0.0, defer_adequacy: bool = False,
                 nuisance: Any = 'off') -> None:
        opts = require('recursive', 'torque', dict(
            model=model, torque_bias=torque_bias, hold=hold, symmetry_axis=symmetry_axis,
            alpha=alpha, torque_scale_std=torque_scale_std, gyro_scale_std=gyro_scale_std,
            nuisance=nuisance))
        torque_bias = opts.torque_bias
        if not (0.0 < forgetting <= 1.0):
            raise ValueError(f'forgetting: must be in (0, 1], got {forgetting!r}')
        if window is not None and not window > 0:
            raise ValueError(f'window: must be > 0 s, got {window!r}')
        self.policy = SelectionPolicy(alpha, torque_scale_std=torque_scale_std,
                                      gyro_scale_std=gyro_scale_std)
        if segment is not None and not segment > 0:
            raise ValueError(f'segment: must be > 0 s, got {segment!r}')
        self.segment = float(segment if segment is not None else (window or 10.0))
        if int(block) < 1:
            raise ValueError(f'block: must be >= 1, got {block!r}')
        if isinstance(reselect_every, bool) or int(reselect_every) != reselect_every \
                or reselect_every < 1:
            raise ValueError(f'reselect_every: must be an integer >= 1, got {reselect_every!r}')
        self.reselect_every = int(reselect_every)
        self.defer_adequacy = bool(defer_adequacy)
        self.model = model
        self.torque_bias = torque_bias
        self.forgetting = float(forgetting)
        self.window = window
        self.hold = hold
        self.axis = unit_axis(symmetry_axis)
        self.block = int(block)
        self._gyro_noise = None if gyro_noise is None else as_noise_std(gyro_noise,
                                                                          'gyro_noise')
        self.reset()

    # -----------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget everything (clock jump, new run)."""
        self._pt: list[np.ndarray] = []      # pending torque blocks
        self._ptau: list[np.ndarray] = []
        self._single_t: list[float] = []
        self._single_w: list[Any] = []
        self._n_buf = 0                     # samples in self._gt
        self._new_torque = False            # torque arrived since the last _process
        self._gt: list[np.ndarray] = []
        self._gw: list[np.ndarray] = []
        self._ts = np.empty(0)
        self._tau = np.empty((0, 3))
        self._T_base = np.zeros(3)       # torque integral at self._ts[0]
        self._t0: float | None = None    # time origin of the bias column
        self._prev: tuple[float, np.ndarray] | None = None   # last processed gyro sample
        self._M = np.zeros(6)            # monomial integral at the last processed sample
        self._w0 = 0.0                   # sum of weights
        self._w00 = 0.0                  # sum of squared weights
        self._mean = np.zeros(13)          # open segment: weighted mean and centred Gram of V
        self._C = np.zeros((13, 13))
        self._Cc = np.zeros((13, 13))      # closed segments
        self._wc = self._w00c = self._neffc = 0.0
        self._seg_start: float | None = None
        self._first_segment = True
        self._walk_reset()
        self._GPc = np.zeros((13, 13))        # closed segments' torque-noise Gram
        self._walkc = 0.0
        self._tau_var: np.ndarray | None = None
        self._m2_sum = np.zeros((3, 3))   # (decayed) sum of w w' [rad^2/s^2] and its count
        self._m2_n = 0.0
        self._history = SegmentHistory()  # closed segments apart, for the adequacy test
        self._clock = 0.0                 # decay clock: sum of log(decay factors)
        self._adequacy: Adequacy | None = None   # last adequacy result, reused between tests
        self._adequacy_left = 0
        #: deferred adequacy test: (estimate serial, final fit, gyro and torque noise variances)
        self._adequacy_due: tuple[int, Fit, np.ndarray, np.ndarray] | None = None
        self._estimates = 0               # estimate() calls (serial of the last one)
        self._tq_ss = np.zeros(3)        # (decayed) sum of squared torque [N^2 m^2]
        self._tq_n = 0.0                 # and its (decayed) count
        self._tau_dt = 0.0
        self._tq_dts = np.empty(0)       # recent torque / gyro sample intervals [s]
        self._g_dts = np.empty(0)
        self._g_dt = 0.0                 # their median (0 before two samples)
        self._tq_last: float | None = None
        self.gaps = 0                    # gaps that ended a segment holding data
        self._t_last: float | None = None
        self._last_t_in: float | None = None
        self._last_tau_in: float | None = None
        self._gyro_nv = StreamingNoise(floor=True)      # gyro noise (unless given)
        self._tau_nv = StreamingNoise(floor=False)     # torque noise
        self.samples_used = 0
        self.samples_dropped = 0
        # model selection reused between re-selections: (torque_bias, model, its record)
        self._selection: tuple[str, str, dict[str, Any]] | None = None
        self._selection_left = 0

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Add gyro samples.

        Parameters
        ----------
        t : float or array_like, shape (n,)
            Sample times [s], increasing across calls.
        omega : array_like, shape (3,) or (n, 3)
            Angular velocity [rad/s].
        """
        if isinstance(t, (float, int)) and len(omega) == 3 and np.ndim(omega) == 1:
            # fast path for one sample (the node's common case)
            tf = float(t)
            if abs(tf) > MAX_TIME_S:        # the one-sample form of refuse_nanoseconds
                raise ValueError(f'time {tf!r} looks like nanoseconds; give seconds')
            if not (math.isfinite(tf) and all(math.isfinite(float(v)) for v in omega)):
                raise ValueError('omega: contains NaN or inf')
            require_after(tf, self._last_t_in, 'omega')
            self._last_t_in = tf
            self._single_t.append(tf)
            self._single_w.append(omega)
            if len(self._single_t) + self._n_buf >= self.block and self._new_torque:
                self._process()
            return
        self._flush_single()
        ta, wa = as_sample_block(t, omega, 'omega')
        if len(ta) == 0:
            return
        require_after(ta[0], self._last_t_in, 'omega')
        self._last_t_in = float(ta[-1])
        self._gt.append(ta)
        self._gw.append(wa)
        self._n_buf += len(ta)
        if self._n_buf + len(self._single_t) >= self.block and self._new_torque:
            self._process()
        elif self._n_buf > _MAX_BUFFER:
            # torque stream stalled: keep the newest samples only
            self._flush_single()
            t = np.concatenate(self._gt)
            w = np.concatenate(self._gw)
            self.samples_dropped += len(t) - _MAX_BUFFER // 2
            self._gt, self._gw = [t[-(_MAX_BUFFER // 2):]], [w[-(_MAX_BUFFER // 2):]]
            self._n_buf = len(self._gt[0])

    def _flush_single(self) -> None:
        """Move single gyro samples into the block buffer."""
        if self._single_t:
            self._gt.append(np.array(self._single_t, dtype=float))
            self._gw.append(np.array(self._single_w, dtype=float).reshape(-1, 3))
            self._n_buf += len(self._single_t)
            self._single_t, self._single_w = [], []

    def add_torque(self, t: Any, tau: Any) -> None:
        """Add torque samples.

        Parameters
        ----------
        t : float or array_like, shape (n,)
            Sample times [s], increasing across calls.
        tau : array_like, shape (3,) or (n, 3)
            Torque about the centre of mass [N m].
        """
        if isinstance(t, (float, int)) and len(tau) == 3 and np.ndim(tau) == 1:
            tf = float(t)
            if abs(tf) > MAX_TIME_S:        # the one-sample form of refuse_nanoseconds
                raise ValueError(f'time {tf!r} looks like nanoseconds; give seconds')
            if not (math.isfinite(tf) and all(math.isfinite(float(v)) for v in tau)):
                raise ValueError('torque: contains NaN or inf')
            require_after(tf, self._last_tau_in, 'torque')
            self._last_tau_in = tf
            self._new_torque = True
            self._pt.append(np.array([tf]))
            self._ptau.append(np.asarray(tau, dtype=float).reshape(1, 3))
            return
        ta, xa = as_sample_block(t, tau, 'torque')
        if len(ta) == 0:
            return
        require_after(ta[0], self._last_tau_in, 'torque')
        self._last_tau_in = float(ta[-1])
        self._new_torque = True
        self._pt.append(ta)
        self._ptau.append(xa)

    def merge(self) -> None:
        """Merge the buffered samples the torque covers now (:meth:`estimate` then has less to
        do); the statistics, so the estimate, do not depend on the cut (up to rounding)."""
        self._process()

    # -----------------------------------------------------------------------------------------
    def _process(self) -> None:
        """Turn buffered gyro samples covered by torque into equations and merge them."""
        self._flush_single()
        self._new_torque = False
        if self._pt:
            self._take_torque()
        if not self._gt:
            return
        t, w, breaks = self._ready_gyro()
        if len(t) == 0:
            return
        if self._gyro_noise is None:
            self._gyro_nv.add(w)
        self._m2_sum = self._m2_sum + w.T @ w          # mean(w w'): the gyroscopic noise walk
        self._m2_n += len(w)
        # torque integral at the gyro times, relative to self._ts[0]
        T = self._T_base + cumulative_torque(self._ts, self._tau, t, self.hold)
        M = self._monomial_integral(t, w)
        # raw monomial integrals: the gyro-noise correction m - s sigma^2 is linear in the
        # variables, applied to the statistics at estimate() with the final noise estimate
        V = np.concatenate([w, M, (t - self._t0)[:, None], T], axis=1)
        # a gap starts a new anchored segment: the wrongly held torque and the trapezoid across
        # the gap shift T and M by constants, which the new segment's momentum absorbs
        lo = 0
        for k in breaks:
            if k > lo:
                self._merge(t[lo:k], V[lo:k])
            self.gaps += self._w0 > 0       # a break that ends a segment holding data
            self._close_segment(float(t[k]))
            lo = k
        self._merge(t[lo:], V[lo:])
        self.samples_used += len(t)
        # keep torque samples from the last one at or before the last processed gyro time
        j = int(np.searchsorted(self._ts, t[-1], side='right') - 1)
        if j > 0:
            self._T_base = self._T_base + cumulative_torque(self._ts, self._tau,
                                                            self._ts[j:j + 1], self.hold)[0]
            self._ts = self._ts[j:]
            self._tau = self._tau[j:]

    def _take_torque(self) -> None:
        """Move the pending torque samples into the held stream; update the torque noise."""
        new_t = np.concatenate(self._pt)
        new_tau = np.concatenate(self._ptau)
        self._ts = np.concatenate([self._ts, new_t])
        self._tau = np.concatenate([self._tau, new_tau])
        self._pt, self._ptau = [], []
        self._tq_ss = self._tq_ss + np.einsum('ij,ij->j', new_tau, new_tau)
        self._tq_n += len(new_t)
        edges = new_t if self._tq_last is None else np.concatenate([[self._tq_last], new_t])
        self._tq_dts = np.concatenate([self._tq_dts, np.diff(edges)])[-_DT_HISTORY:]
        self._tq_last = float(new_t[-1])
        # the same robust estimator as batch, on the recent samples whatever the block size
        # (the variance itself is taken in estimate())
        self._tau_nv.add(new_tau)
        if len(self._tq_dts):
            self._tau_dt = float(median_rows(self._tq_dts[:, None])[0])   # np.median, faster

    def _ready_gyro(self) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """Buffered gyro samples now covered by torque (the rest stays buffered), with gaps.

        Returns the samples ``t`` (n,), ``w`` (n, 3) and the indices where a gap starts a
        new segment (see :meth:`_gaps`).
        """
        t = np.concatenate(self._gt)
        w = np.concatenate(self._gw)
        self._gt, self._gw = [], []
        self._n_buf = 0
        if len(self._ts) == 0:
            self._gt, self._gw = [t], [w]
            self._n_buf = len(t)
            return t[:0], w[:0], []
        # gyro samples before the first torque sample can never be used
        early = t < self._ts[0]
        if np.any(early):
            self.samples_dropped += int(np.sum(early))
            t, w = t[~early], w[~early]
        ready = t <= self._ts[-1]
        if not np.all(ready):
            self._gt, self._gw = [t[~ready]], [w[~ready]]
            self._n_buf = int(np.sum(~ready))
            t, w = t[ready], w[ready]
        return self._gaps(t, w)

    def _monomial_integral(self, t: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Trapezoid integral (n, 6) of the monomials, continuing from the last sample."""
        m = monomials(w)
        if self._prev is None:
            tt = t
            mm = m
            start = np.zeros(6)
            self._t0 = float(t[0])
        else:
            tt = np.concatenate([[self._prev[0]], t])
            mm = np.concatenate([monomials(self._prev[1][None, :]), m])
            start = self._M
        inc = 0.5 * (mm[1:] + mm[:-1]) * np.diff(tt)[:, None]
        M = np.empty((len(t), 6))
        if self._prev is None:
            M[0] = start
            np.cumsum(inc, axis=0, out=M[1:])
            M[1:] += start
        else:
            np.cumsum(inc, axis=0, out=M)
            M += start
        self._M = M[-1].copy()
        self._prev = (float(t[-1]), w[-1].copy())
        return M

    def _gaps(self, t: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """Drop gyro samples inside torque gaps; find where gaps force a new segment.

        A torque interval longer than ``GAP_FACTOR`` nominal intervals (lost messages, a
        paused controller) would be integrated as the last command held throughout, and a
        gyro gap would be bridged by one trapezoid: both corrupt every later equation of the
        segment.  Gyro samples the held torque cannot cover are dropped (counted), and the
        first sample after each gap starts a new anchored segment.

        Returns
        -------
        t, w : ndarray
            The kept gyro samples.
        breaks : list of int
            Sorted indices into the kept ``t`` where a new segment starts.
        """
        starts: list[float] = []
        keep = np.ones(len(t), dtype=bool)
        if len(self._tq_dts) >= 2 and len(self._ts) >= 2:
            nominal = self._tau_dt           # the median of self._tq_dts (_take_torque)
            dq = np.diff(self._ts)
            for i in np.flatnonzero(dq > GAP_FACTOR * nominal):
                keep &= ~((t > self._ts[i] + nominal) & (t < self._ts[i + 1]))
                starts.append(float(self._ts[i + 1]))
        edges = t if self._prev is None else np.concatenate([[self._prev[0]], t])
        dg = np.diff(edges)
        self._g_dts = np.concatenate([self._g_dts, dg])[-_DT_HISTORY:]
        self._g_dt = float(median_rows(self._g_dts[:, None])[0]) if len(self._g_dts) else 0.0
        if len(self._g_dts) >= 2:
            big = np.flatnonzero(dg > GAP_FACTOR * self._g_dt)
            starts.extend(float(edges[i + 1]) for i in big)
        if not starts:
            return t, w, []
        dropped = int(np.sum(~keep))
        self.samples_dropped += dropped
        t, w = t[keep], w[keep]
        breaks = sorted({int(np.searchsorted(t, b, side='left')) for b in starts})
        return t, w, [k for k in breaks if k < len(t)]

    def _merge(self, t: np.ndarray, V: np.ndarray) -> None:
        """Merge a block of equations, closing anchored segments at their boundaries."""
        while len(t):
            if self._seg_start is None:
                self._seg_start = float(t[0])
            k = int(np.searchsorted(t, self._seg_start + self.segment, side='left'))
            if k == 0:
                self._close_segment(float(t[0]))
                continue
            self._merge_piece(t[:k], V[:k])
            t, V = t[k:], V[k:]
            if len(t):
                self._close_segment(float(t[0]))

    def _walk_reset(self) -> None:
        """Empty the open segment's torque-noise accumulators (see :meth:`_walk_add`)."""
        self._wk_s: float | None = None   # start of the open torque interval [s]
        self._wk_ok = True                # a torque sample at or before the segment's start
        self._wk_ntt = 0                  # torque samples of the segment up to the last gyro
        self._wk_n = 0                    # gyro samples of the segment
        self._wk_t0 = self._wk_tl = 0.0   # first and last gyro time of the segment [s]
        self._wk_ref = np.zeros(13)       # reference row: variables are kept relative to it
        self._wk_S = np.zeros(14)         # sum of x_b = [v_b - ref, 1]
        self._wk_St = np.zeros(14)        # open interval: sum of (t_b - s_J) x_b
        self._wk_h2 = 0.0                 # closed intervals: sum h_j^2, sum h_j Q_j,
        self._wk_hQ = np.zeros(14)        # sum Q_j Q_j'  (Q_j = St_j - h_j F_j, 14 vectors)
        self._wk_QQ = np.zeros((14, 14))

    def _walk_add(self, t: np.ndarray, V: np.ndarray) -> None:
        """Accumulate the open segment's torque-noise statistics over new equations.

        The segment's torque-noise sums (:func:`.statistics.torque_stats` on the segment-demeaned
        variables) are ``P_j = [1 | -mean] R_j`` with ``R_j = sum_b o_j(b) x_b``,
        ``o_j(b) = clip(t_b - s_j, 0, h_j)`` and ``x_b = [v_b - ref, 1]``.  Once torque interval
        ``j`` is closed (a gyro sample at or after its end has arrived), ``R_j = h_j S + Q_j``
        with the running segment sum ``S`` and a fixed ``Q_j``; so ``sum_j R_j R_j'`` needs only
        ``sum h_j^2``, ``sum h_j Q_j`` and ``sum Q_j Q_j'`` of the closed intervals plus the open
        one: O(new samples + new torque samples) per block, none per ``estimate()``.
        """
        ts = self._ts
        n = len(t)
        if self._wk_s is None:
            i = int(np.searchsorted(ts, t[0], side='right')) - 1
            if i < 0:                      # cannot happen: such gyro samples are dropped
                self._wk_ok = False
                i = 0
            self._wk_s = float(ts[i])
            # the first segment's torque list starts at the first torque sample, later ones
            # at the last torque sample at or before their start
            self._wk_ntt = i + 1 if self._first_segment else 1
            self._wk_ref = V[0].copy()
            self._wk_t0 = float(t[0])
        X = np.empty((n, 14))
        np.subtract(V, self._wk_ref[None], out=X[:, :13])
        X[:, 13] = 1.0
        lo = int(np.searchsorted(ts, self._wk_s, side='right'))
        hi = int(np.searchsorted(ts, t[-1], side='right'))
        b = ts[lo:hi]                      # torque samples starting new intervals
        k = len(b)
        if k == 0:
            self._wk_St = self._wk_St + (t - self._wk_s) @ X
        else:
            bounds = np.concatenate([[self._wk_s], b])
            first = np.searchsorted(t, bounds, side='left')
            counts = np.diff(np.append(first, n))
            nz = counts > 0
            u = t - np.repeat(bounds, counts)
            Sm = np.zeros((k + 1, 14))
            St = np.zeros((k + 1, 14))
            Sm[nz] = np.add.reduceat(X, first[nz], axis=0)
            St[nz] = np.add.reduceat(X * u[:, None], first[nz], axis=0)
            h = np.diff(bounds)
            St[0] += self._wk_St
            # every earlier sample precedes the end of the block's first interval
            F = self._wk_S + np.cumsum(Sm[:k], axis=0)
            Q = St[:k] - h[:, None] * F
            self._wk_h2 += float(h @ h)
            self._wk_hQ = self._wk_hQ + h @ Q
            self._wk_QQ = self._wk_QQ + Q.T @ Q
            self._wk_St = St[k]
            self._wk_s = float(bounds[k])
            self._wk_ntt += k
        self._wk_S = self._wk_S + X.sum(axis=0)
        self._wk_n += n
        self._wk_tl = float(t[-1])

    def _segment_walk(self) -> tuple[np.ndarray, float]:
        """Torque-noise Gram (13 x 13) and walk time of the open segment (as statistics)."""
        if self._wk_n == 0 or self._tau_nv.count == 0 or self._wk_ntt < 2 or not self._wk_ok:
            return np.zeros((13, 13)), 0.0
        S, hQ = self._wk_S, self._wk_hQ
        RR = self._wk_h2 * np.outer(S, S) + np.outer(S, hQ) + np.outer(hQ, S) + self._wk_QQ \
            + np.outer(self._wk_St, self._wk_St)
        L = np.empty((13, 14))
        L[:, :13] = np.eye(13)
        L[:, 13] = -S[:13] / self._wk_n
        G = L @ RR @ L.T
        return 0.5 * (G + G.T), self._wk_n * (self._wk_tl - self._wk_t0) / 6.0

    def _close_segment(self, new_start: float) -> None:
        """Fold the current segment's statistics into the closed ones; start a new one."""
        if self._w0 > 0:
            self._Cc = self._Cc + self._C
            self._wc += self._w0
            self._w00c += self._w00
            self._neffc += self._w0 - self._w00 / self._w0
            gp, walk = self._segment_walk()
            self._GPc = self._GPc + gp
            self._walkc += walk
            self._history.add(self._open_segment(gp, walk))
        self._w0 = self._w00 = 0.0
        self._mean = np.zeros(13)
        self._C = np.zeros((13, 13))
        self._walk_reset()
        self._first_segment = False
        self._seg_start = new_start

    def _merge_piece(self, t: np.ndarray, V: np.ndarray) -> None:
        """Merge equations of one segment into the weighted centred statistics."""
        n = len(t)
        self._walk_add(t, V)
        if self.window:
            wts = np.exp(-(t[-1] - t) / self.window)
            # nothing merged yet: nothing to decay (the torque statistics gathered before the
            # first merge must survive it)
            old = float(np.exp(-(t[-1] - self._t_last) / self.window)) \
                if self._t_last is not None else 1.0
        else:
            lam = self.forgetting
            wts = lam ** np.arange(n - 1, -1, -1, dtype=float)
            old = lam ** n
        self._t_last = float(t[-1])
        self._clock += math.log(max(old, 1e-300))
        wb = float(np.sum(wts))
        mb = wts @ V / wb
        D = (V - mb[None]) * np.sqrt(wts)[:, None]
        w_old = old * self._w0
        total = w_old + wb
        delta = mb - self._mean
        self._C = old * self._C + gram(D) + (w_old * wb / total) * np.outer(delta, delta)
        self._mean = self._mean + delta * (wb / total)
        self._w0 = total
        self._w00 = old * old * self._w00 + float(np.sum(wts * wts))
        self._Cc = old * self._Cc
        self._GPc = old * old * self._GPc
        self._walkc *= old
        self._tq_ss = old * self._tq_ss
        self._tq_n *= old
        self._m2_sum = old * self._m2_sum
        self._m2_n *= old
        self._wc *= old
        self._w00c *= old * old
        self._neffc *= old

    def _open_segment(self, gp: np.ndarray, walk: float) -> SegmentStats:
        """The open segment's statistics as a :class:`SegmentStats` (at the current clock)."""
        neff = self._w0 - self._w00 / self._w0 if self._w0 > 0 else 0.0
        return SegmentStats(self._C.copy(), gp, walk, self._w0, self._w00, neff, self._wk_t0,
                            self._wk_tl, self._clock)

    def _window_adequacy(self, f: Fit, nv: np.ndarray, tv: np.ndarray) -> Adequacy:
        """The adequacy tests of ``f``: its parameter set refitted on groups of segments.

        Up to :data:`ADEQUACY_WINDOWS` consecutive groups of the kept segments (the open one
        included), each fitted with the weights of ``f``'s tensor, as the batch estimator does
        on time windows.  Run every ``reselect_every`` estimates; reused in between (with
        ``defer_adequacy`` also at a test estimate, the test left to :meth:`refresh`).
        """
        if self._adequacy_due is not None and self._adequacy_due[0] != self._estimates:
            self._adequacy_due = None         # owed by an earlier estimate: test these data
        elif self._adequacy is not None and self._adequacy_left > 0:
            self._adequacy_left -= 1
            return self._adequacy
        elif self.defer_adequacy and self._adequacy is not None:
            self._adequacy_due = (self._estimates, f, nv, tv)   # the last call's fit wins
            return self._adequacy
        self._adequacy = self._test_adequacy(f, nv, tv)
        self._adequacy_left = self.reselect_every - 1
        return self._adequacy

    def _test_adequacy(self, f: Fit, nv: np.ndarray, tv: np.ndarray) -> Adequacy:
        """The window tests of ``f`` on the current statistics (:meth:`_window_adequacy`)."""
        p, k = len(f.beta), f.basis.shape[1]
        gp, walk = self._segment_walk()
        # as the batch's windows, >= ADEQUACY_MIN_WINDOW_S (a 1 s open segment: chi2 ~2000)
        groups = [g for g in self._history.groups(ADEQUACY_WINDOWS,
                                                  self._open_segment(gp, walk), self._clock)
                  if g.neff >= MIN_EQUATIONS and g.t1 - g.t0 >= ADEQUACY_MIN_WINDOW_S]
        thetas, covs, mids = np.zeros((0, p)), np.zeros((0, p, p)), np.zeros(0)
        if len(groups) >= 2:
            K = np.eye(13)
            K[9, 3:6] = -nv
            theta0 = f.basis @ f.beta[:k]
            fits = []
            for g in groups:
                st = SufficientStats(lift(K.T @ g.C @ K), lift(K.T @ g.GP @ K),
                                     int(round(g.w0)), int(round(g.neff)), 1, kind='anchored',
                                     eiv_var=nv, weighted=True, walk_time=g.walk,
                                     torque_dt=self._tau_dt, omega_m2=self._omega_m2(),
                                     gyro_dt=self._gyro_dt(), white_y_cov=self._white_y_cov)
                fk = fit_two_pass(st, f.basis, f.bias, nv, tv, None, theta0)
                fits.append((fk.beta, fk.cov * (g.w00 / g.w0), 0.5 * (g.t0 + g.t1)))
            thetas = np.array([x[0] for x in fits])
            covs = np.array([x[1] for x in fits])
            mids = np.array([x[2] for x in fits])
        return check_adequacy(thetas, covs, mids, f.excess)

    def refresh(self) -> bool:
        """Run the adequacy test the last estimate deferred (``defer_adequacy``), if any: call
        it before new samples are merged, so that it tests that estimate's statistics and fit.

        Returns
        -------
        bool
            True when a test ran.
        """
        if self._adequacy_due is None:
            return False
        (_, f, nv, tv), self._adequacy_due = self._adequacy_due, None
        self._adequacy = self._test_adequacy(f, nv, tv)
        self._adequacy_left = self.reselect_every - 1
        return True

    def _omega_m2(self) -> np.ndarray:
        """``mean(w w')`` of the merged gyro samples [rad^2/s^2] (decayed as the weights)."""
        return self._m2_sum / max(self._m2_n, 1e-300)

    def _gyro_dt(self) -> float:
        """Median recent gyro sample interval [s] (0 before two samples)."""
        return self._g_dt            # kept by _gaps

    # -----------------------------------------------------------------------------------------
    def _gyro_var(self) -> np.ndarray:
        """Gyro white-noise variance per axis [rad^2/s^2]: given, or the streaming estimate."""
        if self._gyro_noise is not None:
            return self._gyro_noise ** 2
        return self._gyro_nv.variance()

    def _torque_variance(self) -> np.ndarray | None:
        """Torque white-noise variance per axis (None before 16 samples); the hook where a
        momentum input states its own (:mod:`.recursive_momentum`)."""
        return self._tau_nv.variance() if self._tau_nv.count >= 16 else None

    def _stats(self, nv: np.ndarray, n_eff: float, gyro_scale: float = 1.0) -> SufficientStats:
        """The weighted statistics of everything merged, in the batch estimator's form.

        The gyro-noise correction of the squared-rate integrals, ``m_c -> m_c - sigma_c^2 s``,
        is linear in the 13 variables (``K``) and applied here with the current noise level.
        ``gyro_scale`` gives the statistics of a gyro read that many times larger (``w`` and
        the squared-rate integrals scale exactly; for the gyro-scale sensitivity).
        """
        K = np.eye(13)
        K[9, 3:6] = -nv
        if gyro_scale != 1.0:
            K = np.diag(np.r_[np.full(3, gyro_scale), np.full(6, gyro_scale ** 2),
                              np.ones(4)]) @ K
        C_all = lift(K.T @ (self._C + self._Cc) @ K)
        gp, walk = self._segment_walk()
        CP = lift(K.T @ (self._GPc + gp) @ K) if self._tau_var is not None else None
        return SufficientStats(C_all, CP, int(round(self._w0 + self._wc)), int(round(n_eff)), 1,
                               kind='anchored', eiv_var=nv, weighted=True,
                               walk_time=self._walkc + walk, torque_dt=self._tau_dt,
                               omega_m2=self._omega_m2(), gyro_dt=self._gyro_dt(),
                               white_y_cov=self._white_y_cov)

    def estimate(self) -> InertiaEstimate:
        """Current estimate from everything merged so far (flushes covered samples first).

        Returns
        -------
        InertiaEstimate
            ``method='recursive'``; standard errors from the same noise model as the batch
            method (white gyro noise, integrated torque noise per segment), scaled up by the
            residual variance when that is larger.
        """
        self._process()
        self._estimates += 1
        base = dict(method='recursive', samples_used=self.samples_used,
                    samples_dropped=self.samples_dropped)
        nv = self._gyro_var()
        diag: dict[str, Any] = {'gyro_noise_std': np.sqrt(nv), 'warnings': [],
                                'effective_samples': self._w0 + self._wc}
        if self.gaps:
            diag['warnings'].append(f'{self.gaps} gap(s) in the streams: each started a new '
                                    'segment; gyro samples inside torque gaps were dropped')
        n_eff = self._neffc + (self._w0 - self._w00 / self._w0 if self._w0 > 0 else 0.0)
        self._tau_var = self._torque_variance()
        if self.samples_used < MIN_GYRO_SAMPLES or n_eff < MIN_EQUATIONS:
            diag['reason'] = f'only {self.samples_used} gyro samples covered by torque so far'
            return status_only('insufficient_data', diag, base)
        # torque-free data (the batch rule): the scale is unobservable, the ratios and the
        # principal axes come from the null vector of the homogeneous problem
        torque_rms = np.sqrt(self._tq_ss / max(self._tq_n, 1e-300))
        diag['torque_rms'] = torque_rms
        tq_std = np.sqrt(self._tau_var) if self._tau_var is not None else np.zeros(3)
        diag['torque_noise_std'] = tq_std
        st = self._stats(nv, n_eff)
        # the meat of weighted sums scales by w^2 / w
        ratio = (self._w00 + self._w00c) / (self._w0 + self._wc)
        if is_torque_free(torque_rms, tq_std):
            diag['warnings'] += unapplied('recursive', self.policy)
            return homogeneous_estimate(st, nv, diag, base, cov_scale=ratio)
        tv = self._tau_var if self._tau_var is not None else np.zeros(3)

        def fit(basis: np.ndarray, bias: bool, offset: np.ndarray | None = None,
                theta0: np.ndarray | None = None) -> Fit:
            """Fit on the weighted statistics; the meat of weighted sums scales by w^2/w."""
            f = fit_two_pass(st, basis, bias, nv, tv, offset, theta0)
            f.cov = f.cov * ratio
            return f

        def adequacy(f: Fit, chosen: str) -> Adequacy:
            """Window consistency over the kept segments and the residual excess."""
            return self._window_adequacy(f, nv, tv)

        def gyro_sensitivity(f: Fit) -> np.ndarray:
            """``d beta / d g``: refit of the statistics of a gyro read 1e-4 larger."""
            k = f.basis.shape[1]
            theta0 = f.basis @ f.beta[:k] + (0.0 if f.offset is None else f.offset)
            b = [fit_two_pass(self._stats(nv, n_eff, s), f.basis, f.bias, nv, tv, f.offset,
                              theta0).beta for s in (1.0, 1.0 + 1e-4)]
            return (b[1] - b[0]) / 1e-4

        return self._conclude(fit, diag, base, adequacy, gyro_sensitivity)

    def _conclude(self, fit: Any, diag: dict[str, Any], base: dict[str, Any],
                  adequacy: Any, sensitivity: Any) -> InertiaEstimate:
        """Model selection (reused between re-selections) and the result."""
        auto = self.model == 'auto' or self.torque_bias == 'auto'
        if auto and self._selection is not None and self._selection_left > 0:
            self._selection_left -= 1
            bias, model, record = self._selection
            est = conclude(fit, model, bias, self.axis, self.policy,
                           dict(diag, warnings=list(diag['warnings'])), base, adequacy,
                           sensitivity)
            if est.status in ('ok', 'model_mismatch'):
                est.diagnostics['model_selection'] = dict(record, reused=True)
                return est
        est = conclude(fit, self.model, self.torque_bias, self.axis, self.policy, diag, base,
                       adequacy, sensitivity)
        self._selection = None
        if auto and est.status in ('ok', 'model_mismatch'):
            record = dict(est.diagnostics.get('model_selection') or {},
                          selected_at_samples=self.samples_used)
            est.diagnostics['model_selection'] = record
            self._selection = ('on' if est.model.endswith('+bias') else 'off',
                               est.model.removesuffix('+bias'), record)
            self._selection_left = self.reselect_every - 1
        return est
