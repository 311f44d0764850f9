"""The gyroscopic noise walk (``noise.gyroscopic_walk_cov``), the torque-noise covariance every
anchored fit adds for the gyro noise its gyroscopic term integrates."""
from __future__ import annotations

import numpy as np

from inertia_ros.core.estimation.noise import gyroscopic_walk_cov


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def test_walk_equals_its_definition_and_a_monte_carlo() -> None:
    """Equals ``dt_g/dt_tau sum_ij E[w_i w_j] A_i S_g A_j'`` with ``A_i = [e_i]x I - [I e_i]x``
    (to 1e-14), and the sample covariance of ``J(w) n`` over random rates and gyro noise (to
    5 %), for random tensors, noise levels and rate moments."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        B = rng.normal(size=(3, 3))
        inertia = B @ B.T + 0.5 * np.eye(3)
        gyro_var = rng.uniform(1e-6, 1e-4, size=3)
        w = rng.normal(size=(200_000, 3)) * rng.uniform(0.5, 5.0, size=3) + rng.normal(size=3)
        m2 = w.T @ w / len(w)
        got = gyroscopic_walk_cov(inertia, gyro_var, m2, 0.005, 0.02)
        A = [_skew(e) @ inertia - _skew(inertia @ e) for e in np.eye(3)]
        want = sum(m2[i, j] * (A[i] @ np.diag(gyro_var) @ A[j].T)
                   for i in range(3) for j in range(3)) * (0.005 / 0.02)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14 * np.abs(want).max())
        n = rng.normal(size=w.shape) * np.sqrt(gyro_var)
        # J(w) n = w x (I n) + n x (I w), to first order in n
        jn = np.cross(w, n @ inertia) + np.cross(n, w @ inertia)
        mc = jn.T @ jn / len(jn) * (0.005 / 0.02)
        np.testing.assert_allclose(got, mc, rtol=0, atol=0.05 * np.abs(mc).max())
    assert np.all(gyroscopic_walk_cov(inertia, gyro_var, None, 0.005, 0.02) == 0)
