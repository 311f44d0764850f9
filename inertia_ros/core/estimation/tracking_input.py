"""The input side of :class:`.tracking.TrackingEstimator`: streams to blocks.

:class:`StreamInput` buffers the gyro samples until the torque covers them, keeps the
streams' nominal intervals and noise levels (and the filter's weights from them), collects
the start-up samples, cuts the covered samples into blocks of ``block`` seconds and handles
the gaps of either stream (re-anchoring after them, :meth:`_reanchor`).  The filter itself
(:meth:`_initialise`, :meth:`_block`) is the estimator's; this mixin decides what reaches it
and when.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .._validate import as_sample_block, require_after
from ..tensor import theta_to_matrix
from .align import gap_starts
from .noise import TRACKER_NOISE_EVERY, gyroscopic_walk_cov
from .options import GAP_FACTOR
from .regressors import momentum_matrix

__all__ = ['StreamInput']

_DT_HISTORY = 64          # recent sample intervals kept per stream for the nominal interval
_MAX_BUFFER = 400_000     # gyro samples kept waiting for torque
_WARM_KEEP = 5.0          # start-up samples kept while undetermined [warmup lengths]
_REFRESH = 0.25           # data time between re-derivations of the weights [s]


class StreamInput:
    """Buffering, alignment, noise levels and blocks of the tracker (a mixin: the state is
    the estimator's, made by its ``reset``)."""

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Add gyro samples: ``t`` (n,) [s] increasing across calls, ``omega`` (n, 3) [rad/s]."""
        ta, wa = as_sample_block(t, omega, 'omega')
        if len(ta) == 0:
            return
        require_after(ta[0], self._last_t_in, 'omega')
        self._last_t_in = float(ta[-1])
        self._gt.append(ta)
        self._gw.append(wa)
        if sum(len(x) for x in self._gt) > _MAX_BUFFER:        # torque stalled: keep newest
            t, w = np.concatenate(self._gt), np.concatenate(self._gw)
            self.samples_dropped += len(t) - _MAX_BUFFER // 2
            self._gt, self._gw = [t[-(_MAX_BUFFER // 2):]], [w[-(_MAX_BUFFER // 2):]]
        if len(self._ts):
            self._process()

    def add_torque(self, t: Any, tau: Any) -> None:
        """Add torque samples: ``t`` (n,) [s] increasing across calls, ``tau`` (n, 3) [N m]."""
        ta, xa = as_sample_block(t, tau, 'torque')
        if len(ta) == 0:
            return
        require_after(ta[0], self._last_tau_in, 'torque')
        edges = ta if self._last_tau_in is None else np.concatenate([[self._last_tau_in], ta])
        self._tq_dts = np.concatenate([self._tq_dts, np.diff(edges)])[-_DT_HISTORY:]
        self._last_tau_in = float(ta[-1])
        self._ts = np.concatenate([self._ts, ta])
        self._tau = np.concatenate([self._tau, xa])
        self._tau_nv.add(xa)
        if self._gt:
            self._process()

    def _process(self) -> None:
        """Fold in the buffered gyro samples the torque now covers, block by block."""
        if not self._gt or len(self._ts) == 0:
            return
        t, w = np.concatenate(self._gt), np.concatenate(self._gw)
        early = t < self._ts[0]
        if np.any(early):                                # before any torque: never usable
            self.samples_dropped += int(np.sum(early))
            t, w = t[~early], w[~early]
        ready = t <= self._ts[-1]
        self._gt, self._gw = ([t[~ready]], [w[~ready]]) if not np.all(ready) else ([], [])
        t, w = t[ready], w[ready]
        if len(t) == 0:
            return
        if self._gyro_noise is None:
            self._gyro_nv.add(w)
        self._m2_sum = self._m2_sum + w.T @ w
        self._m2_n += len(w)
        last = self._warm[-1][0][-1] if self._warm else self._prev[0] if self._prev else None
        edges = t if last is None else np.concatenate([[last], t])
        self._g_dts = np.concatenate([self._g_dts, np.diff(edges)])[-_DT_HISTORY:]
        self.samples_used += len(t)
        self._refresh_noise()
        if self._warm is None:
            self._fold_in(t, w, flush=False)
            return
        self._warm.append((t, w))
        while len(self._warm) > 1 and t[-1] - self._warm[1][0][0] >= _WARM_KEEP * self.warmup:
            del self._warm[0]                  # never determined yet: keep the newest only
        j = int(np.searchsorted(self._ts, self._warm[0][0][0], side='right')) - 1
        if j > 0:
            self._ts, self._tau = self._ts[j:], self._tau[j:]
        span = t[-1] - self._warm[0][0][0]
        if span >= self.warmup and t[-1] - self._tried >= 0.25 * self.warmup:
            self._tried = float(t[-1])
            self._initialise()

    def _refresh_noise(self) -> None:
        """Re-read the streams' noise levels every :data:`.noise.TRACKER_NOISE_EVERY` gyro
        samples (they are medians over thousands of samples: once a block would cost more
        than the rest)."""
        if self._warm is None and self.samples_used - self._noise_at < TRACKER_NOISE_EVERY:
            return
        self._noise_at = self.samples_used
        if self._gyro_noise is not None:
            self._nv = self._gyro_noise ** 2
        else:
            v = self._gyro_nv.variance()
            self._nv = v if np.any(v > 0) else np.full(3, 1e-12)
        self._tv = self._tau_nv.variance() if self._tau_nv.known() else np.zeros(3)

    def _fold_in(self, t: np.ndarray, w: np.ndarray, flush: bool) -> None:
        """Fold in the pending samples and ``t`` (n,), ``w`` (n, 3): every full block, and
        the last partial one only with ``flush``."""
        if self._pend is not None:
            t = np.concatenate([self._pend[0], t])
            w = np.concatenate([self._pend[1], w])
            self._pend = None
        lo = self._run(t, w, flush)
        if lo < len(t):
            self._pend = (t[lo:], w[lo:])
        self._trim_torque()

    def _run(self, t: np.ndarray, w: np.ndarray, flush: bool = True) -> int:
        """Fold in samples ``t`` (n,), ``w`` (n, 3) in blocks of ``block`` seconds; return
        where the unfolded rest starts.  Across a gap of either stream (an interval over
        ``GAP_FACTOR`` nominal ones) the filter re-anchors after it (:meth:`_reanchor`)."""
        lo = 0
        gap = GAP_FACTOR * (self._gdt if self._gdt > 0 else math.inf)
        while lo < len(t):
            end = self._prev[0] + self.block
            hi = max(int(np.searchsorted(t, end - 1e-9, side='right')), lo + 1)
            after = self._torque_gap(float(t[hi - 1]))
            if after is not None:                      # samples the held torque misses
                skip = int(np.searchsorted(t, after, side='left'))
                self.samples_dropped += skip - lo
                if skip >= len(t):
                    return len(t)
                self._reanchor(float(t[skip]), w[skip])
                lo = skip + 1
                continue
            if t[lo] - self._prev[0] > gap:
                self._reanchor(float(t[lo]), w[lo])
                lo += 1
                continue
            step = np.flatnonzero(np.diff(t[lo:hi]) > gap)
            if len(step):
                hi = lo + int(step[0]) + 1
            elif hi == len(t) and t[-1] < end - 1e-9 and not flush:
                break                                   # a partial block: wait for more
            self._block(t[lo:hi], w[lo:hi])
            lo = hi
        return lo

    def _torque_gap(self, t: float) -> float | None:
        """The end [s] of a torque gap between the anchor and ``t``, or None."""
        if self._tdt <= 0:
            return None
        a = max(int(np.searchsorted(self._ts, self._prev[0], side='right')) - 1, 0)
        b = int(np.searchsorted(self._ts, t, side='left'))
        long = gap_starts(self._ts[a:b + 1], self._tdt)        # the one gap rule
        return float(self._ts[a + long[-1] + 1]) if len(long) else None

    def _trim_torque(self) -> None:
        """Drop torque samples no longer needed (keep the one at or before the anchor)."""
        if self._prev is None or self._warm is not None:
            return
        j = int(np.searchsorted(self._ts, self._prev[0], side='right')) - 1
        if j > 0:
            self._ts, self._tau = self._ts[j:], self._tau[j:]

    def _cached(self, end: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The weights ``R`` and the gyro variance, re-derived (with the momentum's walk and
        the nominal sample intervals) every :data:`_REFRESH` s of data or when the weights'
        tensor was set: they move slowly, and deriving them costs more than a block.  With
        ``end`` [s], the block from the anchor to ``end`` is next: ``self._walk`` becomes its
        walk (:meth:`_block_walk`)."""
        t = self._prev[0]
        if self._R is None or t - self._R_at >= _REFRESH or self._R_for is not self._R_theta:
            self._R, self._nv_R = self._weight()
            self._R_at, self._R_for = t, self._R_theta
            self._gdt = float(np.median(self._g_dts)) if len(self._g_dts) else 0.0
            self._tdt = float(np.median(self._tq_dts)) if len(self._tq_dts) else 0.0
            self._walk_rate = self._momentum_walk(self._nv_R)
            E = momentum_matrix(np.eye(3)) @ self.basis           # (3, 3, k): L(e_c) T
            self._B = np.einsum('c,cik,ij,cjl->kl', self._nv_R, E, np.linalg.inv(self._R), E)
        self._walk = self._walk_rate if end is None else self._block_walk(t, end)
        return self._R, self._nv_R

    def _block_walk(self, start: float, end: float) -> np.ndarray:
        """The momentum's variance rate [N^2 m^2 s] (3, 3) over the block from ``start`` to
        ``end`` [s]: here the stationary one (:meth:`_momentum_walk`); a momentum input's
        follows its ``|h(t)|`` and ``|w(t)|`` (:class:`.recursive_momentum.
        MomentumTrackingEstimator`)."""
        return self._walk_rate

    def _momentum_walk(self, nv: np.ndarray) -> np.ndarray:
        """Variance rate of the momentum [N^2 m^2 s]: integrated torque noise and the gyro
        noise integrated by the gyroscopic term (:func:`.noise.gyroscopic_walk_cov`)."""
        tdt = float(np.median(self._tq_dts)) if len(self._tq_dts) else 0.0
        if tdt <= 0:
            return np.zeros((3, 3))
        gdt = float(np.median(self._g_dts)) if len(self._g_dts) else 0.0
        I = theta_to_matrix(self.basis @ self.x[:self.k], check_finite=False)
        m2 = self._m2_sum / max(self._m2_n, 1.0)
        G = gyroscopic_walk_cov(I, nv, m2, gdt, tdt) if np.all(np.isfinite(I)) else 0.0
        return tdt * (np.diag(self._tv) + G)

    def _reanchor(self, t: float, w: np.ndarray) -> None:
        """Across a gap: anchor at ``(t, w)`` with the momentum ``L = I w`` of the current
        tensor (covariance from the tensor's and the gyro noise's)."""
        R, _nv = self._cached()
        A = np.zeros((3, self.n))
        A[:, :self.k] = momentum_matrix(w) @ self.basis
        L = slice(self.n - 3, self.n)
        AP = A @ self.P
        self.x[L] = A @ self.x
        self.P[L, :] = AP
        self.P[:, L] = AP.T
        self.P[L, L] = AP @ A.T + R
        self._prev = (t, w.copy())
        self.gaps += 1
