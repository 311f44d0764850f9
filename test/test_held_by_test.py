"""A zero chosen by a test is not reported as known; the restricted fit does not depend on the
torque-bias setting (issue 27, post-selection).

* ``model='auto'`` picking a restricted parameter set reports the elements it holds with the
  full fit's covariance (``diagnostics.model_selection.held_sigma_from = 'full fit'``), on the
  batch (integral, ml), recursive and reused-selection paths; an explicit ``model='diagonal'``
  (the user's assertion) keeps them at 0 +- 0.
* With ``torque_bias='auto'`` a fit without the bias uses the segment length searched without
  it, so the diagonal fit equals the one of ``torque_bias='off'``.
"""
from __future__ import annotations

import numpy as np
import pytest
from test_estimation import add_noise, noise_free

from inertia_ros.core.estimation import RecursiveEstimator, estimate
from inertia_ros.core.estimation.fit import Fit
from inertia_ros.core.estimation.selection import held_by_test
from inertia_ros.core.inertia import matrix_to_theta

DIAGONAL = [1.0, 1.2, 0.9, 0.0, 0.0, 0.0]
#: a seed on which auto picks the diagonal model, the bias dropped, and the segment search
#: with the bias chooses one whole segment while without it 10 s (main ceead09: the diagonal
#: fit's yy 1.19850 with torque_bias='auto', 1.20003 with 'off')
SEED = 2005


@pytest.fixture(scope='module')
def record():
    """The 20 s default scene with a diagonal truth, one noise draw."""
    sim = noise_free('default', duration=20.0, body={'inertia': DIAGONAL})
    return add_noise(sim, seed=SEED)


def _std(e) -> np.ndarray:
    return matrix_to_theta(e.inertia_std)


def test_auto_diagonal_reports_the_full_fits_sigma_of_the_products(record) -> None:
    """auto -> diagonal: the products 0 with the full fit's sigma (to 1e-6), the moments' sigma
    at least the restricted fit's own and the full fit's (2 %)."""
    auto = estimate(*record, method='integral', torque_bias='off')
    full = estimate(*record, method='integral', model='full', torque_bias='off')
    diag = estimate(*record, method='integral', model='diagonal', torque_bias='off')
    assert auto.model == 'diagonal' and auto.status == 'ok'
    assert np.all(matrix_to_theta(auto.inertia)[3:] == 0.0)
    assert np.allclose(_std(auto)[3:], _std(full)[3:], rtol=1e-6), (_std(auto), _std(full))
    assert np.all(_std(auto)[3:] > 0.0)
    assert np.all(_std(auto)[:3] >= _std(diag)[:3] * (1 - 1e-9))
    assert np.all(_std(auto)[:3] >= _std(full)[:3] * 0.98), (_std(auto), _std(full))
    ms = auto.diagnostics['model_selection']
    assert ms['held_sigma_from'] == 'full fit'
    assert np.all(np.linalg.eigvalsh(np.asarray(auto.covariance)) > -1e-15)


def test_explicit_diagonal_keeps_the_products_known(record) -> None:
    """model='diagonal' is the user's assertion: products 0 +- 0, no held covariance."""
    for method in ('integral', 'ml'):
        e = estimate(*record, method=method, model='diagonal')
        assert e.model == 'diagonal'
        assert np.all(_std(e)[3:] == 0.0), _std(e)
        assert 'held_sigma_from' not in (e.diagnostics.get('model_selection') or {})


def test_ml_keeps_the_held_sigma(record) -> None:
    """The ml refinement of an auto-diagonal integral estimate keeps the products' sigma."""
    e = estimate(*record, method='ml')
    assert e.method == 'ml' and e.model == 'diagonal'
    full = estimate(*record, method='integral', model='full')
    assert np.allclose(_std(e)[3:], _std(full)[3:], rtol=1e-6), (_std(e), _std(full))


def test_recursive_reused_selection_keeps_the_held_sigma(record) -> None:
    """The recursive estimator, the diagonal choice reused between selections: products'
    sigma > 0 on every estimate, fresh and reused (0 with model='diagonal')."""
    t_g, w, t_t, tau = record
    seen = set()
    for model in ('auto', 'diagonal'):
        rec = RecursiveEstimator(model=model, reselect_every=3)
        for k in range(1, 41):
            g0, g1 = (k - 1) * len(t_g) // 40, k * len(t_g) // 40
            s0, s1 = (k - 1) * len(t_t) // 40, k * len(t_t) // 40
            rec.add_torque(t_t[s0:s1], tau[s0:s1])
            rec.add_gyro(t_g[g0:g1], w[g0:g1])
            e = rec.estimate()
            if e.status != 'ok' or k < 30:
                continue
            assert e.model == 'diagonal'
            if model == 'auto':
                assert np.all(_std(e)[3:] > 0.0), (k, _std(e))
                seen.add(bool(e.diagnostics['model_selection'].get('reused')))
            else:
                assert np.all(_std(e)[3:] == 0.0)
    assert seen == {True, False}


def test_restricted_fit_does_not_depend_on_the_bias_setting(record) -> None:
    """torque_bias='auto' (bias dropped) and 'off': the same diagonal fit (1e-5 relative) and
    sigma (1 %); main ceead09 differed by 1.3e-3 in yy (0.9 of its sigma), sigma 2x."""
    a = estimate(*record, method='integral', model='diagonal', torque_bias='auto')
    o = estimate(*record, method='integral', model='diagonal', torque_bias='off')
    assert a.model == o.model == 'diagonal'
    assert np.allclose(np.diag(a.inertia), np.diag(o.inertia), rtol=1e-5), (
        np.diag(a.inertia), np.diag(o.inertia))
    assert np.allclose(_std(a)[:3], _std(o)[:3], rtol=0.01), (_std(a), _std(o))
    assert a.diagnostics['segment_s'] == o.diagnostics['segment_s']
    sel = a.diagnostics['segment_selection']
    assert sel['without_bias']['chosen_s'] == o.diagnostics['segment_selection']['chosen_s']


def _fit(beta: np.ndarray, cov: np.ndarray, basis: np.ndarray) -> Fit:
    p = len(beta)
    return Fit(beta=beta, cov=cov, H=np.eye(p), H0=np.eye(p), basis=basis, bias=False,
               resid_rms=np.zeros(3), n_eq=100)


def test_held_by_test_algebra() -> None:
    """One linear model (cov = J^-1): the result is the full fit's covariance; a restricted
    covariance larger than the full one on the kept elements is kept there."""
    rng = np.random.default_rng(1)
    A = rng.normal(size=(40, 6))
    J = A.T @ A
    cov_f = np.linalg.inv(J)
    B = np.eye(6)[:, :3]
    cov_r = np.linalg.inv(J[:3, :3])
    added = held_by_test(_fit(np.ones(3), cov_r, B), _fit(np.ones(6), cov_f, np.eye(6)))
    assert np.allclose(B @ cov_r @ B.T + added, cov_f, rtol=1e-9, atol=1e-12)
    big = 4.0 * cov_f[:3, :3]
    total = B @ big @ B.T + held_by_test(_fit(np.ones(3), big, B),
                                         _fit(np.ones(6), cov_f, np.eye(6)))
    assert np.all(np.linalg.eigvalsh(total[:3, :3] - big) > -1e-12)
    assert np.all(np.linalg.eigvalsh(total - cov_f) > -1e-12)
    assert np.allclose(total[3:, 3:], cov_f[3:, 3:])
