"""The row-range sums under every sufficient statistic (``statistics.range_sums`` and the
per-torque-interval sums), against plain Python sums, on every layout their fast paths split:
long and short ranges, empty ranges, steady-rate runs, jittered rates, and column views."""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.core.estimation.statistics import _MIN_RUN, _interval_sums, range_sums


def _naive_ranges(V: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    return np.array([V[a:b].sum(axis=0) if b > a else np.zeros(V.shape[1])
                     for a, b in zip(bounds[:-1], bounds[1:], strict=True)])


@pytest.mark.parametrize('n, n_ranges', [(5000, 3), (5000, 20), (5000, 400), (5000, 4999),
                                         (7, 7), (0, 3), (140_000, 800)])
def test_range_sums_equal_python_sums(n: int, n_ranges: int) -> None:
    """Few long ranges (BLAS row sums) and many short ones (reduceat), some empty, on a column
    view of a wider array (as the equations hand them over); a long record's ranges of ~175
    rows (BLAS sums there): the sums to 1e-12."""
    rng = np.random.default_rng(n + n_ranges)
    V = rng.normal(size=(n, 13))[:, :10]
    inner = np.sort(rng.integers(0, n + 1, size=n_ranges - 1))
    bounds = np.concatenate(([0], inner, [n]))
    if n_ranges > 2:
        bounds[2] = bounds[1]                       # an empty range
    got = range_sums(V, bounds)
    assert got.shape == (n_ranges, 10)
    np.testing.assert_allclose(got, _naive_ranges(V, bounds), rtol=0, atol=1e-12 * max(n, 1))


def _naive_intervals(V: np.ndarray, t: np.ndarray, t_tau: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    j = np.searchsorted(t_tau, t, side='right') - 1
    j[j < 0] = 0                                   # rows before the first sample: interval 0
    S = np.zeros((len(t_tau), V.shape[1]))
    St = np.zeros_like(S)
    for b in range(len(t)):
        S[j[b]] += V[b]
        St[j[b]] += (t[b] - t_tau[j[b]]) * V[b]
    return S, St


@pytest.mark.parametrize('layout', ['steady', 'jitter', 'gaps', 'mixed'])
def test_interval_sums_equal_python_sums(layout: str) -> None:
    """Per torque interval, ``sum V`` and ``sum (t - s_j) V``: steady rates (runs of equal
    counts as views), jittered rates (gathered by count), torque gaps (empty intervals) and a
    record that switches between the two; the sums to 1e-12, and the interval row pointers."""
    rng = np.random.default_rng(7)
    t = np.arange(4000) / 200.0
    t_tau = np.arange(0.0, 20.0, 0.02)
    if layout in ('jitter', 'mixed'):
        jit = rng.uniform(-0.009, 0.009, size=len(t_tau))
        if layout == 'mixed':
            jit[: len(jit) // 2] = 0.0
        t_tau = np.sort(t_tau + jit)
        t_tau[0] = 0.0
    if layout == 'gaps':
        t_tau = np.delete(t_tau, np.s_[300:340])
        t = np.delete(t, np.s_[1000:1003])
    V = rng.normal(size=(len(t), 13))[:, :10]
    S, St, indptr = _interval_sums(V, t, t_tau)
    S0, St0 = _naive_intervals(V, t, t_tau)
    np.testing.assert_allclose(S, S0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(St, St0, rtol=0, atol=1e-12)
    assert indptr[0] == 0 and indptr[-1] == len(t)
    assert np.all(np.diff(indptr) >= 0)
    if layout == 'steady':                          # the fast path really ran: one long run
        assert np.count_nonzero(np.diff(indptr) == 4) > _MIN_RUN
