"""Identifiability and model selection on the general model's fit.

* Identifiability: which tensor elements the data determine (:func:`undetermined`: the share
  of each element's conditional information that is signal rather than gyro noise; then the
  standard error against :attr:`SelectionPolicy.identifiability_tol` of the tensor scale),
  and what holding the others at a plausible value costs (:func:`held_leak`).
* Model selection: Wald tests on the general model (full tensor plus bias) with its
  calibrated covariance.  The bias is kept when the test rejects ``d = 0`` at level
  :attr:`SelectionPolicy.alpha` (:func:`select_bias`).  The elements a restricted parameter
  set holds are not known, only not shown to matter: the restricted estimate keeps the full
  fit's covariance (:func:`held_by_test`), and that report is true while the restriction
  costs no more than it saves; so the smallest parameter set whose restriction the data do
  not show to cost more (an MSE test at :attr:`SelectionPolicy.model_alpha`) is used
  (:func:`select_model`).
* Torque hold (:func:`select_hold`): held (zero-order) against linear between the torque
  samples, two non-nested models with the same parameters, by their likelihoods (the
  residual excess of each whole-record fit).

The rules' numbers come from one :class:`SelectionPolicy`, shared by the batch and the
recursive estimators (defaults :data:`.options.ALPHA`, :data:`.options.IDENTIFIABILITY_TOL`).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._numeric import psd_part
from .fit import Fit
from .model import describe_direction, model_basis
from .options import ALPHA, IDENTIFIABILITY_TOL
from .tails import chi2_sf

__all__ = ['HOLD_RULE', 'MODEL_ALPHA', 'SCREEN_ALPHA', 'SCREEN_ROWS', 'FitFunction',
           'SelectionPolicy', 'bias_test', 'complement', 'conditioning', 'dropped_bias_cov',
           'held_by_test', 'held_leak', 'hold_not_compared', 'identifiable', 'mse_test_p',
           'screen_inertial', 'screen_step', 'select_bias', 'select_disturbance', 'select_hold',
           'select_model', 'undetermined', 'wald']

_SIGNAL_SHARE = 0.5                            # conditional signal share of a determined element
_NULL_FRACTION = 0.01                          # signal fraction of an empty direction
_NOISE_SHARE = 0.01                            # gyro-noise share that makes a column suspect

#: Level of the parameter-set choice (:func:`select_model`): the conventional 5 % of the
#: test of the mean-square-error criterion (Toro-Vizcarrondo & Wallace 1968), whose null is
#: that the restriction's bias costs no more than its variance saves.  Per restricted degree
#: of freedom ``q`` it rejects where a plain Wald test of a zero would at 1.3 % (q = 2), 1.7 %
#: (q = 3, diagonal) and 2.0 % (q = 4, axisymmetric).
MODEL_ALPHA = 0.05
#: Noncentrality of the restriction at which its MSE equals the full fit's covariance.
_MSE_NONCENTRALITY = 1.0

#: ``fit(basis (6, k), bias, offset=None, theta0=None) -> Fit`` on fixed statistics.
FitFunction = Callable[..., Fit]


@dataclass(frozen=True)
class SelectionPolicy:
    """The numbers of the identifiability and model-selection rules (validated once, before,
    by :func:`.config.require`).

    Attributes
    ----------
    alpha : float
        Level of the Wald test of the torque bias (0 < alpha < 1).
    model_alpha : float
        Level of the parameter-set choice's MSE test (:func:`select_model`).
    identifiability_tol : float
        An element is identifiable when its standard error is below this share of the
        largest well-determined principal-diagonal element (> 0).
    physical : bool
        Project a physically impossible tensor onto the nearest valid one.
    torque_scale_std, gyro_scale_std : float
        Relative one-sigma scale uncertainty of the torque and the gyro (0.01 = 1 %): a
        uniform scale error is invisible in the data, so only these inputs put it in sigma.
    inertial_torque : {'off', 'auto', 'on'}
        A torque constant in inertial axes beside the torque bias (wide statistics;
        :func:`select_disturbance`).
    """

    alpha: float = ALPHA
    identifiability_tol: float = IDENTIFIABILITY_TOL
    physical: bool = True
    torque_scale_std: float = 0.0
    gyro_scale_std: float = 0.0
    model_alpha: float = MODEL_ALPHA
    inertial_torque: str = 'off'


def conditioning(fit: Fit, names: list[str]) -> dict[str, Any]:
    """Condition number and weakest direction of the column-scaled information matrix."""
    d = np.sqrt(np.diag(fit.H0))
    if np.any(d == 0):
        k = int(np.argmin(d))
        return {'condition_number': float('inf'), 'weakest_direction': names[k]}
    Hs = fit.H0 / d[:, None] / d[None, :]
    lam, vec = np.linalg.eigh(Hs)
    cond = float(lam[-1] / lam[0]) if lam[0] > 0 else float('inf')
    return {'condition_number': cond, 'weakest_direction': describe_direction(vec[:, 0], names)}


def undetermined(f: Fit) -> np.ndarray:
    """Elements (6,) of a full-model fit that the data does not determine.

    For each element, the conditional information (the other parameters partialled out) with
    the gyro-noise contribution removed, ``1 / (H^-1)_kk``, is compared with the same
    information including the noise, ``1 / (H0^-1)_kk``.  Their ratio is the share of what the
    data says about the element that is signal rather than gyro noise; collinear but clean
    columns keep a ratio near 1 (their standard errors say the rest), noise-dominated ones fall
    towards 0 or below.  The element with the smallest ratio under ``_SIGNAL_SHARE`` is
    declared undetermined and removed, and the test is repeated on the rest.  Also, while the
    scaled noise-free information has a direction with less than ``_NULL_FRACTION`` signal,
    the gyro-noise-carrying element loading most on it is removed.

    Returns the mask (the bias is not judged here, but by its Wald test).
    """
    out = np.zeros(6, dtype=bool)
    p = len(f.beta)
    h0 = np.diag(f.H0)
    if np.any(h0[:6] <= 0):
        out[:6] = h0[:6] <= 0
        return out
    d = 1.0 / np.sqrt(h0)
    Hs = 0.5 * (f.H + f.H.T) * d[:, None] * d[None, :]
    H0s = 0.5 * (f.H0 + f.H0.T) * d[:, None] * d[None, :]
    share = np.zeros(p)                                # gyro-noise share of each column
    share[:6] = 1.0 - np.diag(f.H)[:6] / h0[:6]
    keep = list(range(p))
    while any(k < 6 for k in keep):
        idx = np.ix_(keep, keep)
        theta_pos = [i for i in range(len(keep)) if keep[i] < 6]
        # first: a direction with (almost) no signal once the noise is removed, loaded by
        # columns that carry gyro noise (errors in variables, not mere collinearity)
        lam, vec = np.linalg.eigh(Hs[idx])
        if lam[0] < _NULL_FRACTION:
            v = np.abs(vec[:, 0])
            cand = [i for i in theta_pos if share[keep[i]] >= _NOISE_SHARE]
            if cand:
                keep.remove(keep[max(cand, key=lambda i: v[i])])
                continue
        # then: each element's conditional signal share
        try:
            inv0 = np.diag(np.linalg.inv(H0s[idx]))
            inv = np.diag(np.linalg.pinv(Hs[idx]))
        except np.linalg.LinAlgError:
            break
        ratio = np.where(inv > 0, inv0 / np.where(inv > 0, inv, 1.0), -1.0)
        worst = min(theta_pos, key=lambda i: ratio[i])
        if ratio[worst] >= _SIGNAL_SHARE:
            break
        keep.remove(keep[worst])
    out[sorted(set(range(6)) - set(keep))] = True
    return out


def held_leak(f: Fit, free: np.ndarray, scale: float) -> np.ndarray:
    """Covariance the estimated elements inherit from the held (undetermined) ones.

    The held elements are uncertain by a plausible spread (diagonal: +-scale/2, products:
    +-scale/4, uniform); through the coupling ``H_FF^-1 H_FU`` of the full-model information
    that uncertainty moves the estimated elements.
    """
    p = len(f.beta)
    if f.H_full is None:
        return np.zeros((p, p))
    Fi = [*np.flatnonzero(free).tolist(), *range(6, f.H_full.shape[0])]
    Ui = np.flatnonzero(~free)
    sens = np.linalg.lstsq(f.H_full[np.ix_(Fi, Fi)], f.H_full[np.ix_(Fi, Ui)], rcond=None)[0]
    spread = np.where(Ui < 3, 0.5 * scale, 0.25 * scale) / np.sqrt(3.0)
    return (sens * spread ** 2) @ sens.T              # (p, p): estimated elements + bias


def held_by_test(restricted: Fit, full: Fit) -> np.ndarray:
    """Covariance a parameter set chosen by a test gains from the elements it holds.

    A Wald test that does not reject the restriction says the held directions are zero
    within what the full fit knows of them, not that they are zero.  So the restricted
    estimate is reported with the full fit's covariance ``C_F`` (what the data say about
    every element, held ones included), and never with less than the restricted fit's own
    on the kept parameters: ``C = C_F + [P (C_R - C_F) P]_+`` (``P`` the projector on the
    kept parameters, ``[.]_+`` the positive part), so ``C >= C_F`` and, on the kept
    parameters, ``C >= C_R``.  For one linear model and one noise model ``C_F`` is the
    restricted covariance plus the leak of the held directions through the restricted
    fit's coupling; the anchored equations' sandwich covariance is not the inverse of their
    information, and there that leak over-covers (the integral method's diagonal fit of the
    20 s default scene: kept sigma 1.4x, RMS z 0.64), while ``C_F`` does not.

    Parameters
    ----------
    restricted : Fit
        The restricted fit (basis ``B`` (6, k)).
    full : Fit
        The full-model fit the test was run on (identity basis, the same bias setting).

    Returns
    -------
    ndarray, shape (6 + b, 6 + b)
        ``C - C_R`` in ``[theta (6), d (b)]`` coordinates (b = 3 with the bias, else 0), with
        ``C_R = M cov_R M'`` and ``M = diag(B, I_b)``: what to add to the restricted fit's
        covariance mapped to the tensor.
    """
    B = restricted.basis
    k = B.shape[1]
    b = len(restricted.beta) - k
    if full.basis.shape[1] != 6 or len(full.beta) != 6 + b:
        raise ValueError('held_by_test: the full fit must have six elements and the same bias')
    M = np.zeros((6 + b, k + b))
    M[:6, :k] = B
    M[6:, k:] = np.eye(b)
    C_R = M @ restricted.cov @ M.T
    C_F = 0.5 * (full.cov + full.cov.T)
    P = M @ np.linalg.pinv(M)
    C = C_F + psd_part(P @ (C_R - C_F) @ P.T)
    added = C - C_R
    return 0.5 * (added + added.T)


def dropped_bias_cov(without: Fit, with_bias: Fit, weight: float) -> np.ndarray:
    """Covariance (6, 6) [kg^2 m^4] the tensor of a fit without the torque bias gains when a
    test dropped the bias on weak evidence: ``weight [C_B - C_0]_+``.

    As for a parameter set chosen by a test (:func:`held_by_test`), a Wald test that does
    not reject ``d = 0`` says the bias is zero within what the fit with it knows, not that
    it is zero; where that test was suspect (``weight``, :func:`.adequacy.widening_weight` of
    its p-value: 1 below 0.05, none above 0.1) the tensor keeps the bias fit's covariance
    ``C_B`` instead of its own ``C_0`` (the positive part of the difference; the estimate
    stays the one without the bias).  A 0.01 rad/s gyro bias on a 5 s record, which acts
    like a torque bias there (seed 26 of the honesty gyro-bias case): bias test p 0.006,
    dropped, ``ok`` at |z| 5.7; with ``C_B`` 4.4.

    Parameters
    ----------
    without, with_bias : Fit
        The full-model fits without and with the bias (identity basis).
    weight : float
        0..1.
    """
    return weight * psd_part(with_bias.cov[:6, :6] - without.cov[:6, :6])


def wald(theta: np.ndarray, cov: np.ndarray, R: np.ndarray) -> tuple[float, int, float]:
    """Wald statistic, degrees of freedom and p-value of ``R theta = 0``."""
    r = R @ theta
    V = R @ cov @ R.T
    try:
        stat = float(r @ np.linalg.solve(V, r))
    except np.linalg.LinAlgError:
        stat = float(r @ np.linalg.pinv(V) @ r)
    dof = R.shape[0]
    return stat, dof, chi2_sf(stat, dof)            # chi-square upper tail


def complement(basis: np.ndarray) -> np.ndarray:
    """Rows spanning the orthogonal complement of the columns of ``basis`` (6, k)."""
    q, _ = np.linalg.qr(basis, mode='complete')
    return q[:, basis.shape[1]:].T


def identifiable(f: Fit, free: np.ndarray, scale: float, tol: float) -> np.ndarray:
    """Narrow ``free`` (6,) to the elements whose standard error is below ``tol * scale``.

    Parameters
    ----------
    f : Fit
        Fit of the elements in ``free`` (columns of the identity).
    free : ndarray of bool, shape (6,)
        Elements estimated in ``f``.
    scale : float
        Tensor scale: the largest well-determined principal-diagonal element [kg m^2].
    tol : float
        :attr:`SelectionPolicy.identifiability_tol`.
    """
    k = int(np.sum(free))
    se = np.eye(6)[:, free] @ np.sqrt(np.maximum(np.diag(f.cov)[:k], 0.0))
    return free & (se < tol * scale)


def select_bias(fit: FitFunction, f: Fit, alpha: float) -> tuple[Fit, bool, dict[str, Any]]:
    """Keep the torque bias of the full-model fit ``f`` only if a Wald test rejects ``d = 0``.

    Returns
    -------
    f : Fit
        ``f``, or the refit without bias.
    kept : bool
        The bias stays.
    record : dict
        ``wald, dof, p_value, kept`` (:func:`bias_test`).
    """
    record = bias_test(f, alpha)
    if not record['kept']:
        f = fit(np.eye(6), False, theta0=f.basis @ f.beta[:6])
    return f, record['kept'], record


def bias_test(f: Fit, alpha: float) -> dict[str, Any]:
    """The Wald test at level ``alpha`` of ``d = 0`` on a fit ``f`` with the torque bias:
    ``wald, dof, p_value, kept`` (the bias is kept when the test rejects)."""
    stat, dof, pval = wald(f.beta, f.cov, np.eye(len(f.beta))[f.basis.shape[1]:])
    return {'wald': stat, 'dof': dof, 'p_value': pval, 'kept': bool(pval < alpha)}


def _block_test(f: Fit, rows: slice | list[int], alpha: float) -> dict[str, Any]:
    """Wald test at ``alpha`` of ``beta[rows] = 0`` in ``f``: ``wald, dof, p_value, kept``."""
    stat, dof, pval = wald(f.beta, f.cov, np.eye(len(f.beta))[rows])
    return {'wald': stat, 'dof': dof, 'p_value': pval, 'kept': bool(pval < alpha)}


_DISTURBANCE = {(False, False): 'none', (True, False): 'body', (False, True): 'inertial',
                (True, True): 'both'}


def select_disturbance(fit: FitFunction, torque_bias: str, inertial_torque: str,
                       alpha: float) -> tuple[bool, bool, dict[str, Any]]:
    """Which constant disturbances the general model keeps: the body-axis torque bias ``b``,
    the torque fixed in inertial axes ``d`` (:mod:`.attitude`), both or none.

    Each ``'auto'`` block is tested by Wald at ``alpha`` in the fit that holds every block
    allowed (``'on'`` or ``'auto'``).  Both ``'auto'``: the joint test of ``(b, d)`` first
    (6 dof; not rejected: none), then each given the other (3 dof); those rejected are
    kept, and both when neither alone is (the two collinear: a slow rotation or a short
    record, where the data say only that a disturbance is there; fitting both is honest and
    costs sigma).  Measured at 1e-3 on 40 5 s records of the reference simulator:
    inertial disturbance joint 40, ``d | b`` 39, ``b | d`` 0; none 0; body-axis 40, 0, 39.

    Parameters
    ----------
    fit : callable
        ``fit(basis, bias, offset=None, theta0=None, inertial=False) -> Fit`` on wide
        statistics.
    torque_bias, inertial_torque : {'auto', 'on', 'off'}
        The requested handling of each.
    alpha : float
        Level of the tests (the torque bias's, :data:`.options.ALPHA`).

    Returns
    -------
    bias, inertial : bool
        The blocks kept.
    record : dict
        ``requested``, ``chosen`` (``'none'``, ``'body'``, ``'inertial'``, ``'both'``),
        ``tests`` (per test run: ``wald, dof, p_value, kept``; ``joint``,
        ``inertial_given_body``, ``body_given_inertial``, ``inertial``, ``body``) and ``rule``.
    """
    allow_b, allow_d = torque_bias != 'off', inertial_torque != 'off'
    keep_b, keep_d = torque_bias == 'on', inertial_torque == 'on'
    tests: dict[str, Any] = {}
    if allow_b or allow_d:
        f = fit(np.eye(6), allow_b, inertial=allow_d)
        both_auto = torque_bias == 'auto' and inertial_torque == 'auto'
        if both_auto:
            tests['joint'] = _block_test(f, slice(f.bias_at.start, f.inertial_at.stop), alpha)
        if not both_auto or tests['joint']['kept']:
            if inertial_torque == 'auto':
                name = 'inertial_given_body' if allow_b else 'inertial'
                tests[name] = _block_test(f, f.inertial_at, alpha)
                keep_d = tests[name]['kept']
            if torque_bias == 'auto':
                name = 'body_given_inertial' if allow_d else 'body'
                tests[name] = _block_test(f, f.bias_at, alpha)
                keep_b = tests[name]['kept']
            if both_auto and not (keep_b or keep_d):
                keep_b = keep_d = True                 # jointly needed, not separable
    return keep_b, keep_d, {
        'requested': {'torque_bias': torque_bias, 'inertial_torque': inertial_torque},
        'chosen': _DISTURBANCE[keep_b, keep_d], 'tests': tests,
        'rule': (f'Wald tests at alpha={alpha:g} in the fit with every allowed block: with '
                 'both auto, the joint test of (b, d), then each given the other; both kept '
                 'when only the joint test rejects')}


#: Level of the inertial torque's screen (:func:`screen_inertial`): lenient, so that the
#: screen never loses a torque the joint rule at :data:`.options.ALPHA` keeps.
SCREEN_ALPHA = 0.05
#: With both disturbances allowed the screen stays narrow on a significant joint test only
#: when the bias given the inertial torque is below this fraction of :data:`.options.ALPHA`
#: (the rule keeps both where neither is significant alone at its level).
_SCREEN_BIAS_CLEAR = 0.1
#: Equations the screen fits all of, up to this many (exact: the rule's own statistics at
#: the 13-variable run's segment length); of a longer record every k-th, about
#: 1 / :data:`_SCREEN_THINNER` as many (its cost is then mostly the torque samples').
SCREEN_ROWS = 100_000
_SCREEN_THINNER = 5


def screen_step(n: int) -> int:
    """Every how many of ``n`` equations the screen keeps (:data:`SCREEN_ROWS`)."""
    return 1 if n <= SCREEN_ROWS else -(-_SCREEN_THINNER * n // SCREEN_ROWS)


def screen_inertial(fit: FitFunction, torque_bias: str, rows: int, step: int,
                    lenient: float | None = None, level: float = ALPHA
                    ) -> tuple[bool, dict[str, Any]]:
    """Whether the inertial torque ``d`` may be needed (``inertial_torque='auto'``): the
    joint rule of :func:`select_disturbance` at the level ``lenient`` (default
    :data:`SCREEN_ALPHA`) on cheap wide statistics (every ``step``-th equation, ``rows`` of
    them); with both disturbances allowed and the joint test significant,
    ``d`` is screened out only when it is not significant given the bias at ``lenient`` and
    the bias given ``d`` is below a tenth of the rule's ``level`` (where the rule at its level
    could keep both, the collinear case, the screen keeps ``d``).  Only when it keeps ``d`` are
    the full wide equations built and the rule run again at its own level; otherwise the
    estimate is the 13-variable one (as ``'off'``), the bias selected as without the option.
    Not tested (narrow) when the wide general fit leaves tensor elements undetermined
    (:func:`undetermined`: single-axis motion, where ``d`` and the bias are inseparable).

    Returns ``went_wide`` and the record for ``diagnostics.disturbance.screen``:
    ``statistic, dof, p_value`` of the test that decided ``d`` (``inertial_given_body``,
    ``inertial``, or the joint test when it did not reject or when it alone did: both kept),
    ``alpha``, ``went_wide``,
    ``chosen`` (the rule's choice at ``alpha``), ``equations``, ``thinned_by``, ``tests``.
    """
    alpha = SCREEN_ALPHA if lenient is None else lenient
    f = fit(np.eye(6), torque_bias != 'off', inertial=True)
    if np.any(undetermined(f)):      # (single-axis motion: d and the bias leak into the
        return False, {               # tensor's undetermined directions; untestable)
            'test': None, 'statistic': None, 'dof': None, 'p_value': None, 'alpha': alpha,
            'went_wide': False, 'chosen': None, 'equations': rows, 'thinned_by': step,
            'tests': {}, 'rule': ('the tensor is not fully determined with the inertial '
                                  'torque: it is not tested (the 13-variable estimate)')}
    _, keep_d, rec = select_disturbance(lambda *a, **k: f, torque_bias, 'auto', alpha)
    tests = rec['tests']
    given, body = tests.get('inertial_given_body'), tests.get('body_given_inertial')
    if 'joint' in tests and given is not None and body is not None:
        # the rule at its own level keeps d also when neither block alone is significant
        # there: narrow only when the bias alone clearly explains the disturbance
        keep_d = given['kept'] or not body['p_value'] < _SCREEN_BIAS_CLEAR * level
    name = ('inertial' if 'inertial' in tests else
            'inertial_given_body' if given is not None and (given['kept'] or not keep_d)
            else 'joint' if 'joint' in tests else None)
    main = tests[name] if name is not None else {}
    return keep_d, {
        'test': name, 'statistic': main.get('wald'), 'dof': main.get('dof'),
        'p_value': main.get('p_value'), 'alpha': alpha, 'went_wide': keep_d,
        'chosen': rec['chosen'], 'equations': rows, 'thinned_by': step, 'tests': tests,
        'rule': (f'the joint rule at alpha={alpha:g} on every {step}-th equation (attitude at '
                 "each interval's mean rate); the wide fit only when it keeps d")}


def mse_test_p(stat: float, dof: int, noncentrality: float = _MSE_NONCENTRALITY) -> float:
    """``P(W > stat)`` for ``W`` noncentral chi-square (``dof``, ``noncentrality``).

    The Poisson mixture of central tails, ``sum_j e^-m m^j / j! P(chi2_{dof + 2 j} > stat)``
    with ``m = noncentrality / 2``. The central tails follow one another by
    ``P(chi2_{k+2} > x) = P(chi2_k > x) + e^(-x/2) (x/2)^(k/2) / Gamma(k/2 + 1)``, so each term
    costs a few flops; the sum stops when the Poisson weight still to come (bounded by
    ``w_j / (1 - m / (j + 1))``, each tail being at most 1) is below 1e-13 of the sum (for the
    noncentrality 1 used here, 10-25 terms).
    """
    m = 0.5 * noncentrality
    x = float(stat)
    tail = chi2_sf(x, dof)
    if not x > 0.0 or math.isinf(x):
        return float(tail)
    h = 0.5 * x
    # log of the increment e^-h h^(k/2) / Gamma(k/2 + 1) from dof k to k + 2
    log_inc = -h + 0.5 * dof * math.log(h) - math.lgamma(0.5 * dof + 1.0)
    w = math.exp(-m)
    total, j = 0.0, 0
    while True:
        total += w * min(tail, 1.0)
        j += 1
        w *= m / j
        if w <= 0.0 or w / max(1.0 - m / (j + 1), 1e-12) <= 1e-13 * total + 1e-300 or j >= 400:
            break
        tail += math.exp(log_inc)
        log_inc += math.log(h) - math.log(0.5 * (dof + 2 * (j - 1)) + 1.0)
    return float(min(total, 1.0))


def select_model(f: Fit, axis: np.ndarray | None, alpha: float = MODEL_ALPHA
                 ) -> tuple[str, dict[str, Any]]:
    """The smallest parameter set whose restriction of the full fit ``f`` is not shown to cost
    more than it saves.

    Candidates: ``axisymmetric`` (only with a symmetry ``axis``), then ``diagonal``.  A
    chosen restriction is reported with the full fit's covariance (:func:`held_by_test`), and
    the restricted estimate's mean-square error is within that covariance exactly while the
    noncentrality ``delta = r' V^-1 r`` of the held directions ``r`` is at most 1 (Toro-
    Vizcarrondo & Wallace 1968, the MSE-matrix criterion).  So the test's null is
    ``delta <= 1``, not ``r = 0``: the Wald statistic ``W`` of the restriction is referred to
    the noncentral chi-square (its dof, noncentrality 1), and the restriction is rejected when
    that tail is below ``alpha``.  A zero that is true is kept in ~98 % of records (on the
    diagonal candidate a plain Wald test at 1.7 %), and one whose bias would exceed the
    reported sigma is not kept merely because it is not significant at a small level.

    Returns
    -------
    chosen : str
        ``'axisymmetric'``, ``'diagonal'`` or ``'full'``.
    record : dict
        ``models`` (per candidate ``wald, dof, p_value`` (the plain Wald test of a zero),
        ``mse_p_value`` (the test used) and ``rejected``), ``rule`` and ``chosen``.
    """
    candidates = (['axisymmetric'] if axis is not None else []) + ['diagonal']
    tested = {}
    chosen = 'full'
    cov6 = f.cov[:6, :6]
    for cand in candidates:
        stat, dof, pval = wald(f.beta[:6], cov6, complement(model_basis(cand, axis)))
        p_mse = mse_test_p(stat, dof)
        tested[cand] = {'wald': stat, 'dof': dof, 'p_value': pval, 'mse_p_value': p_mse,
                        'rejected': bool(p_mse < alpha)}
        if p_mse >= alpha and chosen == 'full':
            chosen = cand
    return chosen, {'models': tested,
                    'rule': ('smallest parameter set whose restriction of the full model is '
                             'not shown to cost more than it saves: the Wald statistic against '
                             f'a noncentral chi-square of noncentrality 1 at alpha={alpha:g}'),
                    'chosen': chosen}


#: The hold choice's rule (``diagnostics['hold_selection']['rule']``).
HOLD_RULE = ('the higher likelihood: the hold whose whole-record fit leaves the lower residual '
             'excess over the noise model (equal parameter counts, no size correction); '
             'zoh on a tie or when a fit has none')


def hold_not_compared(reason: str) -> dict[str, Any]:
    """``diagnostics['hold_selection']`` where the holds are not compared (``zoh`` kept):
    ``statistic`` None, the ``rule`` and the ``reason``."""
    return {'statistic': None, 'rule': HOLD_RULE, 'reason': reason, 'chosen': 'zoh'}


def select_hold(excess_zoh: float | None, excess_linear: float | None
                ) -> tuple[str, dict[str, Any]]:
    """Held or linear torque between samples: the hold with the higher likelihood.

    Both holds give the same parameters (non-nested models of equal size), so AIC and BIC
    reduce to the likelihoods, and the likelihood of each is that of its own whole-record fit:
    its weighted residual sum over what its noise model predicts (``Fit.excess``, the same
    anchored noise model for both), the lower the better.  No margin and no significance
    level: either way the other hold is the wrong model, and a wrong hold biases the tensor
    by a lag of half a torque period (5 s records of the reference simulator: 2.5 % median
    error where the right one gives 0.4 %).  Measured on those records, the lower excess
    picked the true hold in 59 of 60 (held and continuously varying torque; the one miss
    a near tie, 0.2 %), where the rule before, a Vuong test on per-window likelihoods at the
    whole-record fits, picked either hold with |t| up to 23 on either torque: the windows
    share the fits' estimation error, so their differences are not independent.

    Parameters
    ----------
    excess_zoh, excess_linear : float or None
        Residual excess of each hold's whole-record fit (None: no fit to compare).

    Returns
    -------
    chosen : str
        ``'zoh'`` or ``'linear'``.
    record : dict
        ``test, statistic`` (log of the linear excess over the held one: negative favours
        linear), ``rss_ratio`` (linear / held), ``rule, chosen`` (for
        ``diagnostics['hold_selection']``); ``reason`` when not compared.
    """
    ez, el = (np.nan if v is None else float(v) for v in (excess_zoh, excess_linear))
    if not (ez > 0 and el > 0 and np.isfinite(ez) and np.isfinite(el)):
        return 'zoh', {'test': 'likelihood', **hold_not_compared(
            'a fit has no residual excess: the holds are not compared')}
    chosen = 'linear' if el < ez else 'zoh'
    return chosen, {'test': 'likelihood', 'rule': HOLD_RULE, 'statistic': float(np.log(el / ez)),
                    'rss_ratio': el / ez, 'chosen': chosen}
