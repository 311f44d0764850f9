"""The adequacy widening grows continuously with what the tests saw (issue 27 item 4).

Before 2026-11-28 a test widened the covariance only below p = 0.05: a cliff.  A 0.002 rad/s
gyro bias on a 20 s torque-free tumble, fed to the recursive estimator as one block, had its
segment shift at chi2 11.0 on 5 dof (p 0.051) and stayed ``scale_unobservable`` at |z| 5.5
with the noise model's sigma, while the same shift at p 0.049 widened the covariance 2.2x.
Now every test widens as soon as its chi2 exceeds its dof (:func:`.adequacy.saw_mismatch`).
"""
from __future__ import annotations

import numpy as np
import pytest

from inertia_ros.core.estimation.adequacy import MAX_WIDENING, check_adequacy, saw_mismatch
from inertia_ros.core.estimation.tails import chi2_sf

_NO_WINDOWS = (np.zeros((0, 6)), np.zeros((0, 6, 6)), np.zeros(0))


def _shift(chi2: float, dof: int = 5):
    return check_adequacy(*_NO_WINDOWS, excess=1.0, shift=(chi2, dof, chi2_sf(chi2, dof), 2.0))


def test_shift_just_above_the_old_level_widens_by_its_ratio() -> None:
    """chi2 11.0 on 5 dof (p 0.051, the one-block tumble's): ok, covariance x 2.2 (was 1)."""
    a = _shift(11.0)
    assert 0.05 < a.shift_p_value < 0.055
    assert a.ok and a.benign and a.inflation == pytest.approx(2.2)


def test_widening_has_no_step_at_a_level() -> None:
    """Across p = 0.05 (chi2 11.07 on 5 dof) the factor moves by what the chi2 moved (< 1 %;
    before: 1 -> 2.2), and from chi2 = dof up it starts at 1 and grows with the chi2."""
    lo, hi = _shift(11.0), _shift(11.14)
    assert lo.shift_p_value > 0.05 > hi.shift_p_value
    assert hi.inflation / lo.inflation == pytest.approx(11.14 / 11.0, rel=1e-9)
    grid = np.linspace(0.0, 19.0, 96)
    f = np.array([_shift(c).inflation for c in grid])
    assert np.all(f[grid <= 5.0] == 1.0)
    assert np.all(np.diff(f) >= 0.0) and np.max(np.diff(f)) <= 19.0 / 95 / 5 + 1e-12
    assert _shift(5.05).inflation == pytest.approx(1.01)


def test_window_scatter_and_split_widen_without_a_level() -> None:
    """Window scatter at p 0.35 (chi2 16.5 on 15 dof, Birge ratio 1.1, 4 windows): covariance x
    1 + 4 (B - 1) = 1.4 (was 1); a bias split at chi2 4 on 3 dof (p 0.26): x 4/3 (was 1)."""
    th = np.zeros((4, 5))
    th[0, 0], th[1, 0] = np.sqrt(8.25), -np.sqrt(8.25)          # chi2 = 2 * 8.25 about 0
    covs = np.broadcast_to(np.eye(5), (4, 5, 5)).copy()
    a = check_adequacy(th, covs, np.arange(4) * 10.0 + 5.0, 1.0)
    assert (a.chi2, a.dof) == (pytest.approx(16.5), 15) and 0.3 < a.p_value < 0.4
    assert a.ok and a.change_at is None and a.inflation == pytest.approx(1.4)
    b = check_adequacy(*_NO_WINDOWS, excess=1.0, split=(4.0, 3, chi2_sf(4.0, 3)))
    assert b.ok and b.inflation == pytest.approx(4.0 / 3.0)


def test_status_rule_unchanged() -> None:
    """The status does not depend on the widening's gate: a shift below its dof is not
    widened; one of 4.2 per dof (p 1e-4 < p < 0.05) is model_mismatch; a failure at 1e-4 too."""
    assert _shift(4.0).inflation == 1.0 and _shift(4.0).ok
    s = _shift(21.0)
    assert 1e-4 < s.shift_p_value < 0.05 and not s.ok and not s.benign
    assert s.inflation == pytest.approx(21.0 / 5) and s.inflation > MAX_WIDENING
    assert not saw_mismatch((float('nan'), 0), (3.0, 5), (2.9, 3))
    assert saw_mismatch((16.0, 15), (float('nan'), 0))
