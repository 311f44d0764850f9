"""The chi-square upper tail and quantile and the normal quantile equal scipy's to rounding."""
from __future__ import annotations

import math

import numpy as np
import pytest

from inertia_ros.core.estimation.tails import chi2_isf, chi2_sf, normal_isf


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


@pytest.mark.parametrize('dof, x', [(1983, 2050.0), (2000, 1401.0), (3000, 3100.0),
                                    (10_000, 9_800.0), (1001, 1500.0), (3, 1500.0)])
def test_chi2_sf_large_statistics(dof: int, x: float) -> None:
    """Where ``exp(-x/2)`` underflows (x > ~1400) but the tail does not (``dof`` near ``x``,
    an average-NIS or window test over many blocks): scipy's tail to 1e-10 relative; it
    returned 0.0 for (2050, 1983), whose tail is 0.144."""
    from scipy.special import chdtrc
    want = float(chdtrc(dof, x))
    assert chi2_sf(x, dof) == pytest.approx(want, rel=1e-10, abs=1e-300)


def test_chi2_sf_edges() -> None:
    """x <= 0 is certain, infinity impossible, nan propagates; dof must be a positive integer."""
    assert chi2_sf(0.0, 3) == 1.0 and chi2_sf(-1.0, 2) == 1.0
    assert chi2_sf(math.inf, 5) == 0.0 and math.isnan(chi2_sf(math.nan, 4))
    assert chi2_sf(1e300, 27) == 0.0                  # no overflow of x^k
    for bad in (0, -2, 2.5, 10_001):
        with pytest.raises(ValueError, match='dof'):
            chi2_sf(1.0, bad)


@pytest.mark.parametrize('dof', [1, 3, 6, 30, 300])
def test_chi2_isf_equals_scipy(dof: int) -> None:
    """The quantile (the tracker's change threshold) within 1e-12 relative of scipy's."""
    from scipy.special import chdtri

    for level in (0.4, 1e-2, 1e-3, 1e-6, 1e-10):
        assert chi2_isf(level, dof) == pytest.approx(float(chdtri(dof, level)), rel=1e-12)


def test_normal_isf_equals_scipy() -> None:
    """The normal upper quantile (the spectral evidence's threshold) within 1e-12 relative."""
    from scipy.special import ndtri

    for p in np.logspace(-14, math.log10(0.45), 60):
        assert normal_isf(p) == pytest.approx(float(-ndtri(p)), rel=1e-12), p


def test_quantile_edges() -> None:
    """A level outside the open interval is one ValueError naming it."""
    for bad in (0.0, 1.0, -0.1, math.nan):
        with pytest.raises(ValueError, match='level'):
            chi2_isf(bad, 3)
    with pytest.raises(ValueError, match='p: '):
        normal_isf(0.5)
