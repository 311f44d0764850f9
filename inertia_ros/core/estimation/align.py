"""One gap rule and one momentum interpolation for the batch and online momentum paths.

A stream's sample interval longer than :data:`~.options.GAP_FACTOR` nominal (median)
intervals is a gap: nothing is known of the stream inside it.  For internal momentum ``h``
(wheels, rotors) the batch reduction (:func:`.momentum.equivalent_torque`) and the online one
(:class:`.recursive_momentum.MomentumRecursiveEstimator`) apply the same rule through
:func:`gap_starts`: the gyro samples strictly inside a gap are dropped, the equations on
either side belong to different anchored segments (whose intercepts take the unknown change
of ``h``), and ``h`` is interpolated between its samples (:func:`hermite`) with slopes taken
within each gap-free run only (:func:`run_slopes`), never across a gap.
"""
from __future__ import annotations

import numpy as np

from .options import GAP_FACTOR

__all__ = ['gap_starts', 'hermite', 'inside_gaps', 'run_slopes']


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


def hermite(t_h: np.ndarray, h: np.ndarray, slopes: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of ``h`` (K, c) with ``slopes`` (K, c) at ``t`` (n,).

    ``t`` must lie in ``[t_h[0], t_h[-1]]``; K >= 2.  Returns (n, c).
    """
    j = np.clip(np.searchsorted(t_h, t, side='right') - 1, 0, len(t_h) - 2)
    dx = (t_h[j + 1] - t_h[j])[:, None]
    u = (t - t_h[j])[:, None] / dx
    h00, h10 = 2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u
    h01, h11 = -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2
    return h00 * h[j] + h10 * dx * slopes[j] + h01 * h[j + 1] + h11 * dx * slopes[j + 1]
