"""The tracker's adequacy test: Bar-Shalom's consistency tests on its innovations.

Under the model, the innovations ``nu_i`` (3,) of :class:`.tracking.TrackingEstimator`'s
blocks are independent ``N(0, S_i)``, so the whitened innovations ``e_i = C_i^-1 nu_i``
(``C_i C_i' = S_i``) are independent standard normal 3-vectors.  Over the ``N`` blocks since
the filter was last (re-)armed (the start-up, or a detected change, re-converged), three
tests of that (Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, 2001, sec. 5.4) and a score test for the two faults the filter half absorbs,
each at :data:`.options.ALPHA`:

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
  level given, its false alarms on model-conforming records halved).  Reported only.
- *fault score*: a gyro bias ``b`` or a constant body-axis torque ``d`` is an unmodelled
  torque ``u = G(w, I) f`` linear in ``f = [b, d]`` (6,) with known columns
  (:func:`fault_torque`; ``d`` only when the filter has no torque-bias state).  Its effect on
  the innovations is ``D_i f``, the signature ``D_i`` (3, q) propagated through the filter's
  own gains (Willsky and Jones' GLR, *IEEE TAC* 21, 1976): the filter error's response ``Y``
  (nx, q) to the fault, ``D = H Y - a``, ``Y -= K D`` at the update, ``Y = F Y - C S^-1 D
  + c`` at the prediction.  ``D_i`` depends on the past only, so under the model the score
  ``s = sum D_i' S_i^-1 nu_i`` is ``N(0, J)``, ``J = sum D_i' S_i^-1 D_i``, and the Lagrange
  multiplier statistic ``s' J^-1 s ~ chi2(q)`` (q = rank of ``J``) exactly.  A fault that
  persists is a hypothesis about the whole record: the score runs across detected changes
  (``Y`` goes on through the filter's inflated gains; the blocks while the filter
  re-converges are not counted) from :data:`SKIP_S` after the first arming (counted from
  the arming itself, 3 more of 40 model-conforming 4 s records failed: the start-up's
  errors-in-variables bias looks like a fault).  Unlike the mean test it sees the part of
  the fault the tensor took up (a 0.01 rad/s gyro bias over 20 s: average NIS p 3.3e-3,
  mean p 0.21, fault score p 1.2e-6).

A change the filter detected and followed (a payload step) is no failure: the tests start
again after it (then the blocks after :data:`SKIP_S` of re-arming, while the tensor is still
settling).  A failure before the change is not washed away by it: until the new segment
has :data:`MIN_BLOCKS` of its own, the previous segment's verdict stands (a disturbance
the change test keeps firing on; the fault score, spanning the record, also decides while
the new segment is short).  The estimate is ``model_mismatch`` when a test fails,
its covariance widened by the average NIS per degree of freedom (at least 1).  With
considered (stated, not learnt) inputs the innovations share the inputs' error and are not
independent: the tests are not run (no record).
"""
from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from .adequacy import partial_widening, widening_weight
from .options import ALPHA

__all__ = ['LAGS', 'MIN_BLOCKS', 'SKIP_S', 'InnovationTests', 'fault_torque']

#: Lags of the whiteness test [blocks].
LAGS = 5
#: Blocks after which a segment is tested (fewer: the previous segment's verdict stands).
MIN_BLOCKS = 10
#: Time [s] after (re-)arming before the blocks are counted (the filter still settling).
SKIP_S = 2.0


def fault_torque(w: np.ndarray, I: np.ndarray, constant: bool) -> np.ndarray:
    """The unmodelled torque per unit fault (3, q) [N m per rad/s, and per N m] at the rate
    ``w`` (3,) [rad/s] and tensor ``I`` (3, 3) [kg m^2]: a gyro bias ``b`` adds
    ``w x (I b) + b x (I w) = ([w]x I - [I w]x) b`` to the momentum's rate of change (the
    measured rates' Euler equation; the constant ``I b`` the momentum state takes up), and,
    when ``constant`` (no torque-bias state), a constant body-axis torque its own 3 columns."""
    G = np.empty((3, 6 if constant else 3))
    G[:, :3] = np.cross(w, I, axisb=0, axisc=0) - np.cross(I @ w, np.eye(3), axisb=0, axisc=0)
    if constant:
        G[:, 3:] = np.eye(3)
    return G


def _chi2_sf(x: float, dof: int) -> float:
    """``P(chi2_dof > x)`` for any ``dof`` (the average NIS has ``3 N``, thousands)."""
    from scipy.special import gammaincc  # lazily: scipy costs start-up time

    return float(gammaincc(0.5 * dof, 0.5 * max(x, 0.0)))


def _score_test(score: np.ndarray, fisher: np.ndarray) -> tuple[float, int]:
    """The score statistic ``s' J^+ s`` and its degrees of freedom (the rank of ``J``)."""
    lam, V = np.linalg.eigh(fisher)
    keep = lam > 1e-9 * max(float(lam[-1]), 1e-300)
    u = V[:, keep].T @ score
    return float(np.sum(u ** 2 / lam[keep])), int(np.sum(keep))


def _suspect_widening(tests: dict[str, tuple[float, int]]) -> float:
    """The covariance factor of tests that passed but are suspect: the batch's rule
    (:func:`.adequacy.widening_weight`): the largest chi2 per dof of the deciding tests, in
    full when one is below :data:`.adequacy.WIDEN_ALPHA`, in part up to
    :data:`.adequacy.WIDEN_FROM`.  A 0.01 rad/s gyro bias over 5 s (seed 8: fault score p
    0.035, too few blocks for any test at the level) was ok at |z| 5.05 unwidened."""
    deciding = {k: v for k, v in tests.items() if k != 'whiteness' and v[1] > 0}
    if not deciding:
        return 1.0
    weight = widening_weight(min(_chi2_sf(c, d) for c, d in deciding.values()))
    return partial_widening(weight, max([1.0, *(c / d for c, d in deciding.values())]))


class InnovationTests:
    """Running sums of the whitened innovations of one segment and the three tests."""

    def __init__(self) -> None:
        self._t0: float | None = None
        self.failed_before: dict[str, Any] | None = None    # the last segment's failure
        self.Y: np.ndarray | None = None    # (nx, q) the filter error's response to a fault
        self._D = self._c = None
        self._f0: float | None = None       # the fault score's start: the first arming
        self.fault_n, self.score, self.fisher = 0, 0.0, 0.0    # its sums (the whole record)
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
        elif self.n >= MIN_BLOCKS:
            self.failed_before = None
        self._t0 = None
        self._clear()

    def sensitivity(self, H: np.ndarray, G: np.ndarray, mean_dt: float, dt: float) -> None:
        """A block's innovation response ``D = H Y - a`` (3, q) to a fault ``u = G f`` (``G``
        (3, q) from :func:`fault_torque` at the block's anchor, held over it): ``a = G
        mean_dt`` its integral in the block's mean equation, ``c = G dt`` [s] in the momentum
        propagated to the block's end (Willsky and Jones' GLR signature, *IEEE TAC* 21, 1976)."""
        if self.Y is None or self.Y.shape != (H.shape[1], G.shape[1]):
            self.Y = np.zeros((H.shape[1], G.shape[1]))
        self._D, self._c = H @ self.Y - G * mean_dt, G * dt

    def gain(self, K: np.ndarray) -> None:
        """The update ``x += K nu`` (gain ``K`` (nx, 3)): ``Y -= K D``."""
        self.Y = self.Y - K @ self._D

    def propagate(self, F: np.ndarray, CS: np.ndarray) -> None:
        """The prediction ``x = F x + CS nu`` (``F`` (nx, nx), ``CS`` (nx, 3)): ``Y = F Y - CS D
        + c`` (the fault's integral on the momentum, the last 3 states)."""
        self.Y = F @ self.Y - CS @ self._D
        self.Y[-3:] += self._c

    def add(self, t: float, nu: np.ndarray, S: np.ndarray, armed: bool) -> None:
        """One block's innovation ``nu`` (3,) [N m s] with covariance ``S`` (3, 3) at its last
        sample time ``t`` [s]; counted when the filter is ``armed`` and :data:`SKIP_S` on."""
        if not armed:
            return
        if self._t0 is None:
            self._t0 = float(t)
        if self._f0 is None:
            self._f0 = float(t)
        C = np.linalg.cholesky(S)
        e = np.linalg.solve(C, nu)
        if self._D is not None and t >= self._f0 + SKIP_S:
            Dw = np.linalg.solve(C, self._D)
            self.score = self.score + Dw.T @ e
            self.fisher = self.fisher + Dw.T @ Dw
            self.fault_n += 1
        if t < self._t0 + SKIP_S:
            return
        for k, old in enumerate(reversed(self._recent)):
            self.lagged[k] += np.outer(e, old)
        self._recent.append(e)
        self.n += 1
        self.sq += float(e @ e)
        self.sum += e
        self.outer += np.outer(e, e)

    def record(self) -> dict[str, Any] | None:
        """``diagnostics['adequacy']`` of the segment (None below :data:`MIN_BLOCKS`)."""
        n, tests = self.n, {}
        if n >= MIN_BLOCKS:
            mean = float(self.sum @ self.sum) / n
            R0 = np.linalg.inv(self.outer)              # (n R_0)^-1, R_k = lagged_k / n
            white = n * float(sum(np.sum((R0 @ L) * (L @ R0)) for L in self.lagged))
            tests = {'anis': (self.sq, 3 * n), 'mean': (mean, 3),
                     'whiteness': (white, 9 * LAGS)}
        if self.fault_n >= MIN_BLOCKS:
            tests['fault'] = _score_test(self.score, self.fisher)
        if not tests:
            return None
        rec: dict[str, Any] = {'test': 'innovation consistency (average NIS, mean, whiteness, '
                                       'fault score)',
                               'level': ALPHA, 'blocks': n, 'since_s': self._t0,
                               'fault_blocks': self.fault_n}
        failed = []
        for name, (chi2, dof) in tests.items():
            p = _chi2_sf(chi2, dof)
            rec.update({f'{name}_chi2': chi2, f'{name}_dof': dof, f'{name}_p_value': p})
            if p < ALPHA and name != 'whiteness':
                failed.append(name)
        rec['ok'] = not failed
        rec['covariance_inflation'] = max(1.0, self.sq / (3 * n)) if failed and n else \
            _suspect_widening(tests)
        rec['reason'] = (f'the innovations fail the {", ".join(failed)} test(s) at '
                         f'p < {ALPHA:g} over {n} blocks' if failed else None)
        return rec

    def verdict(self) -> dict[str, Any] | None:
        """The record that decides the status now: the segment's, or while it is too short
        the previous segment's failure (None: nothing to say)."""
        rec = self.record()
        if self.n < MIN_BLOCKS and self.failed_before is not None and (rec is None
                                                                      or rec['ok']):
            return dict(self.failed_before, before_last_change=True)
        return rec
