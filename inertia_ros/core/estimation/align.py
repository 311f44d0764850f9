"""One gap rule and one momentum interpolation for the batch and online momentum paths.

A stream's sample interval longer than :data:`~.options.GAP_FACTOR` nominal (median)
intervals is a gap: nothing is known of the stream inside it.  For internal momentum ``h``
(wheels, rotors) the batch reduction (:func:`.momentum.equivalent_torque`) and the online one
(:class:`.recursive_momentum.MomentumRecursiveEstimator`) apply the same rule through
:func:`gap_starts`: the gyro samples strictly inside a gap are dropped, the equations on
either side belong to different anchored segments (whose intercepts take the unknown change
of ``h``), and ``h`` is interpolated between its samples (:func:`hermite`) with slopes taken
within each gap-free run only (:func:`run_slopes`), never across a gap.

:class:`OnlineAligner` is the online estimator's alignment of the gyro to the held torque,
block by block: coverage, the torque and gyro gap rule (the same factor over recent nominal
intervals) and the anchored equations' variables.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .noise import median_rows
from .options import GAP_FACTOR
from .regressors import cumtrapz, cumulative_torque, monomials

__all__ = ['OnlineAligner', 'cross_matrices', 'cumtrapz', 'gap_starts', 'hermite',
           'hermite_basis', 'hermite_weights', 'inside_gaps', 'run_slopes']

_DT_HISTORY = 64        # recent sample intervals kept per stream for the nominal interval


def gap_starts(t: np.ndarray, nominal: float | None = None) -> np.ndarray:
    """Indices ``i`` whose interval ``[t[i], t[i+1]]`` is a gap.

    Parameters
    ----------
    t : ndarray, shape (K,)
        Strictly increasing sample times [s].
    nominal : float, optional
        The stream's nominal sample interval [s]; default the median interval of ``t``.

    Returns
    -------
    ndarray of int, shape (n_gaps,)
        Sorted; empty with fewer than 3 samples (no nominal interval to compare with).
    """
    if len(t) < 3 and nominal is None:
        return np.zeros(0, dtype=int)
    dt = np.diff(t)
    nom = float(np.median(dt)) if nominal is None else float(nominal)
    return np.flatnonzero(dt > GAP_FACTOR * nom)


def inside_gaps(t_h: np.ndarray, gaps: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Which times ``t`` (n,) lie strictly inside one of the gaps ``gaps`` of ``t_h``.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    out = np.zeros(len(t), dtype=bool)
    if len(gaps) == 0:
        return out
    j = np.searchsorted(t_h, t, side='right') - 1        # last sample at or before t
    in_range = (j >= 0) & (j < len(t_h) - 1)
    is_gap = np.zeros(len(t_h), dtype=bool)
    is_gap[gaps] = True
    out[in_range] = is_gap[j[in_range]] & (t[in_range] > t_h[j[in_range]])
    return out


def run_slopes(t_h: np.ndarray, h: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """Slopes ``dh/dt`` (K, ...) for Hermite interpolation: ``np.gradient`` within each
    gap-free run of samples (one-sided at its ends), 0 for a run of one sample.

    Parameters
    ----------
    t_h : ndarray, shape (K,)
        Sample times [s].
    h : ndarray, shape (K, ...)
        Samples (along axis 0).
    gaps : ndarray of int
        :func:`gap_starts` of ``t_h``.
    """
    if len(t_h) < 2:
        return np.zeros_like(h)
    if len(gaps) == 0:
        return np.gradient(h, t_h, axis=0)
    out = np.zeros_like(h)
    edges = np.concatenate([[0], np.asarray(gaps) + 1, [len(t_h)]])
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if b - a >= 2:
            out[a:b] = np.gradient(h[a:b], t_h[a:b], axis=0)
    return out


def hermite(t_h: np.ndarray, h: np.ndarray, slopes: np.ndarray, t: np.ndarray,
            basis: tuple[np.ndarray, tuple[np.ndarray, ...]] | None = None) -> np.ndarray:
    """Cubic Hermite interpolation of ``h`` (K, c) with ``slopes`` (K, c) at ``t`` (n,).

    ``t`` must lie in ``[t_h[0], t_h[-1]]``; K >= 2.  Returns (n, c).  ``basis``: the
    :func:`hermite_basis` of ``t_h`` and ``t``, when several ``h`` share the stamps.
    """
    j, (a, b, c, d) = hermite_basis(t_h, t) if basis is None else basis
    return a * h[j] + b * slopes[j] + c * h[j + 1] + d * slopes[j + 1]


def hermite_basis(t_h: np.ndarray, t: np.ndarray
                  ) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """The interval ``j`` (n,) of each time ``t`` in ``t_h`` and the weights (n, 1) of
    ``h[j]``, ``slopes[j]``, ``h[j + 1]`` and ``slopes[j + 1]`` in :func:`hermite`."""
    j = np.clip(np.searchsorted(t_h, t, side='right') - 1, 0, len(t_h) - 2)
    dx = (t_h[j + 1] - t_h[j])[:, None]
    return j, hermite_weights((t - t_h[j])[:, None] / dx, dx)


def hermite_weights(u: np.ndarray, dx: np.ndarray) -> tuple[np.ndarray, ...]:
    """Cubic Hermite weights at the relative times ``u`` (...) of intervals ``dx`` [s]
    (broadcast with ``u``): ``x(s + u dx) = H0 x0 + H1 x0' + H2 x1 + H3 x1'`` from the values
    and derivatives at both ends (the derivative weights carry ``dx``); the package's one
    form (:func:`hermite` and the ``ml`` method's slots alike)."""
    u2 = u * u
    u3 = u2 * u
    return 2 * u3 - 3 * u2 + 1, (u3 - 2 * u2 + u) * dx, 3 * u2 - 2 * u3, (u3 - u2) * dx


def cross_matrices(v: np.ndarray) -> np.ndarray:
    """``[v]x`` (n, 3, 3) with ``[v]x u = v x u`` for each row of ``v`` (n, 3)."""
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    return out - out.transpose(0, 2, 1)


class OnlineAligner:
    """The online estimator's alignment of the gyro to the held torque, block by block.

    It owns the held torque stream (samples from the last one at or before the last merged
    gyro sample, and the integral up to it), the recent sample intervals of both streams
    (the nominal intervals of the gap rule) and the continuation of the monomial integral.
    :meth:`ready` splits gyro samples into covered and waiting ones, :meth:`gaps` applies the
    gap rule, :meth:`variables` turns covered samples into the 13 variables ``[w, m, t, T]``
    of the anchored equations (22 with :attr:`attitude`: the inertial torque's nine after
    them) and :meth:`trim` drops the torque samples no longer needed.
    """

    def __init__(self, extra: int = 0) -> None:
        self.ts = np.empty(0)
        #: the torque (n, 3) and ``extra`` held columns after it (the stated inputs' changes of
        #: a momentum input's equivalent torque: :mod:`.online_stated`), integrated alike
        self.tau = np.empty((0, 3 + extra))
        #: a second torque on the same stamps (a momentum input's equivalent torque with the
        #: other torque linear: :mod:`.online_hold`), or None
        self.tau_alt: np.ndarray | None = None
        self.T_base = np.zeros(3 + extra)       # torque integral at self.ts[0]
        self.t0: float | None = None    # time origin of the bias column
        self.prev: tuple[float, np.ndarray] | None = None   # last processed gyro sample
        self.M = np.zeros(6)            # monomial integral at the last processed sample
        self.tau_dt = 0.0               # median recent torque interval [s]
        self.tq_dts = np.empty(0)       # recent torque / gyro sample intervals [s]
        self.g_dts = np.empty(0)
        self.g_dt = 0.0                 # their median (0 before two samples)
        self.tq_last: float | None = None
        #: the carried attitude of the inertial torque (:class:`.online_inertial.
        #: AttitudeState`, advanced over every covered gyro sample by :meth:`gaps`), or None
        self.attitude: Any = None
        self._c = np.zeros((0, 9))      # its ``vec C`` (n, 9) of the samples gaps() kept

    def take(self, new_t: np.ndarray, new_tau: np.ndarray,
             new_alt: np.ndarray | None = None) -> None:
        """Append torque samples ``new_tau`` (n, 3) [N m] at ``new_t`` (n,) [s] (and those of
        the second torque, ``new_alt`` (n, 3), when one is kept)."""
        self.ts = np.concatenate([self.ts, new_t])
        self.tau = np.concatenate([self.tau, new_tau])
        if new_alt is not None:
            old = self.tau_alt if self.tau_alt is not None else np.empty((0, 3))
            self.tau_alt = np.concatenate([old, new_alt])
        edges = new_t if self.tq_last is None else np.concatenate([[self.tq_last], new_t])
        self.tq_dts = np.concatenate([self.tq_dts, np.diff(edges)])[-_DT_HISTORY:]
        self.tq_last = float(new_t[-1])
        if len(self.tq_dts):
            self.tau_dt = float(median_rows(self.tq_dts[:, None])[0])   # np.median, faster

    def ready(self, t: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                           np.ndarray, int, bool]:
        """Split gyro samples ``t`` (n,), ``w`` (n, 3) by the torque's coverage.

        Returns the covered samples, those waiting for torque, the count dropped (before the
        first torque sample: never usable) and whether any torque has arrived (without, all
        wait and nothing is dropped).
        """
        if len(self.ts) == 0:
            return t[:0], w[:0], t, w, 0, False
        early = t < self.ts[0]
        dropped = int(np.sum(early))
        if dropped:
            t, w = t[~early], w[~early]
        ready = t <= self.ts[-1]
        return t[ready], w[ready], t[~ready], w[~ready], dropped, True

    def variables(self, t: np.ndarray, w: np.ndarray, hold: str) -> np.ndarray:
        """The variables ``V`` (n, 13) ``[w, m, t - t0, T]`` of covered gyro samples, (n, 22)
        with :attr:`attitude` (``vec C`` of the samples :meth:`gaps` kept, after them).

        ``T`` is the torque integral at the gyro times (``hold`` between torque samples) and
        ``m`` the raw monomial integrals: the gyro-noise correction ``m - s sigma^2`` is
        linear in the variables, applied to the statistics with the final noise estimate.
        """
        T = self.T_base + cumulative_torque(self.ts, self.tau, t, hold,
                                            out=np.empty((len(t), self.tau.shape[1])))
        M = self._monomials(t, w)
        parts = [w, M, (t - self.t0)[:, None], T]
        if self.attitude is not None:
            if len(self._c) != len(t):
                raise RuntimeError('OnlineAligner.variables: call gaps() on the block first')
            parts.append(self._c)
        return np.concatenate(parts, axis=1)

    def trim(self, t_last: float, hold: str) -> None:
        """Keep torque samples from the last one at or before ``t_last`` [s] (the last merged
        gyro time), folding the integral before it into ``T_base``."""
        j = int(np.searchsorted(self.ts, t_last, side='right') - 1)
        if j > 0:
            self.T_base = self.T_base + cumulative_torque(
                self.ts, self.tau, self.ts[j:j + 1], hold, out=np.empty((1, len(self.T_base))))[0]
            self.ts = self.ts[j:]
            self.tau = self.tau[j:]
            if self.tau_alt is not None:
                self.tau_alt = self.tau_alt[j:]

    def _monomials(self, t: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Trapezoid integral (n, 6) of the monomials, continuing from the last sample."""
        m = monomials(w)
        if self.prev is None:
            tt = t
            mm = m
            start = np.zeros(6)
            self.t0 = float(t[0])
        else:
            tt = np.concatenate([[self.prev[0]], t])
            mm = np.concatenate([monomials(self.prev[1][None, :]), m])
            start = self.M
        inc = 0.5 * (mm[1:] + mm[:-1]) * np.diff(tt)[:, None]
        M = np.empty((len(t), 6))
        if self.prev is None:
            M[0] = start
            np.cumsum(inc, axis=0, out=M[1:])
            M[1:] += start
        else:
            np.cumsum(inc, axis=0, out=M)
            M += start
        self.M = M[-1].copy()
        self.prev = (float(t[-1]), w[-1].copy())
        return M

    def gaps(self, t: np.ndarray, w: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, list[int], int]:
        """Drop gyro samples inside torque gaps; find where gaps force a new segment.

        A torque interval longer than ``GAP_FACTOR`` nominal intervals (lost messages, a
        paused controller) would be integrated as the last command held throughout, and a
        gyro gap would be bridged by one trapezoid: both corrupt every later equation of the
        segment.  Gyro samples the held torque cannot cover are dropped (counted), and the
        first sample after each gap starts a new anchored segment.  The :attr:`attitude`, if
        any, is advanced over every sample first (its own gap rule: bridged or stopped).

        Returns
        -------
        t, w : ndarray
            The kept gyro samples.
        breaks : list of int
            Sorted indices into the kept ``t`` where a new segment starts.
        dropped : int
            Gyro samples dropped inside torque gaps.
        """
        starts: list[float] = []
        keep = np.ones(len(t), dtype=bool)
        if len(self.tq_dts) >= 2 and len(self.ts) >= 2:
            nominal = self.tau_dt           # the median of self.tq_dts (take)
            dq = np.diff(self.ts)
            for i in np.flatnonzero(dq > GAP_FACTOR * nominal):
                keep &= ~((t > self.ts[i] + nominal) & (t < self.ts[i + 1]))
                starts.append(float(self.ts[i + 1]))
        edges = t if self.prev is None else np.concatenate([[self.prev[0]], t])
        dg = np.diff(edges)
        self.g_dts = np.concatenate([self.g_dts, dg])[-_DT_HISTORY:]
        self.g_dt = float(median_rows(self.g_dts[:, None])[0]) if len(self.g_dts) else 0.0
        if len(self.g_dts) >= 2:
            big = np.flatnonzero(dg > GAP_FACTOR * self.g_dt)
            starts.extend(float(edges[i + 1]) for i in big)
        if self.attitude is not None:
            self._c = self.attitude.advance(t, w, self.g_dt if len(self.g_dts) >= 2 else None)
        if not starts:
            return t, w, [], 0
        dropped = int(np.sum(~keep))
        t, w = t[keep], w[keep]
        if self.attitude is not None:
            self._c = self._c[keep]
        breaks = sorted({int(np.searchsorted(t, b, side='left')) for b in starts})
        return t, w, [k for k in breaks if k < len(t)], dropped
