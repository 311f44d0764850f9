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
