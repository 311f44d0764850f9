"""White-noise levels from the data: one estimator, in a batch and a streaming form.

The quantity is the white-noise standard deviation of a sampled signal (gyro [rad/s] or torque
[N m]) per axis.  For white noise of variance ``s^2`` the k-th difference has variance
``C(2k, k) s^2`` (20 s^2 for k = 3), while a smooth signal contributes little to high-order
differences.  The two forms are one estimator of that quantity:

* :func:`noise_std_from_differences` (batch: :func:`~.batch.estimate`, and the torque stream of
  :class:`~.recursive.RecursiveEstimator` block by block): robust, the median absolute
  deviation of the 2nd, 3rd and 4th differences, the smallest of the three (signal only adds
  variance);
* :class:`StreamingDifferenceNoise` (the gyro stream of the online estimator): the running mean
  square of the third differences across blocks, so the answer does not depend on how the
  stream was cut into blocks and costs O(1) memory.

Both gyro estimates are floored at :data:`ISOTROPY_FLOOR` of the largest axis
(:func:`isotropy_floor`): a nearly noise-free axis would otherwise get an absurd weight.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ['ISOTROPY_FLOOR', 'StreamingDifferenceNoise', 'isotropy_floor', 'median_rows',
           'noise_std_from_differences']

#: Smallest gyro-noise std of an axis, as a share of the largest axis' std.
ISOTROPY_FLOOR = 0.1


def isotropy_floor(std: np.ndarray) -> np.ndarray:
    """Per-axis noise std raised to at least :data:`ISOTROPY_FLOOR` of the largest, shape (3,)."""
    return np.maximum(std, ISOTROPY_FLOOR * float(np.max(std)))


def median_rows(d: np.ndarray) -> np.ndarray:
    """Column medians of ``d`` (n, c) by one partition: ``np.median(d, axis=0)`` bit for bit
    on finite input, without its overhead (it runs on every block of the online estimator).
    """
    n = len(d)
    lo, hi = (n - 1) // 2, n // 2
    p = np.partition(d, [lo, hi] if hi != lo else lo, axis=0)
    return p[lo] if hi == lo else (p[lo] + p[hi]) / 2.0


def noise_std_from_differences(x: np.ndarray, orders: tuple[int, ...] = (2, 3, 4),
                               max_samples: int = 50_000) -> np.ndarray:
    """Robust white-noise standard deviation per column from high-order differences.

    For white noise of variance ``s^2`` the k-th difference has variance ``C(2k, k) s^2``;
    a smooth signal contributes little to high-order differences.  The median absolute
    deviation makes the estimate robust to occasional jumps (steps, PRBS); the smallest
    estimate over ``orders`` is returned (signal only adds variance).

    Parameters
    ----------
    x : ndarray, shape (N, C)
        Uniformly (or nearly) sampled signal.
    orders : tuple of int
        Difference orders to try.
    max_samples : int
        Only the first ``max_samples`` rows are used (plenty for a robust estimate).

    Returns
    -------
    ndarray, shape (C,)
        Noise standard deviation, in the units of ``x`` (0 for fewer than ``max(orders)+2``
        samples).
    """
    x = np.asarray(x, dtype=float)[:max_samples]
    best = np.full(x.shape[1], np.inf)
    d = x
    for k in range(1, max(orders, default=0) + 1):
        if len(d) < 2:
            break
        d = d[1:] - d[:-1]                            # the k-th difference, as np.diff(x, k)
        if k in orders and len(x) >= k + 2:
            mad = median_rows(np.abs(d - median_rows(d)[None]))
            best = np.minimum(best, 1.4826 * mad / math.sqrt(math.comb(2 * k, k)))
    best[~np.isfinite(best)] = 0.0
    return best


class StreamingDifferenceNoise:
    """Running white-noise variance per axis from third differences, fed block by block.

    The streaming form of :func:`noise_std_from_differences` (see the module docstring):
    ``var = mean(d3^2) / 20`` over every third difference of the concatenated stream, the
    last three samples of each block kept to bridge to the next.

    Attributes
    ----------
    count : int
        Third differences accumulated so far.
    """

    def __init__(self) -> None:
        self._sum = np.zeros(3)
        self.count = 0
        self._tail = np.empty((0, 3))

    def add(self, x: np.ndarray) -> None:
        """Add consecutive samples (n, 3) of the stream."""
        xx = np.concatenate([self._tail, x]) if len(self._tail) else x
        if len(xx) >= 4:
            d3 = xx[3:] - 3.0 * xx[2:-1] + 3.0 * xx[1:-2] - xx[:-3]
            self._sum = self._sum + np.sum(d3 * d3, axis=0) / 20.0
            self.count += len(d3)
        self._tail = xx[-3:].copy()

    def variance(self) -> np.ndarray:
        """Noise variance per axis, floored as :func:`isotropy_floor` (zeros before any data).

        Returns
        -------
        ndarray, shape (3,)
            [units of the stream squared].
        """
        if not self.count:
            return np.zeros(3)
        nv = self._sum / self.count
        return np.maximum(nv, ISOTROPY_FLOOR ** 2 * float(np.max(nv)))
