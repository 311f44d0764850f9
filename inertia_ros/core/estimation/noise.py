"""White-noise levels from the data: one estimator, in a batch and a streaming form.

The quantity is the white-noise standard deviation of a sampled signal (gyro [rad/s] or torque
[N m]) per axis.  For white noise of variance ``s^2`` the k-th difference has variance
``C(2k, k) s^2`` (20 s^2 for k = 3), while a smooth signal contributes little to high-order
differences.  The two forms are one estimator of that quantity:

* :func:`noise_std_from_differences` (batch: :func:`~.batch.estimate`): robust, the median
  absolute deviation of the 2nd, 3rd and 4th differences, the smallest of the three (signal
  only adds variance), divided by that minimum's own low bias on white noise (the square
  is unbiased for the white-noise variance at every length, :data:`MIN_SELECTION_BIAS`);
* :class:`StreamingNoise` (both streams of the online estimator): the same function on the
  most recent :data:`STREAM_NOISE_SAMPLES` samples of the stream, kept across blocks, so the
  answer does not depend on how the stream was cut into blocks (the node hands over 5 torque
  samples at a time; a per-block estimate would be no estimate) and memory stays bounded.

Both gyro estimates are floored at :data:`ISOTROPY_FLOOR` of the largest axis
(:func:`isotropy_floor`): a nearly noise-free axis would otherwise get an absurd weight.
"""
from __future__ import annotations

import math

import numpy as np

from .._numeric import median_rows

__all__ = ['ISOTROPY_FLOOR', 'MIN_NOISE_SAMPLES', 'MIN_SELECTION_BIAS', 'STREAM_NOISE_SAMPLES',
           'STREAM_NOISE_STRIDE', 'TRACKER_NOISE_EVERY', 'StreamingNoise', 'gyroscopic_walk_cov',
           'isotropy_floor', 'median_rows', 'min_selection_bias', 'noise_std_from_differences',
           'walk_maps']

#: Smallest gyro-noise std of an axis, as a share of the largest axis' std.
ISOTROPY_FLOOR = 0.1
#: Samples of a stream the online noise estimate looks at (the most recent ones).
STREAM_NOISE_SAMPLES = 4096
#: Samples between two noise estimates of a long stream (a quarter of the kept ones).
STREAM_NOISE_STRIDE = 1024
#: Gyro samples between the tracker's re-readings of its streams' noise levels: the same
#: idea as :data:`STREAM_NOISE_STRIDE`, kept apart (issue 26, rule (c)) because 1024 fails
#: the tracker's stated-wheel-inertia test (a diagonal sigma then grows less than 4x).
TRACKER_NOISE_EVERY = 500
#: Samples a stream needs before its streaming estimate stands for its white noise (before,
#: each estimator's fallback): the torque's, the momentum input's (which had 6, the fewest
#: :func:`noise_std_from_differences` answers from; 16 changed no report or online test).
MIN_NOISE_SAMPLES = 16
#: ``(a, b, c)`` of ``E[s^2] / sigma^2 = 1 - a / sqrt(n) + b / n + c / n^1.5`` for the minimum
#: ``s`` over the orders (2, 3, 4) on ``n`` samples of white noise of std ``sigma`` (a least
#: squares fit to 32 Monte-Carlo lengths from 16 to 50 000, 3e7 samples each: residuals
#: within 2e-3; the ratio is 0.913 at 16, 0.951 at 200, 0.974 at 1000, 0.987 at 4096).
MIN_SELECTION_BIAS = (0.983, 4.66, -8.33)


def isotropy_floor(std: np.ndarray) -> np.ndarray:
    """Per-axis noise std raised to at least :data:`ISOTROPY_FLOOR` of the largest, shape (3,)."""
    return np.maximum(std, ISOTROPY_FLOOR * float(np.max(std)))


def noise_std_from_differences(x: np.ndarray, orders: tuple[int, ...] = (2, 3, 4),
                               max_samples: int = 50_000) -> np.ndarray:
    """Robust white-noise standard deviation per column from high-order differences.

    For white noise of variance ``s^2`` the k-th difference has variance ``C(2k, k) s^2``;
    a smooth signal contributes little to high-order differences, a line near the Nyquist
    frequency more to high than to low orders.  The median absolute deviation makes each
    order's estimate robust to occasional jumps (steps, PRBS), and the smallest estimate over
    ``orders`` is the least contaminated one (signal only adds variance).

    That minimum is biased low on white noise: the three orders' estimates scatter about the
    truth (their logarithms correlate 0.85) and the smallest is picked: 2.6 % low in variance
    at 1000 samples, 4.9 % at 200, 6.0 % at 100 (all orders clean, the selection's worst
    case).  Over the default orders it is divided by ``sqrt(E[s^2] / sigma^2)`` of white
    noise on the same number of samples (:func:`min_selection_bias`), so its square is
    unbiased for the white-noise variance at every length from :data:`MIN_NOISE_SAMPLES` on.
    What the minimum was for is kept: it is the same minimum over the same robust estimates,
    scaled by a known factor that tends to 1 (1.032 in std at 100 samples, 1.013 at 1000).
    Where a signal makes one order the clear minimum (a smooth signal in the 2nd difference,
    steps in the higher ones) the selection no longer lowers the estimate and the factor
    over-states it by at most as much (conservative: the variance up to 6 % high at 100
    samples, 2.7 % at 1000).
    Choosing the lowest order the higher ones do not contradict (a test at two standard
    deviations of their log-ratios) was measured too: unbiased on white noise, but a smooth
    signal below the test's reach passes whole (a sinusoid adding 20 % to the 2nd
    difference's variance: +5.8 % in variance at 200 samples, this estimate +2.0 %).  A
    single order (``orders=(k,)``) has no selection and no factor.

    Parameters
    ----------
    x : ndarray, shape (N, C)
        Uniformly (or nearly) sampled signal.
    orders : tuple of int
        Difference orders to try: the default, or a single order.
    max_samples : int
        Only the first ``max_samples`` rows are used (plenty for a robust estimate).

    Returns
    -------
    ndarray, shape (C,)
        Noise standard deviation, in the units of ``x`` (0 for fewer than ``max(orders)+2``
        samples).
    """
    if len(orders) > 1 and tuple(orders) != (2, 3, 4):
        raise ValueError(f'orders: the selection bias is known for (2, 3, 4) or one order, '
                         f'got {orders!r}')
    x = np.asarray(x, dtype=float)[:max_samples]
    best = np.full(x.shape[1], np.inf)
    d = np.ascontiguousarray(x.T)            # one row per column: contiguous partitions
    for k in range(1, max(orders, default=0) + 1):
        if d.shape[1] < 2:
            break
        d = d[:, 1:] - d[:, :-1]                      # the k-th difference, as np.diff(x, k)
        if k in orders and len(x) >= k + 2:
            med, part = _row_medians(d)     # (the partitioned rows: a 4x faster 2nd selection)
            mad = _row_medians(np.abs(part - med[:, None]))[0]
            best = np.minimum(best, 1.4826 * mad / math.sqrt(math.comb(2 * k, k)))
    best[~np.isfinite(best)] = 0.0
    return best / math.sqrt(min_selection_bias(len(x))) if len(orders) > 1 else best


def min_selection_bias(n: int) -> float:
    """``E[s^2] / sigma^2`` of the minimum over the orders (2, 3, 4) on ``n`` samples of white
    noise (:data:`MIN_SELECTION_BIAS`; below :data:`MIN_NOISE_SAMPLES` its value there)."""
    a, b, c = MIN_SELECTION_BIAS
    n = max(int(n), MIN_NOISE_SAMPLES)
    return 1.0 - a / math.sqrt(n) + b / n + c / n ** 1.5


def _row_medians(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`median_rows` of ``d.T`` for a C-contiguous ``d`` (c, n) and the partitioned rows:
    the partition along contiguous rows (a tenth less time than along the columns of ``d.T``)."""
    n = d.shape[1]
    lo, hi = (n - 1) // 2, n // 2
    p = np.partition(d, [lo, hi], axis=1)            # (a kth list, as median_rows: ties)
    return (p[:, lo] if hi == lo else (p[:, lo] + p[:, hi]) / 2.0), p


class StreamingNoise:
    """White-noise std per axis of a stream fed block by block: :func:`noise_std_from_differences`
    on the most recent ``keep`` samples.

    The estimate is a function of the stream only, never of how it was cut into blocks or how
    often it was asked for: until ``stride`` samples it is recomputed on the kept samples when
    new ones came; after that it is the estimate on the ``keep`` samples ending at the latest
    multiple of ``stride`` (computed once per ``stride`` samples, in :meth:`add`): a node asking
    10 times a second at 1 kHz pays for one robust estimate a second, not ten.

    Parameters
    ----------
    floor : bool
        Apply :func:`isotropy_floor` (the gyro stream; not the torque, whose axes may be idle).
    keep : int
        Recent samples kept (default :data:`STREAM_NOISE_SAMPLES`).
    stride : int
        Samples between two estimates once the stream is that long (default
        :data:`STREAM_NOISE_STRIDE`).

    Attributes
    ----------
    count : int
        Samples seen so far.
    """

    def __init__(self, floor: bool = True, keep: int = STREAM_NOISE_SAMPLES,
                 stride: int = STREAM_NOISE_STRIDE) -> None:
        self.floor = floor
        self.keep = int(keep)
        self.stride = int(stride)
        self.count = 0
        self._buf = np.empty((0, 3))
        self._new = 0
        self._std = np.zeros(3)

    def add(self, x: np.ndarray) -> None:
        """Add consecutive samples (n, 3) of the stream."""
        if len(x) == 0:
            return
        buf = np.concatenate([self._buf, x])
        before, self.count = self.count, self.count + len(x)
        last = self.count // self.stride * self.stride     # latest multiple of the stride
        if last >= self.stride and last > before:          # crossed: estimate once, there
            end = len(buf) - (self.count - last)
            self._set(buf[max(0, end - self.keep):end])
            self._new = 0
        elif last < self.stride:
            self._new += len(x)
        self._buf = buf[-self.keep:]

    def _set(self, window: np.ndarray) -> None:
        est = noise_std_from_differences(window)
        self._std = isotropy_floor(est) if self.floor else est

    def std(self) -> np.ndarray:
        """Noise std per axis (zeros before 6 samples), in the units of the stream.

        Returns
        -------
        ndarray, shape (3,)
        """
        if self._new:
            self._set(self._buf)
            self._new = 0
        return self._std

    def variance(self) -> np.ndarray:
        """Noise variance per axis, shape (3,) [units of the stream squared]."""
        return self.std() ** 2

    def known(self) -> bool:
        """Whether the stream has :data:`MIN_NOISE_SAMPLES` samples (its estimate stands)."""
        return self.count >= MIN_NOISE_SAMPLES


#: Levi-Civita symbol eps_abc, shape (3, 3, 3).
_EPS = np.zeros((3, 3, 3))
_EPS[0, 1, 2] = _EPS[1, 2, 0] = _EPS[2, 0, 1] = 1.0
_EPS[0, 2, 1] = _EPS[2, 1, 0] = _EPS[1, 0, 2] = -1.0


def gyroscopic_walk_cov(I: np.ndarray, gyro_var: np.ndarray, omega_m2: np.ndarray | None,
                        gyro_dt: float, torque_dt: float) -> np.ndarray:
    """Torque-noise covariance equivalent to the gyro noise the gyroscopic term integrates.

    The momentum equations integrate ``w x (I w)`` over measured rates ``w + n``; to first
    order that adds ``int J(w) n dt`` with ``J(w) = [w]x I - [I w]x``, a random walk of
    variance rate ``dt_g E[J S_g J']`` (``S_g = diag(gyro_var)``), next to the integrated
    torque noise's ``dt_tau S_tau``.  Since ``J`` is linear in ``w``, the mean over the record
    needs only the second moment ``E[w w']``: ``sum_ij E[w_i w_j] A_i S_g A_j'`` with
    ``A_i = [e_i]x I - [I e_i]x``.  At 50 rad/s this walk outweighs the torque noise.

    Parameters
    ----------
    I : ndarray, shape (3, 3)
        Current tensor [kg m^2].
    gyro_var : ndarray, shape (3,)
        Gyro white-noise variance [rad^2/s^2].
    omega_m2 : ndarray, shape (3, 3), optional
        ``mean(w w')`` of the used samples [rad^2/s^2]; None gives zeros.
    gyro_dt, torque_dt : float
        Median sample intervals [s].

    Returns
    -------
    ndarray, shape (3, 3)
        Covariance [N^2 m^2] to add to the torque-noise covariance of each torque interval.
    """
    if omega_m2 is None or gyro_dt <= 0 or torque_dt <= 0:
        return np.zeros((3, 3))
    # sum_ij E[w_i w_j] A_i S_g A_j' as one contraction (every fit's meat calls this)
    A = walk_maps(I)
    M = np.einsum('ij,iab,b,jcb->ac', omega_m2, A, np.asarray(gyro_var, dtype=float), A)
    M = 0.5 * (M + M.T)
    return (gyro_dt / torque_dt) * M


def walk_maps(I: np.ndarray) -> np.ndarray:
    """``A_i = [e_i]x I - [I e_i]x`` (3, 3, 3) for the tensor ``I`` (3, 3) [kg m^2]: the
    gyroscopic term's ``J(w) = sum_i w_i A_i`` (:func:`gyroscopic_walk_cov`), all three at once
    (``[v]x_ab = -eps_abc v_c``)."""
    return np.einsum('aki,kb->iab', -_EPS, I) + np.einsum('abc,ci->iab', _EPS, I)


def regressor_noise_information(var: np.ndarray, Wh: np.ndarray,
                                basis: np.ndarray | None = None) -> np.ndarray:
    """The gyro noise's own information in the tensor columns of one weighted equation:
    ``sum_k var_k (Wh L(e_k) T)' (Wh L(e_k) T)`` (``I v = L(v) theta``), the expected Gram
    that corrected (errors-in-variables) least squares takes out of the normal matrix.

    Parameters
    ----------
    var : ndarray, shape (3,)
        Variance per gyro axis of the noise in the equation's rate [rad^2/s^2].
    Wh : ndarray, shape (3, 3)
        The equation's whitening factor (``Wh' Wh`` = the inverse error covariance).
    basis : ndarray, shape (6, k), optional
        Model basis ``T`` (default: the six tensor parameters).

    Returns
    -------
    ndarray, shape (k, k)
    """
    from .regressors import momentum_matrix

    L = momentum_matrix(np.eye(3))                       # (3 axes, 3, 6)
    if basis is not None:
        L = L @ basis
    LW = np.einsum('ij,kjp->kip', Wh, L)
    return np.einsum('k,kip,kiq->pq', np.asarray(var, dtype=float), LW, LW)
