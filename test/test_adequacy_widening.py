"""The adequacy widening has no step at a significance level (issue 27 item 4).

Before 2026-11-28 a test widened the covariance only below p = 0.05: a cliff.  A 0.002 rad/s
gyro bias on a 20 s torque-free tumble, fed to the recursive estimator as one block, had its
segment shift at chi2 11.0 on 5 dof (p 0.051) and stayed ``scale_unobservable`` at |z| 5.5
with the noise model's sigma, while the same shift at p 0.049 widened the covariance 2.2x.
Now the widening is taken in full below :data:`WIDEN_ALPHA`, not at all above
:data:`WIDEN_FROM` and in proportion to log p between (:func:`widening_weight`).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from inertia_ros.core.estimation.adequacy import (
    MAX_WIDENING,
    WIDEN_ALPHA,
    WIDEN_FROM,
    check_adequacy,
    widening_weight,
)
from inertia_ros.core.estimation.tails import chi2_sf

_NO_WINDOWS = (np.zeros((0, 6)), np.zeros((0, 6, 6)), np.zeros(0))


def _shift(chi2: float, dof: int = 5):
    return check_adequacy(*_NO_WINDOWS, excess=1.0, shift=(chi2, dof, chi2_sf(chi2, dof), 2.0))


def test_shift_just_above_the_level_widens_nearly_in_full() -> None:
    """chi2 11.0 on 5 dof (p 0.051, the one-block tumble's): ok, covariance x ~2.15 (was 1)."""
    a = _shift(11.0)
    assert 0.05 < a.shift_p_value < 0.055
    w = widening_weight(a.shift_p_value)
    assert 0.95 < w < 1.0
    assert a.ok and a.benign and a.inflation == pytest.approx(1.0 + w * 1.2, rel=1e-12)
    assert a.inflation > 2.1


def test_widening_has_no_step_at_a_level() -> None:
    """Across p = 0.05 (chi2 11.07 on 5 dof) the factor moves by < 1 % (before: 1 -> 2.2);
    it is 1 above p 0.1 (chi2 9.24), and never falls as the chi2 grows."""
    lo, hi = _shift(11.06), _shift(11.08)
    assert lo.shift_p_value > WIDEN_ALPHA > hi.shift_p_value
    assert hi.inflation / lo.inflation == pytest.approx(1.0, abs=0.01)
    grid = np.linspace(0.0, 19.0, 381)
    f = np.array([_shift(c).inflation for c in grid])
    p = np.array([chi2_sf(c, 5) for c in grid])
    assert np.all(f[p >= WIDEN_FROM] == 1.0)
    assert np.all(np.diff(f) >= 0.0) and np.max(np.diff(f)) < 0.05   # no jump on a 0.05 step
    assert np.all(f[(p > WIDEN_ALPHA) & (p < WIDEN_FROM)] > 1.0)


def test_weight_is_log_linear_between_the_levels() -> None:
    assert widening_weight(0.01) == 1.0 and widening_weight(WIDEN_ALPHA) == 1.0
    assert widening_weight(WIDEN_FROM) == 0.0 and widening_weight(0.9) == 0.0
    mid = math.sqrt(WIDEN_ALPHA * WIDEN_FROM)
    assert widening_weight(mid) == pytest.approx(0.5)


def test_window_scatter_and_split_widen_in_part_between_the_levels() -> None:
    """Window scatter at chi2 23.5 on 15 dof (p 0.074, Birge ratio 1.57, 4 windows): covariance
    x 1 + w 4 (B - 1) (was 1); a bias split at p 0.35 is not widened."""
    th = np.zeros((4, 5))
    th[0, 0], th[1, 0] = np.sqrt(11.75), -np.sqrt(11.75)        # chi2 = 2 * 11.75 about 0
    covs = np.broadcast_to(np.eye(5), (4, 5, 5)).copy()
    a = check_adequacy(th, covs, np.arange(4) * 10.0 + 5.0, 1.0)
    assert (a.chi2, a.dof) == (pytest.approx(23.5), 15) and 0.05 < a.p_value < 0.1
    w = widening_weight(a.p_value)
    assert a.ok and a.change_at is None
    assert 0.0 < w < 1.0
    assert a.inflation == pytest.approx(1.0 + w * 4 * (23.5 / 15 - 1.0), rel=1e-9)
    b = check_adequacy(*_NO_WINDOWS, excess=1.0, split=(3.3, 3, chi2_sf(3.3, 3)))
    assert b.ok and b.inflation == 1.0


def test_status_rule_unchanged() -> None:
    """The status does not depend on the widening's gate: a shift below its dof is not
    widened; one of 4.2 per dof (p 1e-4 < p < 0.05) is model_mismatch, widened in full."""
    assert _shift(4.0).inflation == 1.0 and _shift(4.0).ok
    s = _shift(21.0)
    assert 1e-4 < s.shift_p_value < 0.05 and not s.ok and not s.benign
    assert s.inflation == pytest.approx(21.0 / 5) and s.inflation > MAX_WIDENING
