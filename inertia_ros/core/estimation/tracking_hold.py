"""``hold='auto'`` for the tracker: both holds filtered until the batch rule decides.

:class:`~.tracking.TrackingEstimator` with ``hold='auto'`` runs its own filter under the
zero-order hold and a twin filter under linear interpolation on the same streams, and feeds
the streams to a judge, a :class:`~.recursive.RecursiveEstimator` with ``hold='auto'`` (both
holds' statistics on the same rows, :mod:`.online_hold`), which applies the batch rule
(:func:`.selection.select_hold`, the higher likelihood) about once a second of data.  The
choice is locked once it is settled: at least :data:`MIN_S` of data judged, and the same
hold chosen at every judgement over the latest half of them (early judgements, on a tensor
not yet settled, are unreliable: on the reference simulator's 0.06 N m multisine at
200/50 Hz, 2-5 s of data gave the wrong hold in 2 of 4 records under the rule before; the
settled rule locked the right one in all four, at 14-18 s or, for one, by the 20 s cap); or
after :data:`DECIDE_S` of data, the rule's answer however it changed before.  Then the
losing filter and the judge are dropped, so the cost is that of one filter again.
Until then the estimate is that of the filter the rule prefers so far
(``diagnostics['hold_selection']['locked']`` False).  The judge fits one tensor over the
whole evidence (no forgetting): how the torque behaves between its samples is a property of
its source, not of the body the tracker follows.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .homogeneous import is_torque_free
from .options import MIN_EQUATIONS, MIN_GYRO_SAMPLES
from .recursive import RecursiveEstimator
from .selection import hold_not_compared
from .tracking_output import StateOutput

__all__ = ['DECIDE_S', 'JUDGE_EVERY_S', 'MIN_S', 'HoldChoice', 'keep_by_adequacy']

#: Data [s] judged before a choice may be locked.
MIN_S = 10.0
#: Data [s] after which the choice is locked even when not settled.
DECIDE_S = 20.0
#: Data [s] between two judgements (the rule's cost is that of a few small fits).
JUDGE_EVERY_S = 1.0


class HoldChoice:
    """The twin filter (linear hold), the judge and the choice so far.

    Parameters
    ----------
    twin : object
        The tracker under ``hold='linear'`` (fed here).
    torque_bias : str
        The tracker's bias option: ``'on'`` fits the bias in the judge too.
    gyro_noise : float, array_like (3,) or None
        Given gyro noise std [rad/s] (else estimated by the judge).
    judge : object, optional
        The judge (default a :class:`~.recursive.RecursiveEstimator`, ``hold='auto'``).
    """

    def __init__(self, twin: Any, torque_bias: str, gyro_noise: Any,
                 judge: Any = None) -> None:
        self.twin = twin
        self.judge = judge if judge is not None else RecursiveEstimator(
            model='full', hold='auto', gyro_noise=gyro_noise,
            torque_bias='on' if torque_bias == 'on' else 'off')
        self.chosen = 'zoh'
        self.record: dict[str, Any] | None = None
        self._at = -math.inf              # data time of the last judgement [s]
        self._t0: float | None = None     # first gyro time [s]
        self._since: float | None = None  # start of the current significant same-choice run

    def add_gyro(self, t: Any, omega: Any) -> None:
        """Feed gyro samples to the twin and the judge (validated by the tracker first)."""
        if self._t0 is None and np.size(t):
            self._t0 = float(np.ravel(t)[0])
        self.twin.add_gyro(t, omega)
        self.judge.add_gyro(t, omega)

    def add_torque(self, t: Any, tau: Any) -> None:
        """Feed torque samples to the twin and the judge."""
        self.twin.add_torque(t, tau)
        self.judge.add_torque(t, tau)

    def add_momentum(self, m: Any) -> None:
        """Feed a momentum input block to the twin and the judge."""
        self.twin.add_momentum(m)
        self.judge.add_momentum(m)

    def decide(self, now: float | None) -> bool:
        """Judge again when :data:`JUDGE_EVERY_S` of data have come; whether to lock.

        ``now`` is the newest gyro time [s].  Returns True when the choice is settled (see
        the module doc) or :data:`DECIDE_S` of data have been judged.
        """
        if now is None or self._t0 is None:
            return False
        if now - self._at >= JUDGE_EVERY_S:
            sel = _judge(self.judge)
            if sel is not None and sel.get('statistic') is not None:
                same = self._since is not None and sel['chosen'] == self.chosen
                self._since = self._since if same else now
                self.record, self.chosen, self._at = sel, sel['chosen'], now
        if now - self._t0 >= DECIDE_S and self.record is None:     # never compared
            self.record = {'requested': 'auto', **hold_not_compared(
                f'no comparison in {DECIDE_S:g} s of data (torque-free or too little): held')}
            return True
        if self.record is None:
            return False
        span = self._at - self._t0
        settled = self._since is not None and self._at - self._since >= 0.5 * span
        return (settled and span >= MIN_S) or span >= DECIDE_S


def _judge(judge: RecursiveEstimator) -> dict[str, Any] | None:
    """The judge's hold choice alone: what the torque covers merged, its noise levels, then
    its ``hold='auto'`` selection (:meth:`.RecursiveEstimator._choose_hold`), the tensor's
    fits and tests skipped (a fifth of the cost of its ``estimate()``); None with too
    little data."""
    judge._process()
    if judge.samples_used < MIN_GYRO_SAMPLES or judge._acc.n_eff() < MIN_EQUATIONS:
        return None
    judge._tau_var = judge._torque_variance()
    tq = np.sqrt(judge._tau_var) if judge._tau_var is not None else np.zeros(3)
    diag: dict[str, Any] = {}
    judge._choose_hold(judge._gyro_var(), is_torque_free(judge._acc.torque_rms(), tq), diag)
    return diag.get('hold_selection')


def keep_by_adequacy(preferred: str, est: Any, record: dict[str, Any],
                     filters: tuple[Any, Any]) -> tuple[Any, dict[str, Any]]:
    """Before the hold is locked: the other filter's estimate when the preferred one's
    innovations fail (``est`` is ``model_mismatch``) and the other's do not, as the batch
    and the recursive estimator keep a hold by adequacy (``hold_selection.adequacy``).

    Until the choice is settled the rule's preference may be a coin toss (a few seconds
    of data): on 4 s of held torque it preferred the
    linear hold in 7 of 20 records, whose filter then failed its innovation test in 2 while
    the zero-order hold's passed.

    Parameters
    ----------
    preferred : {'zoh', 'linear'}
        The hold the rule prefers so far.
    est : InertiaEstimate
        Its filter's estimate.
    record : dict
        ``diagnostics['hold_selection']`` so far.
    filters : tuple
        The zero-order hold's and the linear hold's trackers.

    Returns
    -------
    tuple
        The estimate to report and its hold record.
    """
    other = 'zoh' if preferred == 'linear' else 'linear'
    alt = StateOutput.estimate(                  # the filter's own, not its hold choice's
        filters[0] if other == 'zoh' else filters[1])
    if alt.status == 'model_mismatch':
        return est, record
    excess = {preferred: est.diagnostics.get('innovation_excess'),
              other: alt.diagnostics.get('innovation_excess')}
    return alt, dict(record, chosen=other, adequacy={
        'rule': "the preferred hold's filter fails its innovation test and the other's "
                'passes: the other is reported until the choice is locked',
        'preferred': preferred, 'innovation_excess': excess})
