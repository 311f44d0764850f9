"""A nearly singular first-pass tensor gives a usable equation weight, never a traceback."""
import numpy as np

from inertia_ros.core.estimation import estimate
from inertia_ros.core.estimation.fit import equation_weight
from inertia_ros.core.tensor import check_physical, matrix_to_theta


def test_nearly_singular_tensor_weight_is_conditioned():
    """A plate that check_physical accepts (smallest moment 2e-9 of the largest): its
    weight ``(I S_g I)^-1`` had a condition number of 4e16 (d5ad26d), now that of the
    projected tensor (min moment 1e-3 of the elements' sum): below 1e8."""
    c, s = np.cos(0.4), np.sin(0.4)
    R = np.array([[1, 0, 0], [0, c, -s], [0, s, c]]) @ np.array([[c, 0, s], [0, 1, 0],
                                                                 [-s, 0, c]])
    I = R @ np.diag([5e-10, 0.25, 0.25]) @ R.T
    assert check_physical(I).valid
    W = equation_weight(matrix_to_theta(I), np.array([1e-8, 9e-9, 9.6e-9]))
    assert np.all(np.isfinite(W)) and np.linalg.cond(W) < 1e8


def test_record_whose_held_fit_is_a_plate_gets_a_status():
    """Sines unrelated to the torque: the held fit is nearly singular; the hold comparison
    weighted by it raised LinAlgError (d5ad26d); a status now, as on the issue-day code."""
    rng = np.random.default_rng(0)
    t = np.arange(2001) * 0.005
    w = 0.3 * np.sin(np.outer(t, [1.0, 1.3, 0.7])) + 1e-4 * rng.standard_normal((len(t), 3))
    ts = np.arange(501) * 0.02
    tau = 0.1 * np.sin(np.outer(ts, [1.1, 0.9, 1.7]))
    est = estimate(t, w, ts, tau, method='integral')
    assert est.status != 'ok'
