"""The tracker's adequacy test: Bar-Shalom's consistency tests on its innovations.

Under the model, the innovations ``nu_i`` (3,) of :class:`.tracking.TrackingEstimator`'s
blocks are independent ``N(0, S_i)``, so the whitened innovations ``e_i = C_i^-1 nu_i``
(``C_i C_i' = S_i``) are independent standard normal 3-vectors.  Over the ``N`` blocks since
the filter was last (re-)armed (the start-up, or a detected change, re-converged), three
tests of that (Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, 2001, sec. 5.4), each at :data:`.options.ALPHA`:

- *average NIS*: ``sum |e_i|^2 ~ chi2(3 N)`` (the innovations too large);
- *mean*: ``|sum e_i|^2 / N ~ chi2(3)`` (persistently one-signed innovations: a gyro bias or
  an unmodelled torque the state half absorbs);
- *whiteness*: Hosking's multivariate portmanteau ``N sum_{k=1}^{m} tr(R_k' R_0^-1 R_k
  R_0^-1) ~ chi2(9 m)`` of the lag-``k`` cross-covariances ``R_k = sum_i e_i e_{i-k}' / N``
  (``m`` = :data:`LAGS`: a slowly varying error the filter follows late; J. R. M. Hosking,
  *JASA* 75, 1980).  Normalised by the sample covariance ``R_0``, it tests correlation
  only: an error in the noise level (the estimated gyro noise's own sampling spread, 6.6 %
  in variance at 2000 samples) is the average NIS's to see, and no longer scales this
  statistic by its square (the unnormalised ``N sum |R_k|_F^2`` did: with the true noise
  level given, its false alarms on model-conforming records halved).

A change the filter detected and followed (a payload step) is no failure: the tests start
again after it (then the blocks after :data:`SKIP_S` of re-arming, while the tensor is still
settling).  A failure before the change is not washed away by it: until the new segment
has :data:`MIN_BLOCKS` of its own, the previous segment's verdict stands (a disturbance
the change test keeps firing on).  The estimate is ``model_mismatch`` when a test fails,
its covariance widened by the average NIS per degree of freedom (at least 1).  With
considered (stated, not learnt) inputs the innovations share the inputs' error and are not
independent: the tests are not run (no record).
"""
from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from .options import ALPHA

__all__ = ['LAGS', 'MIN_BLOCKS', 'SKIP_S', 'InnovationTests']

#: Lags of the whiteness test [blocks].
LAGS = 5
#: Blocks after which a segment is tested (fewer: the previous segment's verdict stands).
MIN_BLOCKS = 10
#: Time [s] after (re-)arming before the blocks are counted (the filter still settling).
SKIP_S = 2.0


def _chi2_sf(x: float, dof: int) -> float:
    """``P(chi2_dof > x)`` for any ``dof`` (the average NIS has ``3 N``, thousands)."""
    from scipy.special import gammaincc  # lazily: scipy costs start-up time

    return float(gammaincc(0.5 * dof, 0.5 * max(x, 0.0)))


class InnovationTests:
    """Running sums of the whitened innovations of one segment and the three tests."""

    def __init__(self) -> None:
        self._t0: float | None = None
        self.failed_before: dict[str, Any] | None = None    # the last segment's failure
        self._clear()

    def _clear(self) -> None:
        self.n = 0
        self.sq = 0.0
        self.sum = np.zeros(3)
        self.lagged = np.zeros((LAGS, 3, 3))
        self.outer = np.zeros((3, 3))
        self._recent: deque[np.ndarray] = deque(maxlen=LAGS)

    def restart(self) -> None:
        """A detected change: a new segment (the old one's failure kept, see the module)."""
        rec = self.record()
        if rec is not None and not rec['ok']:
            self.failed_before = rec
        elif rec is not None:
            self.failed_before = None
        self._t0 = None
        self._clear()

    def add(self, t: float, nu: np.ndarray, S: np.ndarray, armed: bool) -> None:
        """One block's innovation ``nu`` (3,) [N m s] with covariance ``S`` (3, 3) at its last
        sample time ``t`` [s]; counted when the filter is ``armed`` and :data:`SKIP_S` on."""
        if not armed:
            return
        if self._t0 is None:
            self._t0 = float(t)
        if t < self._t0 + SKIP_S:
            return
        e = np.linalg.solve(np.linalg.cholesky(S), nu)
        for k, old in enumerate(reversed(self._recent)):
            self.lagged[k] += np.outer(e, old)
        self._recent.append(e)
        self.n += 1
        self.sq += float(e @ e)
        self.sum += e
        self.outer += np.outer(e, e)

    def record(self) -> dict[str, Any] | None:
        """``diagnostics['adequacy']`` of the segment (None below :data:`MIN_BLOCKS`)."""
        n = self.n
        if n < MIN_BLOCKS:
            return None
        mean = float(self.sum @ self.sum) / n
        R0 = np.linalg.inv(self.outer)                  # (n R_0)^-1, R_k = lagged_k / n
        white = n * float(sum(np.sum((R0 @ L) * (L @ R0)) for L in self.lagged))
        tests = {'anis': (self.sq, 3 * n), 'mean': (mean, 3), 'whiteness': (white, 9 * LAGS)}
        rec: dict[str, Any] = {'test': 'innovation consistency (average NIS, mean, whiteness)',
                               'level': ALPHA, 'blocks': n, 'since_s': self._t0}
        failed = []
        for name, (chi2, dof) in tests.items():
            p = _chi2_sf(chi2, dof)
            rec.update({f'{name}_chi2': chi2, f'{name}_dof': dof, f'{name}_p_value': p})
            if p < ALPHA and name != 'whiteness':
                failed.append(name)
        rec['ok'] = not failed
        rec['covariance_inflation'] = max(1.0, self.sq / (3 * n)) if failed else 1.0
        rec['reason'] = (f'the innovations fail the {", ".join(failed)} test(s) at '
                         f'p < {ALPHA:g} over {n} blocks' if failed else None)
        return rec

    def verdict(self) -> dict[str, Any] | None:
        """The record that decides the status now: the segment's, or while it is too short
        the previous segment's failure (None: nothing to say)."""
        rec = self.record()
        if rec is None and self.failed_before is not None:
            return dict(self.failed_before, before_last_change=True)
        return rec
