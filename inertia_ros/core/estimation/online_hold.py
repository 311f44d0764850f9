"""``hold='auto'`` for the online estimator: both holds' statistics on the same rows, one rule.

:class:`~.recursive.RecursiveEstimator` with ``hold='auto'`` merges every row into two
accumulators (:class:`.accumulator.OnlineStats`), one with the torque integral under the
zero-order hold, one under linear interpolation (only the torque-integral columns ``T``
differ).  For the decision it also keeps :class:`HoldWindows`: consecutive windows of rows,
each anchored on its own (its own initial momentum), as centred Grams of the 16 variables
``[w, m, t, T_zoh, T_linear]`` (25 with the inertial torque's ``vec C`` after them,
:mod:`.online_inertial`: both holds share it).  At each re-selection :func:`choose_hold`
fits each hold's whole statistics (the general model: full tensor, plus the bias unless it
is off, and the inertial torque unless it is off), evaluates every window's weighted residual
sum of squares at each hold's fit under one noise model (the held fit's weight), and applies
the batch rule, :func:`.selection.select_hold` at
:data:`.selection.HOLD_ALPHA` (a Vuong test, not a margin).

With wheels or rotors and another torque
(:class:`.recursive_momentum.MomentumRecursiveEstimator`) the two sides are the momentum
input's equivalent torque with the other torque held and with it linear, each held over the
grid intervals (the second kept as ``OnlineAligner.tau_alt``, :func:`linear_integral`).

The windows cover the whole record, as the batch's do: they start at :data:`HOLD_MIN_ROWS`
rows and, once more than :data:`HOLD_MAX_WINDOWS` are closed, neighbours are merged in pairs
under one anchor (the parallel update of Chan, Golub and LeVeque) and the window length
doubled; across a gap (a new anchored segment) the pair keeps both anchors (its residual sum
is the sum of the two).  How
the torque behaves between its samples is a property of its source, so the evidence is not
forgotten with the tensor's ``window``.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from .accumulator import noise_map
from .align import OnlineAligner
from .fit import Fit, equation_weight, fit_two_pass
from .options import ALPHA, HOLDS, IDENTIFIABILITY_TOL
from .regressors import VARIABLE_MAP, VARIABLE_MAP_WIDE, cumulative_torque, gram
from .selection import (
    HOLD_ALPHA,
    SelectionPolicy,
    hold_rule,
    identifiable,
    select_disturbance,
    select_hold,
    undetermined,
)

__all__ = ['HOLD_MAX_WINDOWS', 'HOLD_MIN_ROWS', 'AutoHold', 'HoldWindows', 'choose_hold',
           'linear_integral']

#: Rows of a window at the start (the batch's :data:`.hold_choice.HOLD_MIN_ROWS`).
HOLD_MIN_ROWS = 25
#: Closed windows kept (the batch's :data:`.hold_choice.HOLD_WINDOWS`); beyond, neighbours
#: are merged in pairs (8 to 16 windows compared).
HOLD_MAX_WINDOWS = 16

#: Rows :meth:`AutoHold.rows` queues before they join the windows.
_MAX_QUEUED = 4096

#: How the adequacy tests override the likelihoods (``hold_selection['adequacy']``).
_ADEQUACY_RULE = ('a hold whose fit fails the adequacy tests is left for the other when the '
                  "other's fit passes them")

_ZOH = np.arange(13)
_LIN = np.r_[np.arange(10), 13, 14, 15]
_VMAP = np.ascontiguousarray(VARIABLE_MAP.reshape(13, 30))   # as regressors.lift's
#: the same with the inertial torque's nine columns (16:25 of a window's rows, 13:22 read)
_WIDE = (np.r_[_ZOH, 16:25], np.r_[_LIN, 16:25],
         np.ascontiguousarray(VARIABLE_MAP_WIDE.reshape(22, 39)))


def _pair(a: tuple[int, np.ndarray, np.ndarray, bool], b: tuple[int, np.ndarray, np.ndarray, bool]
          ) -> tuple[int, np.ndarray, np.ndarray, bool]:
    """Two neighbouring windows as one: one anchor, unless a gap is in or next to them (then
    each keeps its anchors, for good: the flag stays)."""
    (na, ma, Ca, gap), (nb, mb, Cb, gap_b) = a, b
    n = na + nb
    if gap or gap_b:            # separate anchors: the Grams add, the mean is only nominal
        return n, (na * ma + nb * mb) / n, Ca + Cb, True
    d = mb - ma
    return n, ma + d * (nb / n), Ca + Cb + (na * nb / n) * np.outer(d, d), gap_b


class HoldWindows:
    """Centred Grams (16 x 16; 25 x 25 ``wide``) of consecutive, separately anchored
    windows of rows."""

    def __init__(self, wide: bool = False) -> None:
        self.n_var = 25 if wide else 16       # variables per row
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.rows = HOLD_MIN_ROWS             # rows per window now
        #: closed windows: rows, mean (n_var,), centred Gram (n_var, n_var), a gap after it
        self.closed: list[tuple[int, np.ndarray, np.ndarray, bool]] = []
        self._n = 0                           # open window: rows, mean, centred Gram
        self._mean = np.zeros(self.n_var)
        self._C = np.zeros((self.n_var, self.n_var))

    def cut(self) -> None:
        """A gap or a segment boundary: the open window ends (its rows keep their anchor)."""
        if self._n >= 2:
            self._close()
        if self.closed:
            n, m, C, _ = self.closed[-1]
            self.closed[-1] = (n, m, C, True)
        self._n, self._mean, self._C = 0, np.zeros(self.n_var), np.zeros((self.n_var,) * 2)

    def add(self, X: np.ndarray) -> None:
        """Add rows ``X`` (n, n_var) in time order (cut-invariant: windows close by row
        count)."""
        while len(X):
            k = min(len(X), self.rows - self._n)
            piece, X = X[:k], X[k:]
            m = piece.mean(axis=0)
            self._n, self._mean, self._C, _ = _pair((self._n, self._mean, self._C, False),
                                                    (k, m, gram(piece - m[None]), False))
            if self._n >= self.rows:
                self._close()
                self._n, self._mean = 0, np.zeros(self.n_var)
                self._C = np.zeros((self.n_var, self.n_var))

    def _close(self) -> None:
        """Keep the open window; sum neighbours in pairs beyond :data:`HOLD_MAX_WINDOWS`."""
        self.closed.append((self._n, self._mean.copy(), self._C.copy(), False))
        if len(self.closed) > HOLD_MAX_WINDOWS:
            c = self.closed
            self.closed = [_pair(c[i], c[i + 1]) for i in range(0, len(c) - 1, 2)] + (
                [c[-1]] if len(c) % 2 else [])
            self.rows *= 2

    def rss(self, coef: dict[str, np.ndarray], W: np.ndarray, nv: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
        """Weighted residual sums of squares (K,) of each hold's coefficients per window.

        ``coef[h]`` (10,) is ``[-theta, -bias, 1]`` of hold ``h``'s fit (13, ``[..., -d]``
        with the inertial torque ``d``, wide windows), ``W`` (3, 3) the common equation
        weight and ``nv`` (3,) the gyro noise variance [rad^2/s^2] (the squared-rate
        integrals' correction, as :meth:`.accumulator.OnlineStats.stats`).
        """
        wide = self.n_var == 25
        q = 13 if wide else 10
        K = noise_map(nv, 1.0, 22 if wide else 13)
        vmap = _WIDE[2] if wide else _VMAP
        Cs = np.array([C for _, _, C, _ in self.closed]).reshape(-1, self.n_var, self.n_var)
        out = []
        for h, cols in (('zoh', _WIDE[0] if wide else _ZOH),
                        ('linear', _WIDE[1] if wide else _LIN)):
            # every window at once, the products of :func:`.regressors.lift` and
            # :func:`.regressors.metric` stacked (the same numbers as window by window)
            L = vmap.T @ (K.T @ Cs[:, cols[:, None], cols[None, :]] @ K) @ vmap
            L = np.ascontiguousarray(L.reshape(-1, 3, q, 3, q).transpose(0, 1, 3, 2, 4))
            M = np.einsum('rs,krsij->kij', W, L)
            out.append(np.array([float(coef[h] @ m @ coef[h]) for m in M]))
        return out[0], out[1]


def choose_hold(stats: dict[str, Any], windows: HoldWindows, bias: bool, nv: np.ndarray,
                tv: np.ndarray, white_y_cov: np.ndarray | None, inertial: str = 'off'
                ) -> tuple[str, dict[str, Any]]:
    """The hold the data support, by :func:`.selection.select_hold` (the batch rule).

    Parameters
    ----------
    stats : dict
        ``{'zoh': SufficientStats, 'linear': SufficientStats}`` of everything merged.
    windows : HoldWindows
        The same rows in separately anchored windows.
    bias : bool
        Fit the torque bias (the general model unless it is off).
    nv, tv : numpy.ndarray, shape (3,)
        Gyro [rad^2/s^2] and torque [N^2 m^2] white-noise variances.
    white_y_cov : numpy.ndarray, shape (3, 3), optional
        Other white noise in the equations' right-hand side.
    inertial : {'off', 'auto', 'on'}
        The torque fixed in inertial axes (wide statistics and windows).  The holds are
        compared without it, as with ``'off'`` (the batch's rule,
        :func:`.hold_choice.auto_hold`): selected anew on the wrong hold, a bias and an
        inertial torque in opposite directions absorb its misfit and make it win (online 5 s
        zero-control records: 5 of 20 went linear, one at 10.6 %).  ``'auto'`` keeps it
        only where both holds' fits keep it (:func:`_held_keeps`): a disturbance is in the
        data whatever the hold, a wrong hold's misfit is not (continuous 5 s records: the
        held fit kept one, 0.2 -> 7.0 %).  The choice is in the record as
        ``inertial_torque_of_the_held_fit`` (``'on'``: both keep it).

    Returns
    -------
    chosen : str
        ``'zoh'`` or ``'linear'``.
    record : dict
        :func:`.selection.select_hold`'s record (``diagnostics['hold_selection']``).
    """
    chosen, record = _compare(stats, windows, bias, nv, tv, white_y_cov)
    if inertial == 'off':
        return chosen, record
    keep_d = inertial == 'on' or all(_held_keeps(stats[h], bias, nv, tv) for h in stats)
    record['inertial_torque_of_the_held_fit'] = 'on' if keep_d else 'off'
    return chosen, record


def _compare(stats: dict[str, Any], windows: HoldWindows, bias: bool, nv: np.ndarray,
             tv: np.ndarray, white_y_cov: np.ndarray | None) -> tuple[str, dict[str, Any]]:
    """:func:`choose_hold`'s comparison of the holds' general models (the bias if ``bias``;
    never the inertial torque, whose columns of wide windows get a zero coefficient)."""
    coef = {}
    excess = {}
    pad = [np.zeros(3)] if windows.n_var == 25 else []
    for h, st in stats.items():
        f = fit_two_pass(st, np.eye(6), bias, nv, tv)
        excess[h] = f.excess
        theta = f.basis @ f.beta[:6]
        if not np.all(np.isfinite(theta)):
            return 'zoh', {'statistic': None, 'p_value': None, 'rule': hold_rule(HOLD_ALPHA),
                           'reason': f'the {h} fit is not finite: the holds are not compared'}
        d = f.beta[f.bias_at] if bias else np.zeros(3)
        coef[h] = np.concatenate([-theta, -d, [1.0], *pad])
    from .selection import select_hold_by_excess
    return select_hold_by_excess(excess)


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
    """The linear side of ``hold='auto'`` and the choice: the linear torque integral's base,
    the windows, and the last choice with its record (reused between re-selections)."""

    def __init__(self, wide: bool = False) -> None:
        self.wide = bool(wide)          # rows carry the inertial torque's nine columns
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        self.T_base = np.zeros(3)       # linear torque integral at the aligner's first sample
        self.windows = HoldWindows(self.wide)
        self._queue: list[tuple[np.ndarray, list[int]]] = []   # rows (n, 16) not in windows yet
        #: the last :meth:`rows`' time [s], torque times and linear integral for :meth:`fold`
        self._fold_next: tuple[float, np.ndarray, np.ndarray] | None = None
        self._queued = 0
        self.chosen = 'zoh'
        self.record: dict[str, Any] | None = None
        #: the inertial torque of the held fit at the last choice ('on'/'off'), or None
        self.inertial: str | None = None
        #: the hold the adequacy tests chose (:meth:`check_other`), over the likelihoods
        self.preferred: str | None = None
        self.by_adequacy: dict[str, bool] | None = None

    def rows(self, align: OnlineAligner, t: np.ndarray, V: np.ndarray,
             breaks: list[int]) -> dict[str, np.ndarray]:
        """Both holds' variables (n, 13 or 22) of rows ``V`` (the held ones from ``align``) at
        ``t`` (n,) [s]; the rows join the windows (queued until a choice), which end at the
        ``breaks``."""
        V_lin = V.copy()            # extra columns after the 13 (stated inputs) kept as held
        # with the integral :meth:`fold` will need at the last torque sample at or before t[-1]
        j = int(np.searchsorted(align.ts, t[-1], side='right') - 1)
        L = linear_integral(align, np.append(t, align.ts[j]))
        V_lin[:, 10:13] = self.T_base + L[:-1]
        self._fold_next = (float(t[-1]), align.ts, L[-1])
        wide = [V[:, 13:22]] if self.wide else []           # (the inertial torque's)
        self._queue.append((np.concatenate([V[:, :13], V_lin[:, 10:13], *wide], axis=1), breaks))
        self._queued += len(t)
        if self._queued > _MAX_QUEUED:
            self._flush()
        return {'zoh': V, 'linear': V_lin}

    def _flush(self) -> None:
        """Add the queued rows to the windows (read only at a choice), each run of blocks
        between two breaks as one block (the same windows; the sums differ by rounding)."""
        queue, self._queue, self._queued = self._queue, [], 0
        run: list[np.ndarray] = []
        for X, breaks in [*queue, (None, [])]:
            lo = 0
            for k in breaks:
                self.windows.add(np.concatenate([*run, X[lo:k]]))
                self.windows.cut()
                run, lo = [], k
            if X is not None:
                run.append(X[lo:])
            elif run:
                self.windows.add(np.concatenate(run))

    def fold(self, align: OnlineAligner, t_last: float) -> None:
        """Before ``align.trim(t_last)``: fold the linear integral it drops into the base."""
        j = int(np.searchsorted(align.ts, t_last, side='right') - 1)
        if j > 0:
            t_rows, ts, at = self._fold_next or (None, None, None)
            if t_rows != t_last or ts is not align.ts:    # (not the rows' last time: compute)
                at = linear_integral(align, align.ts[j:j + 1])[0]
            self.T_base = self.T_base + at

    def select(self, due: bool, torque_free: bool, stats: Callable[[str], Any], bias: bool,
               nv: np.ndarray, tv: np.ndarray, white_y_cov: np.ndarray | None,
               samples: int, inertial: str = 'off') -> tuple[bool, dict[str, Any]]:
        """Choose the hold when ``due`` (or never chosen), else reuse the last choice.

        ``stats(h)`` gives hold ``h``'s statistics; ``bias``, ``inertial``: the general
        model's disturbances (:func:`choose_hold`).  Returns whether the choice changed and
        ``diagnostics['hold_selection']``.
        """
        before = self.chosen
        reused = not due and self.record is not None
        if not reused:
            if torque_free:
                self.chosen, rec = 'zoh', {'statistic': None, 'p_value': None,
                                           'rule': hold_rule(HOLD_ALPHA),
                                           'reason': 'torque-free data: no choice'}
            else:
                self._flush()
                self.chosen, rec = choose_hold({h: stats(h) for h in HOLDS},
                                               self.windows, bias, nv, tv, white_y_cov,
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
