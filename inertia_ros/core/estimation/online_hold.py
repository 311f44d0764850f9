"""``hold='auto'`` for the online estimator: both holds' statistics on the same rows, one rule.

:class:`~.recursive.RecursiveEstimator` with ``hold='auto'`` merges every row into two
accumulators (:class:`.accumulator.OnlineStats`), one with the torque integral under the
zero-order hold, one under linear interpolation (only the torque-integral columns ``T``
differ).  At each re-selection :func:`choose_hold` fits each hold's whole statistics (the
general model: full tensor, plus the bias unless it is off; never the inertial torque) and
applies the batch rule, :func:`.selection.select_hold`: the higher likelihood, the lower
residual excess of the two fits.

With wheels or rotors and another torque
(:class:`.recursive_momentum.MomentumRecursiveEstimator`) the two sides are the momentum
input's equivalent torque with the other torque held and with it linear, each held over the
grid intervals (the second kept as ``OnlineAligner.tau_alt``, :func:`linear_integral`).
How the torque behaves between its samples is a property of its source, so the evidence is
not forgotten with the tensor's ``window``.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from .align import OnlineAligner
from .fit import Fit, fit_two_pass
from .options import ALPHA, HOLDS, IDENTIFIABILITY_TOL
from .regressors import cumulative_torque
from .selection import (
    SelectionPolicy,
    hold_not_compared,
    identifiable,
    select_disturbance,
    select_hold,
    undetermined,
)

__all__ = ['AutoHold', 'choose_hold', 'linear_integral']

#: How the adequacy tests override the likelihoods (``hold_selection['adequacy']``).
_ADEQUACY_RULE = ('a hold whose fit fails the adequacy tests is left for the other when the '
                  "other's fit passes them")


def choose_hold(stats: dict[str, Any], bias: bool, nv: np.ndarray, tv: np.ndarray,
                inertial: str = 'off') -> tuple[str, dict[str, Any]]:
    """The hold the data support, by :func:`.selection.select_hold` (the batch rule).

    Parameters
    ----------
    stats : dict
        ``{'zoh': SufficientStats, 'linear': SufficientStats}`` of everything merged.
    bias : bool
        Fit the torque bias (the general model unless it is off).
    nv, tv : numpy.ndarray, shape (3,)
        Gyro [rad^2/s^2] and torque [N^2 m^2] white-noise variances.
    inertial : {'off', 'auto', 'on'}
        The torque fixed in inertial axes (wide statistics).  The holds are compared
        without it, as with ``'off'`` (the batch's rule, :func:`.hold_choice.auto_hold`):
        fitted on the wrong hold, a bias and an inertial torque in opposite directions absorb
        its misfit.  ``'auto'`` keeps it only where both holds' fits keep it
        (:func:`_held_keeps`): a disturbance is in the data whatever the hold, a wrong hold's
        misfit is not (continuous 5 s records: the held fit kept one, 0.2 -> 7.0 %).  The
        choice is in the record as ``inertial_torque_of_the_held_fit`` (``'on'``: both keep
        it).

    Returns
    -------
    chosen : str
        ``'zoh'`` or ``'linear'``.
    record : dict
        :func:`.selection.select_hold`'s record (``diagnostics['hold_selection']``).
    """
    excess = {}
    for h, st in stats.items():
        f = fit_two_pass(st, np.eye(6), bias, nv, tv)
        excess[h] = f.excess if np.all(np.isfinite(f.beta)) else None
    chosen, record = select_hold(excess['zoh'], excess['linear'])
    if inertial == 'off':
        return chosen, record
    keep_d = inertial == 'on' or all(_held_keeps(stats[h], bias, nv, tv) for h in stats)
    record['inertial_torque_of_the_held_fit'] = 'on' if keep_d else 'off'
    return chosen, record


def _held_keeps(st: Any, bias: bool, nv: np.ndarray, tv: np.ndarray) -> bool:
    """Whether the held statistics ``st`` keep the inertial torque
    (:func:`.selection.select_disturbance` at :data:`.options.ALPHA`); False while their
    general model (the bias and the inertial torque) does not identify every tensor element:
    there the tests reject on conforming data (5 s zero-control seed 9 at 2-4.5 s, batch and
    online alike: joint p 1e-33 to 0, then 0.09 on the whole record)."""
    def fit(basis: np.ndarray, b: bool, offset: np.ndarray | None = None,
            theta0: np.ndarray | None = None, inertial: bool = False) -> Fit:
        return fit_two_pass(st, basis, b, nv, tv, offset, theta0, inertial=inertial)
    f = fit(np.eye(6), bias, inertial=True)
    scale = float(np.max(f.beta[:3]))
    if np.any(undetermined(f)) or not scale > 0 or not np.all(
            identifiable(f, np.ones(6, dtype=bool), scale, IDENTIFIABILITY_TOL)):
        return False
    return select_disturbance(fit, 'auto' if bias else 'off', 'auto', ALPHA)[1]


def linear_integral(align: OnlineAligner, t: np.ndarray) -> np.ndarray:
    """The torque integral (n, 3) [N m s] of the linear side from ``align.ts[0]`` to ``t``
    (n,) [s]: the torque stream linear between its samples, or, when the aligner keeps a
    second torque (a momentum input's equivalent torque with the other torque linear, held
    over the grid intervals: :class:`.recursive_momentum.MomentumRecursiveEstimator`), that
    one held."""
    if align.tau_alt is not None:
        return cumulative_torque(align.ts, align.tau_alt, t, 'zoh')
    return cumulative_torque(align.ts, align.tau, t, 'linear')


class AutoHold:
    """The linear side of ``hold='auto'`` and the choice: the linear torque integral's base
    and the last choice with its record (reused between re-selections)."""

    def __init__(self, wide: bool = False) -> None:
        self.wide = bool(wide)          # rows carry the inertial torque's nine columns
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.T_base = np.zeros(3)       # linear torque integral at the aligner's first sample
        #: the last :meth:`rows`' time [s], torque times and linear integral for :meth:`fold`
        self._fold_next: tuple[float, np.ndarray, np.ndarray] | None = None
        self.chosen = 'zoh'
        self.record: dict[str, Any] | None = None
        #: the inertial torque of the held fit at the last choice ('on'/'off'), or None
        self.inertial: str | None = None
        #: the hold the adequacy tests chose (:meth:`check_other`), over the likelihoods
        self.preferred: str | None = None
        self.by_adequacy: dict[str, bool] | None = None

    def rows(self, align: OnlineAligner, t: np.ndarray, V: np.ndarray) -> dict[str, np.ndarray]:
        """Both holds' variables (n, 13 or 22) of rows ``V`` (the held ones from ``align``) at
        ``t`` (n,) [s]."""
        V_lin = V.copy()            # extra columns after the 13 (stated inputs) kept as held
        # with the integral :meth:`fold` will need at the last torque sample at or before t[-1]
        j = int(np.searchsorted(align.ts, t[-1], side='right') - 1)
        L = linear_integral(align, np.append(t, align.ts[j]))
        V_lin[:, 10:13] = self.T_base + L[:-1]
        self._fold_next = (float(t[-1]), align.ts, L[-1])
        return {'zoh': V, 'linear': V_lin}

    def fold(self, align: OnlineAligner, t_last: float) -> None:
        """Before ``align.trim(t_last)``: fold the linear integral it drops into the base."""
        j = int(np.searchsorted(align.ts, t_last, side='right') - 1)
        if j > 0:
            t_rows, ts, at = self._fold_next or (None, None, None)
            if t_rows != t_last or ts is not align.ts:    # (not the rows' last time: compute)
                at = linear_integral(align, align.ts[j:j + 1])[0]
            self.T_base = self.T_base + at

    def select(self, due: bool, torque_free: bool, stats: Callable[[str], Any], bias: bool,
               nv: np.ndarray, tv: np.ndarray, samples: int, inertial: str = 'off'
               ) -> tuple[bool, dict[str, Any]]:
        """Choose the hold when ``due`` (or never chosen), else reuse the last choice.

        ``stats(h)`` gives hold ``h``'s statistics; ``bias``, ``inertial``: the general
        model's disturbances (:func:`choose_hold`).  Returns whether the choice changed and
        ``diagnostics['hold_selection']``.
        """
        before = self.chosen
        reused = not due and self.record is not None
        if not reused:
            if torque_free:
                self.chosen, rec = 'zoh', hold_not_compared('torque-free data: no choice')
            else:
                self.chosen, rec = choose_hold({h: stats(h) for h in HOLDS}, bias, nv, tv,
                                               inertial)
            self.record = dict(rec, selected_at_samples=samples)
            self.inertial = rec.get('inertial_torque_of_the_held_fit')
        out = {'requested': 'auto', **(self.record or {}), 'chosen': self.chosen}
        if self.preferred is not None and not torque_free:
            self.chosen = out['chosen'] = self.preferred
            out['adequacy'] = dict(self.by_adequacy or {}, rule=_ADEQUACY_RULE)
        if reused:
            out['reused'] = True
        return self.chosen != before, out

    def held_inertial(self, policy: SelectionPolicy, active: str) -> SelectionPolicy:
        """``policy`` for an estimate on the ``active`` hold (either): ``'auto'`` stays
        (selected anew on that hold's statistics) only where both holds' fits keep the
        inertial torque (:func:`choose_hold`), else ``'off'``; other settings as given."""
        if policy.inertial_torque != 'auto' or self.inertial in (None, 'on'):
            return policy
        return replace(policy, inertial_torque='off')

    def check_other(self, active: str, accs: dict[str, Any], f: Fit, nv: np.ndarray,
                    tv: np.ndarray, walk_noise: bool, context: dict[str, Any]) -> None:
        """The ``active`` hold's fit ``f`` failed the adequacy tests: fit the same parameter
        set on the other hold's statistics (``accs[h]``: :class:`.accumulator.OnlineStats`)
        and test it; when it passes, it is :attr:`preferred` from the next estimate on, over
        the likelihoods (the batch's :func:`.hold_choice.hold_by_adequacy`).  One more fit
        and adequacy test, only after a failed test.  ``nv``, ``tv`` (3,): gyro [rad^2/s^2]
        and torque [N^2 m^2] noise variances; ``walk_noise`` and ``context`` as
        :meth:`.accumulator.OnlineStats.stats`.
        """
        other = 'linear' if active == 'zoh' else 'zoh'
        acc = accs[other]
        g = fit_two_pass(acc.stats(nv, acc.n_eff(), walk_noise, **context), f.basis, f.bias,
                         nv, tv, f.offset, inertial=f.inertial)
        g.cov = g.cov * ((acc.w00 + acc.w00c) / (acc.w0 + acc.wc))
        ok = bool(np.all(np.isfinite(g.beta))) and acc.window_test(g, nv, tv, **context).ok
        self.by_adequacy = {f'{active}_ok': False, f'{other}_ok': ok}
        if ok:
            self.preferred = other
