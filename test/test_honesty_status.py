"""Status that means something, sigma true under mismatch (issue 27 items 3 and 4).

Unit checks of the adequacy decision (:mod:`inertia_ros.core.estimation.adequacy`) on
synthetic window estimates with a known scatter, and reduced seeded Monte Carlo on the
independent reference simulator (``bench/truth_sim.py``) through ``estimate()`` with its
defaults; the full figures and commands are in docs/BENCHMARKS.md ("Honesty").
"""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.core.estimation.adequacy import (
    MAX_WIDENING,
    check_adequacy,
    segment_shift,
)


def _windows(scale: float, K: int = 4, p: int = 6, seed: int = 0, step: float = 0.0):
    """K window estimates of p parameters whose scatter is ``scale`` x their stated sigma."""
    rng = np.random.default_rng(seed)
    cov = np.eye(p) * 1e-4
    th = 1.0 + rng.normal(0.0, 1e-2 * scale, (K, p))
    th[K // 2:] += step
    return th, np.broadcast_to(cov, (K, p, p)).copy(), np.arange(K) * 10.0 + 5.0


def test_noise_model_scatter_is_ok_and_not_widened() -> None:
    """Windows that scatter as their covariances say: ok, covariance factor 1."""
    a = check_adequacy(*_windows(1.0), excess=1.0)
    assert a.ok and a.benign and a.inflation == 1.0


def test_small_scatter_is_ok_with_the_sigma_widened_by_it() -> None:
    """Scatter 1.7x sigma (Birge ratio 2.3, p ~ 4e-6): ok (benign), widened by that ratio."""
    a = check_adequacy(*_windows(1.7, K=8, seed=1), excess=1.0)
    B = a.chi2 / a.dof
    assert not a.ok and a.benign, a
    assert 1.5 < B <= MAX_WIDENING and a.inflation == pytest.approx(B)


def test_large_scatter_or_a_step_is_a_mismatch() -> None:
    """Scatter 4x sigma: beyond what widening may cover; a step: located, never benign."""
    a = check_adequacy(*_windows(4.0, K=8, seed=2), excess=1.0)
    assert not a.ok and not a.benign and a.inflation > MAX_WIDENING
    s = check_adequacy(*_windows(1.0, K=8, seed=3, step=0.05), excess=1.0)
    assert not s.benign and s.change_at == pytest.approx(40.0)


def test_segment_shift_calibrated_and_sensitive() -> None:
    """Under the model d ~ N(0, Cs - Cl): chi2 averages its dof; an 8-sigma shift fails."""
    rng = np.random.default_rng(0)
    Cl = np.diag([1.0, 2.0, 0.5, 1.0, 1.0, 3.0]) * 1e-6
    Cs = 3.0 * Cl
    L = np.linalg.cholesky(Cs - Cl)
    stats = [segment_shift(np.zeros(6), Cl, L @ rng.normal(size=6), Cs)[0] for _ in range(400)]
    assert 5.0 < np.mean(stats) < 7.0
    d = np.zeros(6)
    d[2] = 8.0 * np.sqrt(Cl[2, 2])
    chi2, dof, p, max_sigma = segment_shift(np.zeros(6), Cl, d, Cs)
    assert dof == 6 and p < 1e-4 and max_sigma == pytest.approx(8.0)
