"""The wide variables of a torque fixed in inertial axes (core/estimation/regressors.py):
``[w, m, s, y, c (9)]`` with blocks ``[X6 | Xd | y | Xi]``; the 13-variable layout is their
exact prefix, and on the independent reference simulator the true tensor and disturbance
explain the anchored equations to integration accuracy."""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.bench.honesty import CASES
from inertia_ros.bench.truth_sim import simulate_truth
from inertia_ros.core.estimation.attitude import attitude_integral
from inertia_ros.core.estimation.regressors import (
    N_VARIABLES_WIDE,
    REGRESSOR_COLUMNS_WIDE,
    VARIABLE_MAP,
    VARIABLE_MAP_WIDE,
    blocks,
    cumulative_monomials,
    cumulative_torque,
    gram,
    lift,
    variables,
)
from inertia_ros.core.tensor import THETA_COLS, THETA_ROWS


def test_the_narrow_map_is_an_exact_prefix_of_the_wide_one() -> None:
    assert VARIABLE_MAP_WIDE.shape == (N_VARIABLES_WIDE, 3, 13)
    assert np.array_equal(VARIABLE_MAP_WIDE[:13, :, :10], VARIABLE_MAP)
    assert not np.any(VARIABLE_MAP_WIDE[:13, :, 10:])
    assert not np.any(VARIABLE_MAP_WIDE[13:, :, :10])
    assert list(REGRESSOR_COLUMNS_WIDE) == [*range(10), *range(13, 22)]


def test_wide_blocks_and_grams_contain_the_narrow_ones() -> None:
    rng = np.random.default_rng(4)
    V = rng.normal(size=(500, 22)) * rng.uniform(0.1, 10.0, 22)
    A = blocks(V)
    assert A.shape == (500, 3, 13)
    assert np.array_equal(A[..., :10], blocks(V[:, :13]))
    # the inertial columns: Xi[r, k] = -C[r, k] with c[3 r + k] = C[r, k]
    assert np.array_equal(A[..., 10:], -V[:, 13:].reshape(500, 3, 3))
    C22, C13 = lift(gram(V)), lift(gram(V[:, :13]))
    assert C22.shape == (3, 3, 13, 13)
    assert np.allclose(C22[..., :10, :10], C13, rtol=1e-12, atol=0.0)
    # a cross Gram is the sum of the blocks' products
    assert np.allclose(C22[0, 2], A[:, 0].T @ A[:, 2], rtol=1e-12, atol=1e-9)


def test_variables_stack_the_attitude_integral_row_by_row() -> None:
    n = 4
    C = np.arange(n * 9, dtype=float).reshape(n, 3, 3)
    V = variables(np.zeros((n, 3)), np.zeros((n, 6)), np.ones(n), np.zeros((n, 3)), C)
    assert V.shape == (n, 22)
    assert np.array_equal(V[:, 13:], C.reshape(n, 9))
    assert variables(np.zeros((n, 3)), np.zeros((n, 6)), np.ones(n),
                     np.zeros((n, 3))).shape == (n, 13)


@pytest.mark.parametrize('n_var', [12, 14, 21, 23])
def test_other_widths_are_refused(n_var: int) -> None:
    with pytest.raises(ValueError, match='13 or 22 variables'):
        blocks(np.zeros((2, n_var)))
    with pytest.raises(ValueError, match='13 or 22 variables'):
        lift(np.zeros((n_var, n_var)))


def test_reference_simulator_inertial_disturbance_is_explained() -> None:
    """Noise-free 10 s record of the disturbance scene (0.01 N m per axis fixed in inertial
    axes; the simulator's attitude starts at identity, so its inertial axes are the body axes
    at the first sample): the true ``[theta, 0, 1, d]`` leaves a residual of 3e-6 of the
    disturbance's angular impulse (integration error); without ``d`` it is all of it, with
    ``-d`` twice."""
    case = CASES['disturbance'].truth.with_(duration=10.0, gyro_noise=0.0, torque_noise=0.0)
    assert case.disturbance_kind == 'inertial'
    rec = simulate_truth(case, [0])[0]
    inside = (rec.t_gyro >= rec.t_torque[0]) & (rec.t_gyro <= rec.t_torque[-1])
    t, w = rec.t_gyro[inside], rec.omega[inside]
    V = variables(w, cumulative_monomials(t, w), t - t[0],
                  cumulative_torque(rec.t_torque, rec.torque, t, 'zoh'),
                  attitude_integral(t, w))
    A = blocks(V - V[0])                                # anchored at the first sample
    theta = rec.inertia_end[THETA_ROWS, THETA_COLS]
    d = np.asarray(case.disturbance, dtype=float)
    impulse = np.sqrt(np.mean((A[..., 10:] @ d) ** 2))
    assert impulse > 0.01                               # 0.017 N m over 10 s: a real signal

    def rel(dd: np.ndarray) -> float:
        e = A @ np.r_[-theta, np.zeros(3), 1.0, -dd]
        return float(np.sqrt(np.mean(e ** 2)) / impulse)

    assert rel(d) < 1e-4
    assert 0.99 < rel(0.0 * d) < 1.01
    assert 1.98 < rel(-d) < 2.02


# --------------------------------------------------------------------------------------------
# the integral equations and their statistics with the inertial columns (step 2b)
# --------------------------------------------------------------------------------------------
def _record(duration: float = 10.0, seed: int = 31) -> tuple:
    """The disturbance scene (with its sensor noise), the gyro samples inside the torque."""
    case = CASES['disturbance'].truth.with_(duration=duration)
    rec = simulate_truth(case, [seed])[0]
    return case, rec


def _build(rec, mask: np.ndarray | None = None, inertial: bool = False,
           hold: str = 'zoh', shared: dict | None = None):
    from inertia_ros.core.estimation.equations import (
        build_equations,
        shared_integral_equations,
    )
    tg, w, ts, tau = rec.t_gyro, rec.omega, rec.t_torque, rec.torque
    if mask is None:
        mask = (tg >= ts[0]) & (tg <= ts[-1])
    idx = np.flatnonzero(mask)
    breaks = (np.diff(idx) > 1) | (np.diff(tg[idx]) > 5.0 * np.median(np.diff(tg)))
    gv = np.full(3, 2e-3 ** 2)
    if shared is not None:
        return shared_integral_equations('integral', tg, w, ts, tau, mask, breaks, hold, gv,
                                         shared, inertial)
    return build_equations('integral', tg, w, ts, tau, mask, breaks, hold, gv, None,
                           inertial=inertial)


def test_wide_integral_equations_extend_the_narrow_ones() -> None:
    _, rec = _record()
    narrow, wide = _build(rec), _build(rec, inertial=True)
    assert narrow.V.shape[1] == 13 and 'attitude' not in narrow.info
    assert wide.V.shape == (len(narrow.V), 22)
    assert np.array_equal(wide.V[:, :13], narrow.V)
    t = narrow.t
    i0 = int(np.searchsorted(rec.t_gyro, t[0]))
    C = attitude_integral(rec.t_gyro[i0:i0 + len(t)], rec.omega[i0:i0 + len(t)])
    assert np.array_equal(wide.V[:, 13:], C.reshape(len(t), 9))
    assert wide.info['attitude'] == {'gaps': 0, 'bridge_error_rad': 0.0}


def test_wide_statistics_contain_the_narrow_ones() -> None:
    from inertia_ros.core.estimation.statistics import segment_rss, sufficient_stats
    _, rec = _record()
    ts, tv = rec.t_torque, np.full(3, 5e-3 ** 2)
    for seg in (2.5, None):
        narrow, wide = _build(rec), _build(rec, inertial=True)
        sn = sufficient_stats(narrow, seg, ts, float(narrow.t[-1]), tv)
        sw = sufficient_stats(wide, seg, ts, float(wide.t[-1]), tv)
        assert sw.C.shape == (3, 3, 13, 13) and sw.CP.shape == (3, 3, 13, 13)
        assert (sw.n, sw.n_eff, sw.n_seg) == (sn.n, sn.n_eff, sn.n_seg)
        for a, b in ((sw.C[..., :10, :10], sn.C), (sw.CP[..., :10, :10], sn.CP)):
            assert np.allclose(a, b, rtol=1e-10, atol=1e-12 * np.abs(b).max())
        # the torque integral carries no torque-noise sums of its own; the inertial ones do
        assert not np.any(sw.CP[..., 9, :]) and np.all(np.abs(sw.CP[0, 0, 10:, 10:]) > 0)
    rng = np.random.default_rng(5)
    c10 = rng.normal(size=10)
    W = np.eye(3) + 0.1
    starts = np.array([0, 700, 1500])
    assert np.allclose(segment_rss(wide.V, starts, np.r_[c10, 0.0, 0.0, 0.0], W),
                       segment_rss(narrow.V, starts, c10, W), rtol=1e-10, atol=0.0)


def test_attitude_runs_over_excluded_samples_and_reports_time_gaps() -> None:
    _, rec = _record()
    tg = rec.t_gyro
    mask = (tg >= rec.t_torque[0]) & (tg <= rec.t_torque[-1])
    mask[300:340] = False                               # samples left out: the attitude goes on
    eq = _build(rec, mask, inertial=True)
    idx = np.flatnonzero(mask)
    C = attitude_integral(tg[idx[0]:idx[-1] + 1], rec.omega[idx[0]:idx[-1] + 1])
    C = C[idx - idx[0]].reshape(-1, 9)
    k = int(np.searchsorted(idx, 340))                  # the segment after the hole ...
    C[k:] -= C[k]                                       # ... re-anchored, as every column
    assert np.allclose(eq.V[:, 13:], C, rtol=0.0, atol=1e-12)
    assert eq.info['attitude']['gaps'] == 0
    # a gyro time gap of 0.2 s: crossed at the mean rate, bounded and reported
    keep = np.ones(len(tg), bool)
    keep[500:540] = False
    from dataclasses import replace
    cut = replace(rec, t_gyro=tg[keep], omega=rec.omega[keep])
    info = _build(cut, inertial=True).info['attitude']
    w = rec.omega
    bound = np.linalg.norm(w[540] - w[499]) * (tg[540] - tg[499]) / 2.0
    assert info['gaps'] == 1 and np.isclose(info['bridge_error_rad'], bound, rtol=1e-12)


def test_holds_share_the_inertial_columns() -> None:
    _, rec = _record()
    shared: dict = {}
    held = _build(rec, inertial=True, shared=shared).V.copy()
    linear = _build(rec, inertial=True, hold='linear', shared=shared)
    fresh = _build(rec, inertial=True, hold='linear')
    assert np.array_equal(linear.V, fresh.V) and linear.info == fresh.info
    assert np.array_equal(held[:len(linear.V), 13:], linear.V[:, 13:])


def test_inertial_columns_only_for_the_integral_methods() -> None:
    from inertia_ros.core.estimation.equations import build_equations
    _, rec = _record()
    mask = np.ones(len(rec.t_gyro), bool)
    with pytest.raises(ValueError, match='integral methods only'):
        build_equations('integral_sliding', rec.t_gyro, rec.omega, rec.t_torque, rec.torque,
                        mask, np.zeros(len(mask) - 1, bool), 'zoh', np.full(3, 4e-6), None,
                        inertial=True)
