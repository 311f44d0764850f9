"""The cumulative integrals behind the integral equations, computed in cache-sized blocks
(``regressors.BLOCK_ROWS``): bit-identical to the whole-array computation they replace, for
every length around the block size, every option, a row range written into a column view."""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.core.estimation import regressors
from inertia_ros.core.estimation.equations import _as_range
from inertia_ros.core.estimation.regressors import (
    BLOCK_ROWS,
    cumulative_monomials,
    cumulative_torque,
    monomials,
)


def _whole_monomials(t, omega, noise_var=None, end_correction=True):
    """The whole-array form (the definition: trapezoid, -h^2/12 f', noise span)."""
    p = monomials(omega)
    out = np.empty_like(p)
    out[0] = 0.0
    n = len(t)
    if n > 1:
        dt = np.diff(t)
        inc = p[1:] + p[:-1]
        inc *= (0.5 * dt)[:, None]
        np.cumsum(inc, axis=0, out=out[1:])
        if end_correction and n > 2:
            dp = np.empty_like(p)
            np.subtract(p[2:], p[:-2], out=dp[1:-1])
            dp[1:-1] /= (t[2:] - t[:-2])[:, None]
            if n > 3:
                dp[0] = 2.0 * dp[1] - dp[2]
                dp[-1] = 2.0 * dp[-2] - dp[-3]
            else:
                dp[0] = dp[-1] = dp[1]
            h = np.empty(n)
            h[1:] = dt
            h[0] = dt[0]
            dp *= (h * h / 12.0)[:, None]
            out -= dp
            out -= out[0].copy()
    if noise_var is not None:
        span = t - t[0]
        for c, v in enumerate(noise_var):
            out[:, c] -= span * v
    return out


def _whole_torque(t_tau, tau, t, hold):
    dts = np.diff(t_tau)
    cum = np.zeros_like(tau)
    j = np.clip(np.searchsorted(t_tau, t, side='right') - 1, 0, len(t_tau) - 1)
    if hold == 'zoh':
        np.cumsum(tau[:-1] * dts[:, None], axis=0, out=cum[1:])
        out = tau[j]
        out *= (t - t_tau[j])[:, None]
        out += cum[j]
        return out
    np.cumsum(0.5 * (tau[:-1] + tau[1:]) * dts[:, None], axis=0, out=cum[1:])
    u = (t - t_tau[j])[:, None]
    slope = np.zeros_like(tau)
    slope[:-1] = (tau[1:] - tau[:-1]) / dts[:, None]
    return cum[j] + tau[j] * u + np.where((j < len(t_tau) - 1)[:, None],
                                          0.5 * slope[j] * u * u, 0.0)


@pytest.mark.parametrize('n', [1, 2, 3, 4, 5, 9, BLOCK_ROWS - 1, BLOCK_ROWS, BLOCK_ROWS + 1,
                               2 * BLOCK_ROWS + 3, 5 * BLOCK_ROWS + 17])
def test_blocks_equal_the_whole_array_form(n: int) -> None:
    """Monomial integrals (with and without noise and end correction) and held-torque
    integrals (zoh, linear; queries beyond the last sample) equal the whole-array form bit
    for bit."""
    rng = np.random.default_rng(n)
    t = 3.0 + np.cumsum(rng.uniform(0.004, 0.006, n))
    w = rng.normal(size=(n, 3)) * 2.0
    for nv in (None, np.array([1e-4, 2e-4, 3e-4])):
        for ec in (True, False):
            assert np.array_equal(cumulative_monomials(t, w, nv, ec),
                                  _whole_monomials(t, w, nv, ec))
    ts = t[0] - 0.001 + np.cumsum(rng.uniform(0.015, 0.025, n // 4 + 2))
    ts = np.r_[t[0] - 0.001, ts]
    tau = rng.normal(size=(len(ts), 3))
    for hold in ('zoh', 'linear'):
        assert np.array_equal(cumulative_torque(ts, tau, t, hold), _whole_torque(ts, tau, t, hold))


def test_row_range_into_a_column_view() -> None:
    """``rows=`` and ``out=`` (how the integral equations write their 13 columns): the rows of
    the whole result, in place in a strided view; a bad range is a ValueError."""
    n = 3 * BLOCK_ROWS + 5
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.004, 0.006, n))
    w = rng.normal(size=(n, 3))
    whole = _whole_monomials(t, w, np.full(3, 1e-4))
    for a, b in ((0, n), (17, n - 3), (BLOCK_ROWS, 2 * BLOCK_ROWS + 1), (5, 5)):
        V = np.full((b - a, 13), np.nan)
        got = cumulative_monomials(t, w, np.full(3, 1e-4), rows=slice(a, b), out=V[:, 3:9])
        assert got.base is V or got is V[:, 3:9] or np.shares_memory(got, V)
        assert np.array_equal(V[:, 3:9], whole[a:b])
        assert np.all(np.isnan(V[:, :3])) and np.all(np.isnan(V[:, 9:]))
    with pytest.raises(ValueError, match='rows'):
        cumulative_monomials(t, w, rows=slice(0, n + 1))
    with pytest.raises(ValueError, match='rows'):
        cumulative_monomials(t, w, rows=slice(0, n, 2))


def test_contiguous_index_is_a_range() -> None:
    """The equations take the blocked path only for a contiguous run of samples."""
    assert _as_range(np.arange(4, 90), 100) == slice(4, 90)
    assert _as_range(slice(None), 100) == slice(0, 100)
    assert _as_range(np.array([1, 2, 4]), 100) is None
    assert _as_range(np.ones(100, dtype=bool), 100) is None
    assert _as_range(np.array([], dtype=int), 100) is None
    assert regressors.BLOCK_ROWS >= 1024
