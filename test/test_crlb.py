"""Cramer-Rao bound: Fisher information of the gyro + torque model, validated three ways."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from inertia_ros.core.crlb import (
    fisher_information,
    frobenius_weights,
    prediction_error_step,
    scene_fisher,
)
from inertia_ros.core.estimation import estimate
from inertia_ros.core.inertia import matrix_to_theta, theta_to_matrix
from inertia_ros.core.scene import Scene
from inertia_ros.core.simulation import simulate

SHORT = {
    'name': 'short', 'seed': 3, 'duration': 10.0,
    'body': {'inertia': [1.0, 1.2, 0.9, 0.05, -0.03, 0.02]},
    'initial_omega': [0.05, -0.03, 0.02],
    'torque': [{'type': 'multisine', 'amplitude': 0.2, 'axes': ['x', 'y', 'z'],
                'f_min': 0.1, 'f_max': 2.0}],
    'command_rate': 20.0,
    'gyro': {'rate': 100.0, 'noise_std': 0.004},
    'torque_sensor': {'rate': 20.0, 'noise_rel': 0.05},
}
I_TRUE = theta_to_matrix(np.array([1.0, 1.2, 0.9, 0.05, -0.03, 0.02]))
W0 = np.array([0.05, -0.03, 0.02])


def _tiny(n_gyro: int = 41, n_tau: int = 11, seed: int = 0):
    """A tiny record: gyro 40 Hz over 1 s, torque samples every 0.1 s."""
    rng = np.random.default_rng(seed)
    tg = np.arange(n_gyro) / 40.0
    ts = np.arange(n_tau) / 10.0
    tau = rng.uniform(-0.5, 0.5, size=(n_tau, 3))
    return tg, ts, tau


def test_trajectory_matches_simulator() -> None:
    """The model trajectory equals the simulator's true angular velocity (atol 1e-12)."""
    sim = simulate(Scene.from_dict(SHORT), seed=0)
    fr = scene_fisher(sim)
    np.testing.assert_allclose(fr.omega, sim.omega_true, rtol=0, atol=1e-12)


def test_sensitivities_match_finite_differences() -> None:
    """d omega / d p from the variational equations equals central differences (rtol 1e-6)."""
    tg, ts, tau = _tiny()
    d = np.array([0.01, -0.02, 0.015])
    fr = fisher_information(tg, ts, tau, I_TRUE, W0, gyro_std=1e-3, disturbance=d,
                            estimate_bias=True)
    theta = matrix_to_theta(I_TRUE)
    p0 = np.concatenate([theta, W0, d])
    num = np.empty_like(fr.sensitivity)
    for k in range(p0.size):
        h = 1e-6
        out = []
        for s in (+1, -1):
            p = p0.copy()
            p[k] += s * h
            out.append(fisher_information(tg, ts, tau, theta_to_matrix(p[:6]), p[6:9],
                                          gyro_std=1e-3, disturbance=p[9:]).omega)
        num[:, :, k] = (out[0] - out[1]) / (2 * h)
    scale = np.max(np.abs(num), axis=(0, 1))
    np.testing.assert_allclose(fr.sensitivity / scale, num / scale, rtol=0, atol=1e-6)


def test_zero_torque_noise_is_output_least_squares() -> None:
    """Without torque noise F equals sum J'J / sigma_g^2 of the output sensitivities."""
    tg, ts, tau = _tiny()
    sg = np.array([1e-3, 2e-3, 1.5e-3])
    fr = fisher_information(tg, ts, tau, I_TRUE, W0, gyro_std=sg, torque_std=0.0)
    J = fr.sensitivity / sg[None, :, None]
    F = np.einsum('nrp,nrq->pq', J, J)
    np.testing.assert_allclose(fr.information, F, rtol=1e-12, atol=0)


def test_kalman_information_equals_dense_covariance() -> None:
    """With torque noise, the Kalman-filter F equals J' R^-1 J with R built densely (rtol 1e-6)."""
    tg, ts, tau = _tiny()
    sg, st = 1e-3, np.array([0.02, 0.03, 0.01])
    fr = fisher_information(tg, ts, tau, I_TRUE, W0, gyro_std=sg, torque_std=st)
    # G[:, j, c] = d omega / d tau_jc by central differences (the model is smooth)
    n, m = len(tg), len(ts)
    G = np.empty((n * 3, m * 3))
    h = 1e-6
    for j in range(m):
        for c in range(3):
            out = []
            for s in (+1, -1):
                tq = tau.copy()
                tq[j, c] += s * h
                out.append(fisher_information(tg, ts, tq, I_TRUE, W0, gyro_std=sg).omega)
            G[:, 3 * j + c] = ((out[0] - out[1]) / (2 * h)).ravel()
    R = sg ** 2 * np.eye(n * 3) + G @ np.diag(np.tile(st ** 2, m)) @ G.T
    J = fr.sensitivity.reshape(n * 3, -1)
    F = J.T @ np.linalg.solve(R, J)
    np.testing.assert_allclose(fr.information, F, rtol=1e-6, atol=0)


def test_torque_noise_only_loses_information() -> None:
    """Process noise can only lower the information: F_clean - F_noisy is PSD (atol 1e-9 rel)."""
    sim = simulate(Scene.from_dict(SHORT), seed=0)
    noisy = scene_fisher(sim).information
    clean = fisher_information(sim.t_gyro, sim.t_torque, sim.torque_command, sim.inertia,
                               sim.omega_true[0], gyro_std=SHORT['gyro']['noise_std']
                               ).information
    d = np.sqrt(np.diag(clean))
    lam = np.linalg.eigvalsh((clean - noisy) / d[:, None] / d[None, :])
    assert lam[0] >= -1e-9
    assert np.trace(np.linalg.inv(noisy)[:6, :6]) > 1.05 * np.trace(np.linalg.inv(clean)[:6, :6])


def test_bias_nuisance_inflates_bound() -> None:
    """Estimating the disturbance as a nuisance never tightens the bound on theta (rtol 1e-9)."""
    sim = simulate(Scene.from_dict(SHORT), seed=0)
    without = scene_fisher(sim, estimate_bias=False).theta_std()
    with_bias = scene_fisher(sim, estimate_bias=True).theta_std()
    assert np.all(with_bias >= without * (1 - 1e-9))


@pytest.mark.slow
def test_monte_carlo_never_beats_bound() -> None:
    """An unbiased estimator's per-element MSE over 60 seeded runs is not below the bound.

    The floor is the 0.1 % quantile of chi2(R)/R (Bonferroni over 6 elements): a Gaussian
    estimator exactly at the bound falls below it with probability 1e-3.  The estimator must
    also be within 4x of the bound in total (the bound is not vacuous).
    """
    scene = Scene.from_dict(SHORT)
    bound = np.diag(scene_fisher(simulate(scene, seed=0)).theta_covariance())
    runs = 60
    errs = np.empty((runs, 6))
    for s in range(runs):
        sim = simulate(scene, seed=100 + s)
        r = estimate(sim.t_gyro, sim.omega, sim.t_torque, sim.torque, method='integral',
                     model='full', torque_bias='off', physical=False)
        errs[s] = matrix_to_theta(r.inertia) - matrix_to_theta(sim.inertia)
    mse = np.mean(errs ** 2, axis=0)
    floor = stats.chi2.ppf(1e-3 / 6, runs) / runs
    assert np.all(mse >= floor * bound), mse / bound
    assert np.sum(bound) / np.sum(mse) > 0.25


def test_frobenius_bound_counts_off_diagonals_twice() -> None:
    """frobenius_mse is sum of diagonal bounds with weights 1,1,1,2,2,2 (rtol 1e-12)."""
    tg, ts, tau = _tiny()
    fr = fisher_information(tg, ts, tau, I_TRUE, W0, gyro_std=1e-3)
    var = np.diag(fr.theta_covariance())
    np.testing.assert_allclose(fr.frobenius_mse(), float(frobenius_weights() @ var),
                               rtol=1e-12, atol=0)
    np.testing.assert_allclose(frobenius_weights(), [1, 1, 1, 2, 2, 2], rtol=0, atol=0)


@pytest.mark.parametrize(('kwargs', 'message'), [
    ({'gyro_std': 0.0}, 'gyro_std: must be > 0'),
    ({'gyro_std': -1.0}, 'gyro_std: must be finite and >= 0'),
    ({'torque_std': [1.0, np.nan, 0.0]}, 'torque_std: must be finite'),
    ({'inertia': np.eye(3) * -1}, 'inertia: must be a symmetric positive definite'),
    ({'omega0': [0.0, 1.0]}, 'omega0: expected a finite 3-vector'),
    ({'disturbance': [0.0, 0.0]}, 'disturbance: expected a finite 3-vector'),
    ({'torque': np.zeros((3, 3))}, 'torque: expected finite shape'),
    ({'t_gyro': np.array([0.0, 0.0, 1.0])}, 't_gyro: times must be strictly increasing'),
])
def test_validation_messages(kwargs: dict, message: str) -> None:
    """Bad arguments raise ValueError naming the argument."""
    tg, ts, tau = _tiny()
    args = {'t_gyro': tg, 't_torque': ts, 'torque': tau, 'inertia': I_TRUE, 'omega0': W0,
            'gyro_std': 1e-3}
    args.update(kwargs)
    with pytest.raises(ValueError, match=message.replace('(', r'\(')):
        fisher_information(**args)


def test_scene_fisher_rejects_inertia_change() -> None:
    """A record with an inertia change is refused with a message naming sim."""
    d = dict(SHORT, inertia_change={'time': 5.0, 'inertia': [1.1, 1.2, 0.9, 0, 0, 0]})
    sim = simulate(Scene.from_dict(d), seed=0)
    with pytest.raises(ValueError, match='sim: the bound assumes a constant tensor'):
        scene_fisher(sim)


def test_prediction_error_steps_converge_on_exact_data() -> None:
    """Gauss-Newton on noise-free data recovers theta and w0 from a 3 % error (atol 1e-9)."""
    tg, ts, tau = _tiny()
    st = np.array([0.02, 0.03, 0.01])
    y = fisher_information(tg, ts, tau, I_TRUE, W0, gyro_std=1e-3).omega
    truth = np.concatenate([matrix_to_theta(I_TRUE), W0])
    p = truth * np.array([1.03, 0.97, 1.02, 0.9, 1.1, 0.95, 1.05, 0.95, 1.02])
    for _ in range(4):
        p = p + prediction_error_step(tg, y, ts, tau, theta_to_matrix(p[:6]), p[6:9],
                                      gyro_std=1e-3, torque_std=st).step
    np.testing.assert_allclose(p, truth, rtol=0, atol=1e-9)
    at_truth = prediction_error_step(tg, y, ts, tau, I_TRUE, W0, gyro_std=1e-3, torque_std=st)
    np.testing.assert_allclose(at_truth.cost, 0.0, rtol=0, atol=1e-20)


def test_prediction_error_step_rejects_bad_omega() -> None:
    """A gyro array of the wrong shape raises ValueError naming omega."""
    tg, ts, tau = _tiny()
    with pytest.raises(ValueError, match='omega: expected finite shape'):
        prediction_error_step(tg, np.zeros((3, 3)), ts, tau, I_TRUE, W0, gyro_std=1e-3)
