"""Torque-free data: the inertia ratios and principal axes (the scale is unobservable).

With no torque Euler's equations are homogeneous in ``theta``: any multiple of the tensor
explains the motion.  :func:`is_torque_free` is the one rule that declares a record
torque-free (batch and online); :func:`homogeneous_estimate` fits the ratios
``inertia / trace`` under ``trace = 1`` from the same statistics as the torque-driven fits;
:func:`torque_free_stats` builds those statistics for a batch record.  Both estimators add
the stated gyro scale, the window and segment-shift tests (:class:`TorqueFreeChecks` on a batch
record's equations, :class:`OnlineTorqueFreeChecks` on the recursive estimator's statistics).

The covariance carries the same noise model as the torque-driven fits: the white gyro noise
of each equation and the random walk that the integrated gyroscopic term ``int w x (I w)``
makes of the gyro noise (:func:`.noise.gyroscopic_walk_cov`).  With no torque stream that
walk is held over the gyro intervals.  Without it the ratios' sigma was about half their
scatter on fast tosses (12 rad/s, 1.5 s: RMS z 1.9; 5 s: up to 2.6 and 16 for an axis),
since at ``|w| dt`` of order 0.1 the walk's share of the equation error is comparable to
the white part and, being correlated in time, it does not average out.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._numeric import median
from ..tensor import THETA_NAMES, check_physical, nearest_physical, principal_axes, theta_to_matrix
from .adequacy import Adequacy, check_adequacy, segment_shift
from .assemble import _suspect, _widened_by
from .equations import Equations, segment_starts
from .fit import Fit, eiv_swap, equation_weight, fit_weighted, solve_symmetric
from .model import TRACE, TRACE_FREE, describe_direction, selector
from .noise import walk_maps
from .options import (
    ADEQUACY_MIN_WINDOW_S,
    ADEQUACY_WINDOWS,
    MIN_EQUATIONS,
    TORQUE_FREE_SIGMAS,
)
from .regressors import (
    MOMENTUM_BASIS,
    N_REGRESSOR_VARIABLES,
    VARIABLE_MAP,
    gram,
    lift,
    metric,
)
from .result import InertiaEstimate
from .statistics import SufficientStats, sufficient_stats
from .uncertainty import axis_std, moment_std

#: :func:`walk_grams`: the walk's cross Grams ``K`` and their cross Grams with the white part.
WalkGrams = tuple[np.ndarray, np.ndarray]
#: :func:`_pair_grams`: the cross Grams of two segmentations' walk rows.
PairGrams = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
#: :data:`.regressors.VARIABLE_MAP` as (13, 30): ``lift(G) = _VMAP' G _VMAP`` (reshaped).
_VMAP = VARIABLE_MAP.reshape(13, 30)

__all__ = ['OnlineTorqueFreeChecks', 'TorqueFreeChecks', 'homogeneous_estimate',
           'is_torque_free', 'torque_free_checked', 'torque_free_stats', 'walk_grams']

#: The reason of every torque-free result (a mismatch's reason ends with it).
REASON = 'no torque excitation: only ratios and principal axes are observable'
#: Smallest eigenvalue gap of the homogeneous information that singles out the ratios.
MIN_GAP = 10.0
#: The segment shift's shorter segments: the fit's divided by this.  A gyro bias acts through
#: the rotation a segment integrates and saturates once it spans the motion's period: 2.5 s
#: segments of 20 s tumbles kept 2/3 of the 10 s fit's error, 1.25 s ones 1/3 (see _shift).
SHIFT_FACTOR = 8.0


def is_torque_free(torque_rms: np.ndarray, torque_std: np.ndarray) -> bool:
    """The torque-free rule: every axis' torque RMS within ``TORQUE_FREE_SIGMAS`` noise sigmas.

    Parameters
    ----------
    torque_rms : ndarray, shape (3,)
        RMS of the torque samples per axis [N m] (zeros for no torque stream).
    torque_std : ndarray, shape (3,)
        Torque white-noise std per axis [N m].

    Returns
    -------
    bool
        ``max(rms) <= TORQUE_FREE_SIGMAS * max(std)`` (so all-zero torque is torque-free).
    """
    return float(np.max(torque_rms)) <= TORQUE_FREE_SIGMAS * float(np.max(torque_std))


def torque_free_stats(eq: Equations, t_gyro: np.ndarray, omega: np.ndarray,
                      segment: float | None) -> tuple[SufficientStats, WalkGrams | None]:
    """Statistics of torque-free equations, with the gyroscopic noise walk of the covariance.

    The walk's variance (:func:`.noise.gyroscopic_walk_cov`, for the residual excess) needs
    the motion's second moment and walk steps; with no torque stream the steps are the gyro
    intervals of the equations.  Its exact covariance needs the rate at every step:
    :func:`walk_grams`.  Equations of another kind (``hac``) get plain statistics.

    Parameters
    ----------
    eq : Equations
        Equations of a torque-free record (``motion`` is set here).
    t_gyro, omega : ndarray, shape (N,), (N, 3)
        The used gyro stamps [s] and samples [rad/s].
    segment : float, optional
        Segment length [s] of the anchored equations.

    Returns
    -------
    st : SufficientStats
    walk : tuple of ndarray or None
        :func:`walk_grams` (anchored equations only).
    """
    t = eq.t
    dt = median(np.diff(t)) if len(t) > 1 else 0.0
    eq.motion = (omega.T @ omega / max(len(omega), 1), dt)
    if eq.kind != 'anchored' or len(t) < 2:
        return sufficient_stats(eq, segment, t[:1], float(t[-1]) if len(t) else 0.0,
                                np.zeros(3)), None
    # walk steps at the equations' stamps; the unit "torque variance" only asks for the
    # walk's statistics (the fit is given zero torque noise: the walk is all gyroscopic)
    st = sufficient_stats(eq, segment, t, float(t[-1]), np.ones(3))
    w_eq = np.column_stack([np.interp(t, t_gyro, omega[:, c]) for c in range(3)])
    return st, walk_grams(eq.V, t, w_eq, segment_starts(t, eq.breaks, segment))


def walk_grams(V: np.ndarray, t: np.ndarray, omega: np.ndarray,
               starts: np.ndarray) -> WalkGrams:
    """Cross Grams of the gyroscopic noise walk, step by step with the rate of each step.

    Anchored equation ``b`` integrates ``w x (I w)`` over the measured rates, so gyro noise
    ``n_j`` of step ``j`` (the interval ``h_j`` after equation ``j``) adds ``h_j J(w_j) n_j``
    to every later equation of its segment, ``J(w) = sum_i w_i A_i`` (``A_i = [e_i]x I -
    [I e_i]x``).  With segment-demeaned variables, ``D_j = sum_{b > j} (V_b - m_seg(b))``,
    the walk's meat is ``sum_il sum_j h_j^2 w_ji w_jl X(D_j)' W A_i S_g A_l' W X(D_j)``, and
    since ``n_j`` is also the white error ``I n_j`` of equation ``j``, the two parts are
    correlated.  These Grams keep the rate of every step and that cross term: the mean-rate
    form of :func:`.noise.gyroscopic_walk_cov` without it misplaces the variance between the
    elements (a steady spin about the major axis: sigma of one ratio 2x too large, of the
    others 1.4x too small).

    Parameters
    ----------
    V : ndarray, shape (n, 13)
        Per-equation variables (:func:`.regressors.variables`).
    t : ndarray, shape (n,)
        Equation stamps [s].
    omega : ndarray, shape (n, 3)
        Rate at the equation stamps [rad/s].
    starts : ndarray of int
        Segment start indices (beginning with 0).

    Returns
    -------
    K : ndarray, shape (3, 3, 3, 3, 10, 10)
        ``K[i, l]``: cross Grams (3, 3, 10, 10) of the blocks ``h_j w_ji X(D_j)`` and
        ``h_j w_jl X(D_j)``, the torque variable dropped.
    Kx : ndarray, shape (3, 3, 3, 10, 10)
        ``Kx[i]``: cross Grams of the demeaned blocks ``X_j`` and ``h_j w_ji X(D_j)``: the
        same noise sample is in equation ``j`` (white, ``I n_j``) and in the walk of the
        later ones, so the two parts of the meat are correlated.
    """
    Xd, R = _walk_rows(V, t, omega, starts)
    G = gram(R).reshape(3, 10, 3, 10).transpose(0, 2, 1, 3)
    Gx = np.einsum('np,nq->pq', Xd, R).reshape(13, 3, 10)
    K = np.zeros((3, 3, 3, 3, 10, 10))
    Kx = np.zeros((3, 3, 3, 10, 10))
    G13 = np.zeros((13, 13))
    for i in range(3):
        for j in range(3):
            G13[:N_REGRESSOR_VARIABLES, :N_REGRESSOR_VARIABLES] = G[i, j]
            K[i, j] = lift(G13)
        G13[:, :N_REGRESSOR_VARIABLES] = Gx[:, i]
        G13[:, N_REGRESSOR_VARIABLES:] = 0.0
        Kx[i] = lift(G13)
    for k in (K, Kx):                    # the torque variable: noise only here
        k[..., 9, :] = 0.0
        k[..., :, 9] = 0.0
    return K, Kx


def _walk_rows(V: np.ndarray, t: np.ndarray, omega: np.ndarray,
               starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-step rows of :func:`walk_grams`: the segment-demeaned variables ``Xd`` (n, 13)
    and the walk's blocks ``R`` (n, 3 x 10), ``R[j, i] = h_j w_ji D_j``."""
    n = len(t)
    bounds = np.append(starts, n)
    Xd = np.zeros((n, 13))                            # segment-demeaned variables
    D = np.zeros((n, N_REGRESSOR_VARIABLES))
    h = np.append(np.diff(t), 0.0)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        X = V[a:b, :N_REGRESSOR_VARIABLES] - V[a:b, :N_REGRESSOR_VARIABLES].mean(axis=0)
        Xd[a:b, :N_REGRESSOR_VARIABLES] = X
        # the later equations of the same segment (the rest of the record cancels)
        D[a:b] = np.cumsum(X[::-1], axis=0)[::-1] - X
        h[b - 1] = 0.0
    return Xd, ((h[:, None] * omega)[:, :, None] * D[:, None, :]).reshape(n, -1)


def homogeneous_estimate(st: SufficientStats, gyro_var: np.ndarray, diag: dict[str, Any],
                         base: dict[str, Any], cov_scale: float = 1.0,
                         walk: WalkGrams | None = None,
                         checks: Checks | None = None) -> InertiaEstimate:
    """Torque-free data: the ratios ``inertia / trace`` with their standard errors, and axes.

    With no torque the equations are homogeneous, ``X6 theta = e``: ``theta`` is fitted
    under the constraint ``trace = 1`` (``theta = offset + B psi`` with ``B`` spanning the
    trace-free directions), by the same weighted, bias-compensated least squares and
    covariance model as the torque-driven fits (:func:`.fit.fit_two_pass`), the torque
    column dropped (it holds only sensor noise).  The eigenvalue gap of the homogeneous
    information says whether the motion singles out the ratios at all.

    Shared by the batch and the recursive estimators, so that both report the same
    ``scale_unobservable`` result.

    Parameters
    ----------
    st : SufficientStats
        Statistics of the equations (cross Grams of the segment-demeaned blocks).
    gyro_var : ndarray, shape (3,)
        Gyro white-noise variance per axis [rad^2/s^2].
    diag, base : dict
        Diagnostics (updated in place) and the common result fields.
    cov_scale : float
        Factor on the covariance (the recursive estimator's forgetting weights).
    walk : tuple of ndarray, optional
        :func:`walk_grams` of the equations: the exact gyroscopic-walk covariance (without:
        the mean-rate form of the fit's noise model, as for the torque-driven fits).
    checks : TorqueFreeChecks or OnlineTorqueFreeChecks, optional
        The equations and options of a batch record (:func:`torque_free_checked`), or the
        recursive estimator's statistics and options: the stated gyro-scale uncertainty is
        added to the covariance and the adequacy tests run.

    Returns
    -------
    InertiaEstimate
        ``scale_unobservable`` (``model_mismatch`` when an adequacy test fails) with
        ``ratios``, ``ratios_std`` and ``principal_axes`` (and
        ``principal_ratios`` with their std in the diagnostics), or
        ``insufficient_excitation`` when the motion does not single out the ratios.
    """
    st = _without_torque(st)
    diag['reason'] = REASON
    sep = _separation(st)
    if sep is None:
        diag['reason'] = 'torque-free data without rotation about every axis'
        return InertiaEstimate(status='insufficient_excitation', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    gap, cond, weakest = sep
    diag['eigenvalue_gap'] = gap
    diag['condition_number'] = cond
    if gap < MIN_GAP:
        diag['reason'] = ('torque-free data whose motion does not single out the inertia '
                          'ratios (e.g. a spin about a principal axis)')
        diag['weakest_direction'] = describe_direction(weakest, list(THETA_NAMES))
        return InertiaEstimate(status='insufficient_excitation', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    return _ratios(st, gyro_var, diag, base, cov_scale, walk, checks)


def _without_torque(st: SufficientStats) -> SufficientStats:
    """``st`` with the (integrated) torque column dropped: it holds only noise here."""
    C = st.C.copy()
    C[:, :, 9, :] = 0.0
    C[:, :, :, 9] = 0.0
    CP = None
    if st.CP is not None:                # the walk's sums (gyroscopic noise walk)
        CP = st.CP.copy()
        CP[:, :, 9, :] = 0.0
        CP[:, :, :, 9] = 0.0
    A = None
    if st.A is not None:
        A = st.A.copy()
        A[..., 9] = 0.0
    return replace(st, C=C, CP=CP, A=A)


def _separation(st: SufficientStats) -> tuple[float, float, np.ndarray] | None:
    """How well the motion singles out the ratios: ``(gap, condition, weakest)``.

    ``gap`` is the ratio of the two smallest eigenvalues of the scaled homogeneous
    information (the smallest belongs to the tensor itself), ``weakest`` (6,) the next
    direction; ``None`` when an element has no information at all.
    """
    H0 = metric(st.C, np.eye(3))[:6, :6]
    H = H0.copy()
    if st.eiv_var is not None:
        H -= st.n_eff * np.einsum('c,crk,csl->kl', st.eiv_var, MOMENTUM_BASIS, MOMENTUM_BASIS)
    d = np.sqrt(np.diag(H0))
    if np.any(d == 0):
        return None
    lam0 = np.linalg.eigvalsh(H0 / d[:, None] / d[None, :])
    _, vec = np.linalg.eigh(H / d[:, None] / d[None, :])
    return (float(lam0[1] / max(lam0[0], 1e-300)), float(lam0[-1] / max(lam0[0], 1e-300)),
            vec[:, 1] / d)


def _walk_covariance(st: SufficientStats, f: Fit, W: np.ndarray, theta: np.ndarray,
                     gyro_var: np.ndarray, walk: WalkGrams,
                     offset: np.ndarray) -> np.ndarray:
    """Sandwich covariance (p, p) of the fit ``f`` (weight ``W``) with the exact walk.

    Meat: the white gyro noise of each equation (as :func:`.fit.fit_weighted`) plus the
    gyroscopic walk step by step and its correlation with the white part
    (:func:`walk_grams`); inflated, never deflated, by the fit's
    residual excess.
    """
    T = selector(TRACE_FREE, False, offset)
    p = T.shape[1] - 1
    Im = theta_to_matrix(theta)
    Sg = np.diag(gyro_var)
    S = Im @ Sg @ Im
    if st.white_y_cov is not None:
        S = S + st.white_y_cov
    meat = metric(st.C, W @ S @ W)
    A = walk_maps(Im)
    K, Kx = walk
    for i in range(3):
        for j in range(3):
            meat += metric(K[i, j], W @ A[i] @ Sg @ A[j].T @ W)
        cross = metric(Kx[i], W @ Im @ Sg @ A[i].T @ W)
        meat += cross + cross.T
    meat = (T.T @ meat @ T)[:p, :p]
    if st.weighted and st.eiv_var is not None:       # as the fit compensates: fit.eiv_swap
        k = TRACE_FREE.shape[1]
        meat[:k, :k] += st.n_eff * (TRACE_FREE.T @ eiv_swap(st.eiv_var, W, theta) @ TRACE_FREE)
    Hinv = solve_symmetric(f.H, np.eye(p))
    cov = Hinv @ meat @ Hinv.T
    return 0.5 * (cov + cov.T) * max(f.excess, 1.0)


def _fit_ratios(st: SufficientStats, gyro_var: np.ndarray, W: np.ndarray | None = None
                ) -> tuple[Fit, np.ndarray, np.ndarray]:
    """``theta`` (6,) under ``trace = 1`` on ``st`` (torque column dropped): ``(fit, W, theta)``.

    Without ``W``: the two passes of :func:`.fit.fit_two_pass` (identity, then the weight
    of the first pass' tensor), the weight of the final pass returned; with ``W``: one pass.
    """
    offset = TRACE / 3.0
    zero = np.zeros(3)
    final = W is not None
    W = np.eye(3) if W is None else W
    f = fit_weighted(st, TRACE_FREE, False, W, gyro_var, zero, st.weighted, offset)
    theta = TRACE_FREE @ f.beta + offset
    if not final and st.weighted and np.all(gyro_var > 0) and np.all(np.isfinite(theta)):
        W = equation_weight(theta, gyro_var, st.white_y_cov)
        f = fit_weighted(st, TRACE_FREE, False, W, gyro_var, zero, st.weighted, offset)
        theta = TRACE_FREE @ f.beta + offset
    return f, W, theta


def _ratios(st: SufficientStats, gyro_var: np.ndarray, diag: dict[str, Any],
            base: dict[str, Any], cov_scale: float,
            walk: WalkGrams | None, checks: Checks | None) -> InertiaEstimate:
    """The ``scale_unobservable`` result: ``theta`` fitted under ``trace = 1`` (torque column
    of ``st`` already dropped), projected onto a physical tensor when needed; with
    ``checks``, the adequacy tests and the stated gyro-scale uncertainty."""
    f, W, theta = _fit_ratios(st, gyro_var)
    cov = f.cov
    if walk is not None and st.kind == 'anchored':
        cov = _walk_covariance(st, f, W, theta, gyro_var, walk, TRACE / 3.0)
    status = 'scale_unobservable'
    if checks is not None:
        a = checks.adequacy(f, W, gyro_var)
        diag['adequacy'] = a.as_dict()
        # as the torque paths (assemble._adequate): widened by what the tests saw; a
        # covered mismatch keeps the status, with a warning, a larger one is model_mismatch
        cov = cov * max(1.0, a.inflation / max(f.excess, 1.0))
        if not a.benign:
            status = 'model_mismatch'
            diag['reason'] = 'the model does not explain the data: ' + a.reason + '; ' + REASON
        if a.inflation > 1.0:
            diag['adequacy']['sigma_widened_by'] = float(np.sqrt(a.inflation))
        if a.benign and a.inflation > 1.0:
            diag['warnings'].append(f'sigma widened {np.sqrt(a.inflation):.3g}x by the '
                                    f'{_widened_by(a)}: {a.reason or _suspect(a)}; covered')
    cov6 = cov_scale * (TRACE_FREE @ cov @ TRACE_FREE.T)
    if checks is not None:
        cov6 = cov6 + _calibration(checks, st, f, W, gyro_var, diag)
    diag['residual_excess'] = f.excess
    R = theta_to_matrix(theta)
    chk = check_physical(R)
    if not chk.valid:
        diag['physical'] = {'valid': False, 'failures': list(chk.failures), 'projected': True}
        R = nearest_physical(R)
        R /= np.trace(R)
    ratios, axes = principal_axes(R)
    diag['principal_ratios'] = ratios
    diag['principal_ratios_std'] = moment_std(R, cov6)
    diag['principal_axes_std'] = axis_std(R, cov6)
    ratios_std = theta_to_matrix(np.sqrt(np.maximum(np.diag(cov6), 0.0)), check_finite=False)
    return InertiaEstimate(status=status, ratios=R, ratios_std=ratios_std,
                           principal_axes=axes, identifiable=dict.fromkeys(THETA_NAMES, False),
                           model='homogeneous', diagnostics=diag,
                           **base)   # type: ignore[arg-type]


@dataclass(frozen=True)
class TorqueFreeChecks:
    """What a batch record adds to the torque-free fit: its equations and stated options.

    Attributes
    ----------
    eq : Equations
        The record's equations (statistics already made from them).
    t_gyro, omega : ndarray, shape (N,), (N, 3)
        The used gyro stamps [s] and samples [rad/s].
    segment : float, optional
        Anchored segment length [s].
    gyro_scale_std, torque_scale_std : float
        Stated relative one-sigma scale uncertainties (the torque's has no effect here: the
        torque-free equations hold no torque, but it is recorded).
    """

    eq: Equations
    t_gyro: np.ndarray
    omega: np.ndarray
    segment: float | None
    gyro_scale_std: float = 0.0
    torque_scale_std: float = 0.0

    def adequacy(self, f: Fit, W: np.ndarray, gyro_var: np.ndarray) -> Adequacy:
        """The window test of the whole fit ``f`` (weight ``W``): :func:`_window_adequacy`."""
        return _window_adequacy(self, f, W, gyro_var)

    def scale_sensitivity(self, f: Fit, W: np.ndarray, gyro_var: np.ndarray) -> np.ndarray:
        """``d beta / d g`` (5,) of ``f``: :func:`_scale_sensitivity` of the equations."""
        return _scale_sensitivity(self.eq, self.segment, f, W, gyro_var)


@dataclass(frozen=True)
class OnlineTorqueFreeChecks:
    """What the recursive estimator adds to the torque-free fit: the same two checks as a
    batch record's (:class:`TorqueFreeChecks`) on its statistics.

    The adequacy test's windows are the accumulator's groups of anchored segments (as for
    its torque-driven fits, :meth:`.accumulator.OnlineStats.window_test`); the gyro-scale
    sensitivity is the refit of the statistics of a gyro read ``1 + g`` times larger (the
    13 variables scale exactly, so no sample is kept).

    Attributes
    ----------
    stats : callable
        ``stats(g)``: the statistics of everything merged, the gyro read ``g`` times larger.
    groups : callable
        ``groups(g)``: :meth:`.accumulator.OnlineStats.group_stats` with that gyro scale.
    gyro_scale_std, torque_scale_std : float
        Stated relative one-sigma scale uncertainties (the torque's is only recorded).
    memo : dict, optional
        The last computed test and sensitivity (the estimator's, kept between calls).
    due : bool
        Compute both now; False: reuse ``memo``'s when it has them (the estimator's
        re-selection schedule: the node tests about once a second, as its torque fits).
    shift : callable, optional
        ``shift(gyro_var, W, gyro_scale_std, step)``: the segment shift of the fit with
        weight ``W`` (:func:`.adequacy.segment_shift`'s result or ``None``), from
        :mod:`.online_shift`.
    """

    stats: Callable[[float], SufficientStats]
    groups: Callable[[float], list[tuple[SufficientStats, float, float]]]
    gyro_scale_std: float = 0.0
    torque_scale_std: float = 0.0
    memo: dict[str, Any] | None = None
    due: bool = True
    shift: Callable[[np.ndarray, np.ndarray, float, float],
                    tuple[float, int, float, float] | None] | None = None

    def _memo(self, key: str, compute: Callable[[], Any]) -> Any:
        """``compute()``, or its value in :attr:`memo` when not :attr:`due`."""
        if self.memo is None:
            return compute()
        if self.due or key not in self.memo:
            self.memo[key] = compute()
        return self.memo[key]

    def scale_sensitivity(self, f: Fit, W: np.ndarray, gyro_var: np.ndarray,
                          step: float = 1e-4) -> np.ndarray:
        """``d beta / d g`` (5,) of the whole fit ``f``: refit with ``W`` of the scaled
        statistics (as :func:`_scale_sensitivity`)."""
        def compute() -> np.ndarray:
            fs, _, _ = _fit_ratios(_without_torque(self.stats(1.0 + step)), gyro_var, W)
            return (fs.beta - f.beta) / step
        return self._memo('sensitivity', compute)

    def adequacy(self, f: Fit, W: np.ndarray, gyro_var: np.ndarray,
                 step: float = 1e-4) -> Adequacy:
        """The window test of ``f`` on the segment groups, as :func:`_window_adequacy`:
        the ratios refitted on each group with ``W`` (covariance times the group's weight
        factor), groups that do not single out the ratios left out, the stated gyro scale
        profiled out (each group's sensitivity), the residual excess deciding nothing."""
        return self._memo('adequacy', lambda: self._adequacy(f, W, gyro_var, step))

    def _adequacy(self, f: Fit, W: np.ndarray, gyro_var: np.ndarray,
                  step: float) -> Adequacy:
        """The test itself (see :meth:`adequacy`)."""
        p = f.beta.size
        groups = self.groups(1.0)
        scaled = self.groups(1.0 + step) if self.gyro_scale_std and len(groups) >= 2 else []
        thetas, covs, mids, common = [], [], [], []
        for i, (st, factor, mid) in enumerate(groups if len(groups) >= 2 else []):
            st = _without_torque(st)
            sep = _separation(st)
            if sep is None or sep[0] < MIN_GAP:
                continue
            fk, _, _ = _fit_ratios(st, gyro_var, W)
            if not 0.0 < fk.excess < np.inf:
                continue
            thetas.append(fk.beta)
            covs.append(fk.cov * factor)
            mids.append(mid)
            if scaled:
                fs, _, _ = _fit_ratios(_without_torque(scaled[i][0]), gyro_var, W)
                common.append(self.gyro_scale_std * ((fs.beta - fk.beta) / step)[:, None])
        # the noise model broke down (noise-free data: the whole fit's excess is no number
        # of the noise model, e.g. negative): no shift test, as the batch's fits skip it
        broke = not 0.0 < f.excess < np.inf
        shift = None if self.shift is None or broke else self.shift(
            gyro_var, W, self.gyro_scale_std, step)
        if len(thetas) < 2:
            return check_adequacy(np.zeros((0, p)), np.zeros((0, p, p)), np.zeros(0),
                                  f.excess, max_excess=np.inf, shift=shift)
        return check_adequacy(np.array(thetas), np.array(covs), np.array(mids), f.excess,
                              max_excess=np.inf, common=np.array(common) if common else None,
                              shift=shift)


#: What the torque-free fit's checks need (a batch record's or the recursive estimator's).
Checks = TorqueFreeChecks | OnlineTorqueFreeChecks


def torque_free_checked(eq: Equations, t_gyro: np.ndarray, omega: np.ndarray,
                        segment: float | None, gyro_var: np.ndarray, diag: dict[str, Any],
                        base: dict[str, Any], gyro_scale_std: float = 0.0,
                        torque_scale_std: float = 0.0) -> InertiaEstimate:
    """The batch torque-free estimate: statistics, ratios, adequacy and stated calibration.

    Parameters
    ----------
    eq : Equations
        Equations of a torque-free record.
    t_gyro, omega : ndarray, shape (N,), (N, 3)
        The used gyro stamps [s] and samples [rad/s].
    segment : float, optional
        Anchored segment length [s].
    gyro_var : ndarray, shape (3,)
        Gyro white-noise variance per axis [rad^2/s^2].
    diag, base : dict
        Diagnostics (updated in place) and the common result fields.
    gyro_scale_std, torque_scale_std : float
        Stated relative one-sigma scale uncertainties of the gyro and the torque.

    Returns
    -------
    InertiaEstimate
        As :func:`homogeneous_estimate`, with ``diagnostics['adequacy']`` and (when a scale
        uncertainty is stated) ``diagnostics['calibration']``.
    """
    st, walk = torque_free_stats(eq, t_gyro, omega, segment)
    checks = TorqueFreeChecks(eq, t_gyro, omega, segment, gyro_scale_std, torque_scale_std)
    return homogeneous_estimate(st, gyro_var, diag, base, walk=walk, checks=checks)


def _calibration(checks: Checks, st: SufficientStats, f: Fit, W: np.ndarray,
                 gyro_var: np.ndarray, diag: dict[str, Any],
                 step: float = 1e-4) -> np.ndarray:
    """Covariance (6, 6) of the ratios from the stated gyro-scale uncertainty.

    A gyro read ``1 + g`` times too large scales the momentum variables by ``1 + g`` and the
    gyroscopic ones by ``(1 + g)^2``: torque-free, that is a change of time scale, which moves
    the ratios (not only their scale).  ``d theta / d g`` is a refit of the scaled statistics
    with the final weight (as :func:`.refits.gyro_sensitivity` for the torque paths);
    ``cov += g_std^2 J J'``.  A torque scale error has no effect on torque-free equations.
    """
    gs, ts = checks.gyro_scale_std, checks.torque_scale_std
    if not (gs or ts):
        return np.zeros((6, 6))
    add = np.zeros((6, 6))
    how = None
    if gs:
        J = TRACE_FREE @ checks.scale_sensitivity(f, W, gyro_var)
        add = gs ** 2 * np.outer(J, J)
        how = 'refit of the gyro-scaled statistics'
    diag['calibration'] = {'torque_scale_std': ts, 'gyro_scale_std': gs,
                           'gyro_sensitivity': how, 'covariance_added': add}
    return add


def _scale_sensitivity(eq: Equations, segment: float | None, f: Fit, W: np.ndarray,
                       gyro_var: np.ndarray, step: float = 1e-4) -> np.ndarray:
    """``d beta / d g`` (trace-free coordinates, shape (5,)) of the fit ``f`` of ``eq``.

    The 13 variables scale exactly (``w`` by ``1 + g``, the squared-rate integrals by
    ``(1 + g)^2``), so the scaled statistics need no new data; the refit keeps ``W``.
    """
    scaled = eq.rows(0, len(eq.t))
    scaled.V[:, :3] *= 1.0 + step
    scaled.V[:, 3:9] *= (1.0 + step) ** 2
    fs, _, _ = _fit_ratios(_without_torque(_plain_stats(scaled, segment)), gyro_var, W)
    return (fs.beta - f.beta) / step


def _plain_stats(eq: Equations, segment: float | None) -> SufficientStats:
    """The statistics :func:`torque_free_stats` makes, without the walk's exact Grams."""
    t = eq.t
    if eq.kind != 'anchored' or len(t) < 2:
        return sufficient_stats(eq, segment, t[:1], float(t[-1]) if len(t) else 0.0,
                                np.zeros(3))
    return sufficient_stats(eq, segment, t, float(t[-1]), np.ones(3))


def _shift(checks: TorqueFreeChecks, gyro_var: np.ndarray, W: np.ndarray
           ) -> tuple[float, int, float, float] | None:
    """The segment shift of the torque-free fit (:func:`.adequacy.segment_shift`): the ratios
    refitted with anchored segments :data:`SHIFT_FACTOR` x shorter, the difference tested
    against its exact covariance (:func:`_shift_covariance`); a stated gyro scale moves the
    two fits differently, so its share of their difference is added."""
    eq = checks.eq
    if eq.kind != 'anchored' or len(eq.t) < 2:
        return None
    span = float(eq.t[-1] - eq.t[0])
    fits, sens, rows = [], [], []
    w_eq = np.column_stack([np.interp(eq.t, checks.t_gyro, checks.omega[:, c]) for c in range(3)])
    for seg in (checks.segment, (checks.segment or span) / SHIFT_FACTOR):
        st = _without_torque(_plain_stats(eq, seg))   # (the walk: _shift_covariance)
        if st.n_eff < MIN_EQUATIONS:
            return None
        fk, _, th = _fit_ratios(st, gyro_var, W)
        if not 0.0 < fk.excess < np.inf:       # the noise model broke down (noise-free data)
            return None
        fits.append((fk, th, st.white_y_cov))
        rows.append(_walk_rows(eq.V, eq.t, w_eq, segment_starts(eq.t, eq.breaks, seg)))
        if checks.gyro_scale_std:
            sens.append(_scale_sensitivity(eq, seg, fk, W, gyro_var))
    cov_long, cov_short, cov_diff = _shift_covariance(
        fits, lambda a, b: _pair_grams(rows[a], rows[b]), W, gyro_var)
    if sens:
        dg = np.outer(*2 * [checks.gyro_scale_std * (sens[1] - sens[0])])
        cov_short, cov_diff = cov_short + dg, cov_diff + dg
    return segment_shift(fits[0][0].beta, cov_long, fits[1][0].beta, cov_short, cov_diff)


def _shift_covariance(fits: list[tuple[Fit, np.ndarray, np.ndarray | None]],
                      grams: Callable[[int, int], PairGrams], W: np.ndarray,
                      gyro_var: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Covariances (p, p) of the long fit (0), of the short one (1) and of their difference.

    Both fits use the same equations (segmented differently) and the same weight ``W``, so
    their sandwiches share the noise: the white gyro noise of equation ``j`` is in equation
    ``j`` of both, the walk of step ``j`` in the later equations of the segment that holds it
    in each.  ``cov(d) = C_ll + C_ss - C_ls - C_sl`` with ``C_ab = H_a^-1 M_ab H_b^-1`` and the
    cross meats :func:`_pair_meat` of ``grams(a, b)`` (:func:`_pair_grams` of the two
    segmentations' rows; the noise model, not widened by the residual excess).
    Without the cross term (``C_ss`` alone as the difference's covariance) the 8x shorter
    fit, here as efficient as the long one, made 5 false alarms in 40 conforming 20 s tumbles.
    Where the two fits share nearly all their information the difference is a cancellation
    the noise model does not resolve (a 2 s intermediate-axis flip: chi2 292 on 4 dof for a
    shift of 0.0 sigma), so the test keeps ``cov(d)`` above a floor
    (:data:`.adequacy.COV_RESOLUTION`, :func:`.adequacy.segment_shift`).
    """
    (fl, thl, wyc), (fs, _, _) = fits
    T = selector(TRACE_FREE, False, TRACE / 3.0)
    p = T.shape[1] - 1
    Im = theta_to_matrix(thl)
    Sg = np.diag(gyro_var)
    S = Im @ Sg @ Im + (wyc if wyc is not None else 0.0)
    A = walk_maps(Im)
    Hinv = [solve_symmetric(f.H, np.eye(p)) for f in (fl, fs)]

    def cov(a: int, b: int) -> np.ndarray:
        m = (T.T @ _pair_meat(grams(a, b), W, S, Im, Sg, A) @ T)[:p, :p]
        return Hinv[a] @ m @ Hinv[b].T

    c_ll, c_ls, c_ss = cov(0, 0), cov(0, 1), cov(1, 1)
    return c_ll, c_ss, c_ll + c_ss - c_ls - c_ls.T


def _pair_grams(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]
                ) -> PairGrams:
    """The cross Grams of two segmentations' :func:`_walk_rows` ``(X, R)``: ``Xa' Xb``
    (13, 13), ``Ra' Rb`` (30, 30), ``Xa' Rb`` (13, 30), ``Ra' Xb`` (30, 13)."""
    (Xa, Ra), (Xb, Rb) = a, b
    return Xa.T @ Xb, Ra.T @ Rb, Xa.T @ Rb, Ra.T @ Xb


def _pair_meat(grams: PairGrams, W: np.ndarray, S: np.ndarray, Im: np.ndarray,
               Sg: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Cross meat (10, 10) of the weighted scores of two segmentations of the same equations.

    ``grams``: :func:`_pair_grams` of their rows.  White with white (``W S W``), walk with
    walk (``W A_i Sg A_l' W``) and each one's white with the other's walk, as
    :func:`_walk_covariance` does for one segmentation; the torque variable dropped.
    """
    Gxx, Grr, Gxr, Grx = grams
    nv = N_REGRESSOR_VARIABLES
    B = np.zeros((16, 13, 13))                  # each term's Gram of the 13 variables ...
    WA = W @ A                                  # (3, 3, 3): W A_i
    WAS = WA @ Sg
    B[0] = Gxx
    B[1:10, :nv, :nv] = Grr.reshape(3, nv, 3, nv).transpose(0, 2, 1, 3).reshape(9, nv, nv)
    B[10:13, :, :nv] = Gxr.reshape(13, 3, nv).transpose(1, 0, 2)
    B[13:16, :nv, :] = Grx.reshape(3, nv, 13)
    M = np.concatenate([(W @ S @ W)[None],                                 # ... its metric
                        np.einsum('irs,jus->ijru', WAS, WA).reshape(9, 3, 3),
                        W @ Im @ Sg @ WA.transpose(0, 2, 1), WAS @ (Im @ W)])
    L = (_VMAP.T @ B @ _VMAP).reshape(16, 3, 10, 3, 10)      # lift() of each
    meat = np.einsum('krs,krqsp->qp', M, L)
    meat[9, :] = 0.0
    meat[:, 9] = 0.0
    return meat


def _window_adequacy(checks: TorqueFreeChecks, f: Fit, W: np.ndarray,
                     gyro_var: np.ndarray) -> Adequacy:
    """The adequacy test of the torque-free fit: window consistency.

    As for the torque paths (:mod:`.adequacy`): up to :data:`.options.ADEQUACY_WINDOWS`
    consecutive windows of at least :data:`.options.ADEQUACY_MIN_WINDOW_S` each, the ratios
    refitted on each with the whole fit's weight and their noise-model covariance (the exact
    gyroscopic walk, inflated by the window's residual excess as the torque paths' window
    fits are).  A gyro bias or an
    unmodelled torque acts differently as the motion wanders between the axes, so the
    windows disagree.  So does a gyro scale error (torque-free, a change of time scale): the
    stated one is profiled out of the test (each window's sensitivity, see
    :func:`.adequacy.window_consistency`).  Windows whose motion does not single out the
    ratios are left out.

    The residual excess decides nothing here (it widens the sigma and is reported): on
    torque-free records it is a poor test, scattered (1.5 s tosses of the reference
    simulator, correct data: mean 0.95, sd 0.15, up to 1.51 in 40 seeds) and blind to a gyro
    bias (0.01 rad/s on the nominal scene: 1.34 while the ratios move by 150 sigma).
    """
    eq = checks.eq
    empty = np.zeros((0, f.beta.size)), np.zeros((0, f.beta.size, f.beta.size)), np.zeros(0)
    span = float(eq.t[-1] - eq.t[0]) if len(eq.t) else 0.0
    n_win = min(ADEQUACY_WINDOWS, int(span // ADEQUACY_MIN_WINDOW_S))
    shift = _shift(checks, gyro_var, W)
    if eq.kind != 'anchored' or n_win < 2:
        return check_adequacy(*empty, f.excess, max_excess=np.inf, shift=shift)
    cuts = np.searchsorted(eq.t, np.linspace(eq.t[0], eq.t[-1], n_win + 1)[1:-1])
    bounds = [0, *cuts.tolist(), len(eq.t)]
    thetas, covs, mids, common = [], [], [], []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        if b - a < MIN_EQUATIONS:
            continue
        sub = eq.rows(a, b)
        st, walk = torque_free_stats(sub, checks.t_gyro, checks.omega, checks.segment)
        st = _without_torque(st)
        sep = _separation(st)
        if sep is None or sep[0] < MIN_GAP:
            continue
        fk, _, theta_k = _fit_ratios(st, gyro_var, W)
        if not 0.0 < fk.excess < np.inf:      # the noise model broke down (noise-free data)
            continue
        cov = fk.cov
        if walk is not None:
            cov = _walk_covariance(st, fk, W, theta_k, gyro_var, walk, TRACE / 3.0)
        thetas.append(fk.beta)
        covs.append(cov)
        mids.append(0.5 * float(sub.t[0] + sub.t[-1]))
        if checks.gyro_scale_std:
            common.append(checks.gyro_scale_std
                          * _scale_sensitivity(sub, checks.segment, fk, W, gyro_var)[:, None])
    if len(thetas) < 2:
        return check_adequacy(*empty, f.excess, max_excess=np.inf, shift=shift)
    return check_adequacy(np.array(thetas), np.array(covs), np.array(mids), f.excess,
                          max_excess=np.inf, common=np.array(common) if common else None,
                          shift=shift)
