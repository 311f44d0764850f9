"""The attitude integral ``C(t) = int R(s)' ds`` from the gyro (core/estimation/attitude.py),
the per-sample variables of a torque fixed in inertial axes: checked against scipy's
``Rotation`` and closed forms (exact for a rate constant between samples)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.spatial.transform import Rotation

from inertia_ros.core.estimation.attitude import attitude_integral, cross_matrix, step_maps


def _spin_closed_form(t: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R(t) = exp([u t]x)`` and ``int_0^t R' ds`` for a constant rate ``u`` (3,)."""
    K = cross_matrix(u)
    a = float(np.linalg.norm(u))
    R = Rotation.from_rotvec(t[:, None] * u).as_matrix()
    C = (t[:, None, None] * np.eye(3)
         - ((1.0 - np.cos(a * t)) / a ** 2)[:, None, None] * K
         + ((t - np.sin(a * t) / a) / a ** 2)[:, None, None] * (K @ K))
    return R, C


def test_constant_rate_spin_is_exact_on_irregular_stamps() -> None:
    rng = np.random.default_rng(1)
    t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 6.0, 300))])
    u = np.array([0.4, -1.3, 2.2])                     # 2.6 rad/s, ~2.5 turns
    C, R = attitude_integral(t, np.tile(u, (len(t), 1)), rotations=True)
    R_ref, C_ref = _spin_closed_form(t, u)
    assert np.max(np.abs(R - R_ref)) < 1e-12
    assert np.max(np.abs(C - C_ref)) < 1e-12 * 6.0
    # the spin axis is never turned: C u = t u
    assert np.allclose(C @ u, t[:, None] * u, rtol=0, atol=1e-12)


def test_large_steps_are_exact_for_a_constant_rate() -> None:
    # 0.5 s steps at 3 rad/s (1.5 rad per step): a trapezoid of R' would be far off
    t = np.arange(0.0, 5.01, 0.5)
    u = np.array([0.0, 0.0, 3.0])
    C = attitude_integral(t, np.tile(u, (len(t), 1)))
    assert np.max(np.abs(C - _spin_closed_form(t, u)[1])) < 1e-13 * 5.0


def test_piecewise_constant_rates_against_scipy_composition_and_quadrature() -> None:
    rng = np.random.default_rng(2)
    t = np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.3, 25)])
    rates = rng.normal(scale=1.5, size=(len(t) - 1, 3))
    C, R = attitude_integral(t, np.zeros((len(t), 3)), rates, rotations=True)
    r = Rotation.identity()
    C_ref = np.zeros((len(t), 3, 3))
    for k, u in enumerate(rates):
        h = t[k + 1] - t[k]
        Rk = r.as_matrix()

        def transposed(s: float, Rk: np.ndarray = Rk, u: np.ndarray = u) -> np.ndarray:
            return (Rk @ Rotation.from_rotvec(u * s).as_matrix()).T

        C_ref[k + 1] = C_ref[k] + quad_vec(transposed, 0.0, h, epsabs=1e-14, epsrel=1e-13)[0]
        r = r * Rotation.from_rotvec(u * h)            # body increment on the right
        assert np.max(np.abs(R[k + 1] - r.as_matrix())) < 1e-12
    assert np.max(np.abs(C - C_ref)) < 1e-11


def test_default_rule_is_second_order_on_a_smooth_rate() -> None:
    def rate(t: np.ndarray) -> np.ndarray:
        return np.column_stack([np.sin(t), 0.8 * np.cos(2.0 * t), 0.5 + 0.3 * t])

    T = 4.0
    fine = np.linspace(0.0, T, 2 ** 14 + 1)             # reference: exact per tiny step
    mids = 0.5 * (fine[1:] + fine[:-1])
    C_ref = attitude_integral(fine, rate(fine), rate(mids))[-1]
    errs = []
    for n in (40, 80, 160):
        t = np.linspace(0.0, T, n + 1)
        errs.append(np.max(np.abs(attitude_integral(t, rate(t))[-1] - C_ref)))
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 3.5) & (ratios < 4.5)), (errs, ratios)
    assert errs[-1] < 1e-3


def test_blocks_do_not_change_the_result_and_rotations_stay_orthonormal() -> None:
    rng = np.random.default_rng(3)
    n = 200_000
    t = np.arange(n) * 5e-3
    w = rng.normal(scale=2.0, size=(n, 3))
    C, R = attitude_integral(t, w, rotations=True)
    C7, R7 = attitude_integral(t[:1000], w[:1000], rotations=True, block=7)
    assert np.max(np.abs(C7 - C[:1000])) < 1e-12
    assert np.max(np.abs(R7 - R[:1000])) < 1e-12
    err = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max()
    assert err < 1e-11
    assert np.allclose(np.linalg.det(R[::1000]), 1.0, rtol=0, atol=1e-11)


def test_step_maps_series_and_closed_form_agree_at_the_switch() -> None:
    h = np.ones(2)
    u = np.array([[0.0, 0.0, 0.1 - 1e-9], [0.0, 0.0, 0.1 + 1e-9]])
    E, J = step_maps(u, h)
    assert np.max(np.abs(E[0] - E[1])) < 1e-8
    assert np.max(np.abs(J[0] - J[1])) < 1e-8
    E0, J0 = step_maps(np.zeros((1, 3)), np.array([0.25]))
    assert np.array_equal(E0[0], np.eye(3)) and np.allclose(J0[0], 0.25 * np.eye(3))


def test_short_and_malformed_input() -> None:
    assert attitude_integral(np.zeros(1), np.zeros((1, 3))).shape == (1, 3, 3)
    assert attitude_integral(np.zeros(0), np.zeros((0, 3))).shape == (0, 3, 3)
    with pytest.raises(ValueError, match='omega'):
        attitude_integral(np.arange(3.0), np.zeros((3, 2)))
    with pytest.raises(ValueError, match='non-decreasing'):
        attitude_integral(np.array([0.0, 1.0, 0.5]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match='rates'):
        attitude_integral(np.arange(3.0), np.zeros((3, 3)), np.zeros((3, 3)))


def test_out_writes_columns_of_a_wider_array_in_place() -> None:
    rng = np.random.default_rng(6)
    t = np.cumsum(rng.uniform(0.004, 0.006, 50))
    w = rng.normal(size=(50, 3))
    V = np.full((50, 22), 7.0)
    C = attitude_integral(t, w, out=V[:, 13:])
    assert np.shares_memory(C, V)
    assert np.array_equal(V[:, 13:], attitude_integral(t, w).reshape(50, 9))
    assert np.all(V[:, :13] == 7.0)                    # the other columns untouched
    T = np.zeros((9, 50)).T                            # a transposed view works as well
    attitude_integral(t, w, out=T)
    assert np.array_equal(T, V[:, 13:])
    with pytest.raises(ValueError, match='out must be'):
        attitude_integral(t, w, out=np.zeros((49, 9)))


def _stacked_reference(t: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One step at a time, as the first (stacked-matrix) implementation defined it: the step
    rotation from scipy, ``J`` from its closed form, ``R`` multiplied out sample by sample."""
    u = 0.5 * (w[1:] + w[:-1])
    h = np.diff(t)
    E = Rotation.from_rotvec(u * h[:, None]).as_matrix()
    C = np.zeros((len(t), 3, 3))
    R = np.zeros((len(t), 3, 3))
    R[0] = np.eye(3)
    for k in range(len(h)):
        K = cross_matrix(u[k] * h[k])
        q = float(np.linalg.norm(u[k] * h[k]))
        f2 = 0.5 if q < 1e-4 else (1.0 - np.cos(q)) / q ** 2
        f3 = 1.0 / 6.0 if q < 1e-4 else (q - np.sin(q)) / q ** 3
        J = h[k] * (np.eye(3) - f2 * K + f3 * K @ K)
        C[k + 1] = C[k] + J @ R[k].T
        R[k + 1] = R[k] @ E[k]
    return C, R


def _tumbling_gyro(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """200 Hz irregular stamps and a wandering rate with a 0.5 s spin burst at up to 280 rad/s
    (1.4 rad per step: beyond the series switch of :func:`step_maps`)."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(np.r_[0.0, rng.uniform(0.004, 0.006, n - 1)])
    w = np.cumsum(rng.normal(scale=0.05, size=(n, 3)), axis=0) + np.array([1.5, -0.8, 0.4])
    w[5000:5100] *= 40.0
    return t, w


def test_the_blocked_scan_equals_a_step_by_step_product() -> None:
    t, w = _tumbling_gyro(6_001, 27)
    C_ref, R_ref = _stacked_reference(t, w)
    scale = np.abs(C_ref).max()
    # block sizes that leave partial runs and a partial last block, and the default
    for block in (7, 1000, 4099, 100_000):
        C, R = attitude_integral(t, w, rotations=True, block=block)
        assert np.max(np.abs(C - C_ref)) < 1e-12 * scale, block
        assert np.max(np.abs(R - R_ref)) < 1e-12, block


def test_values_of_the_first_implementation_are_kept() -> None:
    # rows of C and R printed by the stacked (N, 3, 3) implementation of fc1dd39 on this
    # seeded input (20 001 samples, C up to 55 s): the flat scan must agree to 1e-12
    t, w = _tumbling_gyro(20_001, 27)
    C, R = attitude_integral(t, w, rotations=True)
    kept = {
        5050: ([0.7146853124706719, -0.3259288680728145, 0.5708712365852477,
                12.221361787740541, 1.749646457758201, -1.9874487606182996,
                10.877468011767812, -5.052593588149126, 4.1511548425773945],
               [-0.7339062116259278, 0.6273213041693384, 0.26047966114873655,
                -0.0015140917833552895, 0.38196901462413996, -0.9241738902355648,
                -0.6792491296004323, -0.6786513487810536, -0.27937961044912457]),
        20000: ([2.466290316271329, -2.715699679994194, -5.345150579917131,
                 -1.3655453046455743, -7.082983835890792, -54.54050015252016,
                 8.952348042814883, -5.2070108265990624, -3.5925968251763996],
                [0.7892085006477908, -0.6076677926954198, 0.08882452491256074,
                 -0.3869969538576224, -0.3797931059073287, 0.8402324407032723,
                 -0.4768472503959545, -0.6974934052920639, -0.5349015324000048]),
    }
    for k, (c, r) in kept.items():
        assert np.max(np.abs(C[k].ravel() - c)) < 1e-12 * 55.0, k
        assert np.max(np.abs(R[k].ravel() - r)) < 1e-12, k
