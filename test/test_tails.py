"""The chi-square upper tail of the model tests equals scipy's to ~1e-13."""
from __future__ import annotations

import math

import numpy as np
import pytest

from inertia_ros.core.estimation.tails import chi2_sf


@pytest.mark.parametrize('dof', [1, 2, 3, 4, 5, 6, 9, 18, 27, 60])
def test_chi2_sf_equals_scipy(dof: int) -> None:
    """Over 1e-6 <= x <= 1e3 (down to tails of 1e-290), relative error below 1e-12."""
    from scipy.special import chdtrc

    for x in np.logspace(-6, 3, 300):
        want = float(chdtrc(dof, x))
        got = chi2_sf(x, dof)
        if want > 1e-290:
            assert abs(got - want) <= 1e-12 * want, (dof, x, got, want)
        else:
            assert got <= 1e-280


def test_chi2_sf_edges() -> None:
    """x <= 0 is certain, infinity impossible, nan propagates; dof must be a positive integer."""
    assert chi2_sf(0.0, 3) == 1.0 and chi2_sf(-1.0, 2) == 1.0
    assert chi2_sf(math.inf, 5) == 0.0 and math.isnan(chi2_sf(math.nan, 4))
    assert chi2_sf(1e300, 27) == 0.0                  # no overflow of x^k
    for bad in (0, -2, 2.5, 10_001):
        with pytest.raises(ValueError, match='dof'):
            chi2_sf(1.0, bad)
