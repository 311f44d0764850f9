"""The tracker's whiteness test sees correlation, not an error in the noise level."""
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
