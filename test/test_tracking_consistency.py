"""The tracker's whiteness test sees correlation, not an error in the noise level; its fault
score test is chi-square under the model and sees a fault along its signature."""
from __future__ import annotations

import numpy as np

from inertia_ros.core.estimation.tracking_consistency import SKIP_S, InnovationTests


def _record(e: np.ndarray, scale: float) -> dict:
    """The tests' record of innovations ``e`` (n, 3) claimed with covariance ``scale * I``."""
    t = InnovationTests()
    for i, x in enumerate(e):
        t.add(SKIP_S + 0.1 * i, x, scale * np.eye(3), armed=True)
    return t.record()


def test_whiteness_is_blind_to_the_noise_level_and_sees_correlation():
    """300 blocks of white innovations whose claimed variance is 30 % low (a noise level
    estimated low): the average NIS rejects, the whiteness test does not (p > 0.01 on 10
    seeds; the unnormalised portmanteau, 2.04x its expectation, gave p 2.5e-5 on seed 0:
    it counted the level twice).  AR(1) innovations (rho 0.3) at the right level: the
    whiteness test rejects (p < 1e-6) and the average NIS does not."""
    for seed in range(10):
        rng = np.random.default_rng(seed)
        rec = _record(rng.standard_normal((300, 3)), 0.7)
        assert rec['anis_p_value'] < 1e-3 and rec['whiteness_p_value'] > 0.01, rec
        w = rng.standard_normal((300, 3))
        e = np.empty_like(w)
        e[0] = w[0]
        for i in range(1, len(w)):
            e[i] = 0.3 * e[i - 1] + np.sqrt(1 - 0.09) * w[i]
        rec = _record(e, 1.0)
        assert rec['whiteness_p_value'] < 1e-6 and rec['anis_p_value'] > 1e-3, rec


def _fault_p(rng: np.random.Generator, f: np.ndarray) -> float:
    """The fault score's p-value over 200 blocks of unit innovations plus ``D f``, the
    signature ``D = -G`` (3, 6) drawn afresh for each block (known before its innovation)."""
    t = InnovationTests()
    for i in range(200):
        G = rng.standard_normal((3, 6))
        t.sensitivity(np.zeros((3, 9)), G, 1.0, 1.0)
        t.add(SKIP_S + 0.1 * i, -G @ f + rng.standard_normal(3), np.eye(3), armed=True)
    return t.record()['fault_p_value']


def test_fault_score_is_chi_square_under_the_model_and_sees_a_fault():
    """Under the model the score statistic is chi2(6): of 300 seeds, 5 % +- 2.5 % below p
    0.05 and none below 1e-3 more than 3 times (binomial 99.8 % bounds: at most 2 expected).
    A fault of 0.1 per unit signature over the 180 blocks counted (noncentrality ~ 32): p <
    1e-3 on 9 of 10 seeds or more, where the average NIS (1.06 per dof, one standard
    deviation over 540 dof) cannot see it."""
    rng = np.random.default_rng(1)
    p = np.array([_fault_p(rng, np.zeros(6)) for _ in range(300)])
    assert 0.025 <= np.mean(p < 0.05) <= 0.075 and np.sum(p < 1e-3) <= 3, np.sort(p)[:20]
    p = np.array([_fault_p(rng, np.full(6, 0.1)) for _ in range(10)])
    assert np.sum(p < 1e-3) >= 9, p
