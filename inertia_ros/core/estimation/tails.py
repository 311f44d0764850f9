"""Upper tail and upper quantile of the chi-square distribution for the tests' integer degrees
of freedom, and the standard normal's upper quantile: the package's one implementation of each.

The Wald tests of model selection and the window test of model adequacy need
``P(chi2_k > x)`` for integer ``k`` (at most a few dozen).  For integer ``k`` it is a finite
sum (Abramowitz & Stegun 26.4.4 and 26.4.5):

* even ``k``: ``exp(-x/2) sum_{i < k/2} (x/2)^i / i!``;
* odd ``k``: ``erfc(sqrt(x/2)) + exp(-x/2) sqrt(2x/pi) sum_{r < (k-1)/2} x^r / (3 5 ... (2r+1))``;

all terms positive (no cancellation), each built from the last so nothing overflows; above
``x = 1400``, where ``exp(-x/2)`` underflows although a tail with ``k`` near ``x`` does not, the
same terms are summed as logarithms.  It equals ``scipy.special.chdtrc`` to ~1e-14 (~1e-11 in
the logarithmic range; tested), without importing scipy: the command-line
estimate of an hour-long log would otherwise pay ~0.1 s of its start-up for scipy.special
(and the scipy base it loads) to evaluate a handful of p-values.

The quantiles invert it: :func:`chi2_isf` by bisection, :func:`normal_isf` as
``sqrt(chi2_isf(2 p, 1))``; both equal scipy's to ~1e-15 (tested), whose 2 us a call against
160 us would cost 0.125 s of ``scipy.special`` import for a handful of quantiles a run.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ['chi2_isf', 'chi2_sf', 'normal_isf']

#: Largest degrees of freedom accepted (the tests use at most a few dozen).
MAX_DOF = 10_000


def chi2_sf(x: float, dof: int) -> float:
    """``P(chi2_dof > x)``, the chi-square upper tail for integer ``dof``.

    Parameters
    ----------
    x : float
        Statistic (dimensionless); ``x <= 0`` gives 1.
    dof : int
        Degrees of freedom, ``1 <= dof <= MAX_DOF``.

    Returns
    -------
    float
        The tail probability in [0, 1] (``nan`` for a ``nan`` statistic).

    Raises
    ------
    ValueError
        ``dof`` not an integer in ``[1, MAX_DOF]``.
    """
    k = int(dof)
    if k != dof or not 1 <= k <= MAX_DOF:
        raise ValueError(f'dof: expected an integer in [1, {MAX_DOF}], got {dof!r}')
    x = float(x)
    if math.isnan(x):
        return math.nan
    if x <= 0.0:
        return 1.0
    if math.isinf(x):
        return 0.0
    if x > 1400.0:      # exp(-x/2) near underflow: the same sum term by term in logarithms
        return _chi2_sf_log(x, k)
    if k % 2 == 0:
        total, term = 0.0, math.exp(-0.5 * x)
        for i in range(k // 2):
            total += term
            term *= 0.5 * x / (i + 1)
    else:
        total = math.erfc(math.sqrt(0.5 * x))
        term = math.exp(-0.5 * x) * math.sqrt(2.0 * x / math.pi)
        for r in range(1, (k - 1) // 2 + 1):
            total += term
            term *= x / (2 * r + 1)
    return min(total, 1.0)


def _chi2_sf_log(x: float, k: int) -> float:
    """:func:`chi2_sf` for ``x > 1400``, where ``exp(-x/2)`` underflows but the tail need not
    (``x`` near ``k`` in the thousands): the same terms as logarithms, summed scaled by the
    largest (the odd case's ``erfc`` term is below 1e-300 there and left out)."""
    h = 0.5 * x
    if k % 2 == 0:
        i = np.arange(k // 2)
        logs = -h + i * math.log(h) - _lgamma(i + 1.0)
    else:
        r = np.arange((k - 1) // 2)
        logs = (-h + 0.5 * math.log(2.0 * x / math.pi) + r * math.log(x)
                - (_lgamma(2.0 * r + 2.0) - r * math.log(2.0) - _lgamma(r + 1.0)))
    if logs.size == 0:
        return 0.0
    top = float(logs.max())
    return min(math.exp(top) * float(np.exp(logs - top).sum()), 1.0)


def _lgamma(v: np.ndarray) -> np.ndarray:
    """``log Gamma`` of each element of ``v`` (> 0)."""
    return np.array([math.lgamma(float(a)) for a in np.ravel(v)]).reshape(np.shape(v))


def chi2_isf(level: float, dof: int) -> float:
    """``q`` with ``P(chi2_dof > q) = level`` for ``0 < level < 1`` and integer ``1 <= dof
    <= MAX_DOF``: bisection on :func:`chi2_sf` (to its rounding)."""
    if not 0.0 < level < 1.0:
        raise ValueError(f'level: expected a probability in (0, 1), got {level!r}')
    lo, hi = 0.0, 400.0
    while chi2_sf(hi, dof) > level:
        lo, hi = hi, 2.0 * hi
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if chi2_sf(mid, dof) > level else (lo, mid)
    return 0.5 * (lo + hi)


def normal_isf(p: float) -> float:
    """``z`` with ``P(N(0, 1) > z) = p`` for ``0 < p < 0.5``: ``sqrt`` of the 1-dof
    :func:`chi2_isf` at ``2 p``."""
    if not 0.0 < p < 0.5:
        raise ValueError(f'p: expected a probability in (0, 0.5), got {p!r}')
    return math.sqrt(chi2_isf(2.0 * p, 1))
