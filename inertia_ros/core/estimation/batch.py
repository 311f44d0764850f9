"""Batch inertia estimation from gyro and torque streams: :func:`estimate`.

This module is the orchestration of :func:`estimate`: validation, the method choice, torque
coverage and gaps, the anchored-segment choice and the dispatch.  The pieces live in one
module each: :mod:`.equations` (per-method equations), :mod:`.statistics` (sufficient
statistics), :mod:`.fit` (weighted EIV-compensated least squares), :mod:`.selection` and
:mod:`.assemble` (identifiability, model choice, status), :mod:`.homogeneous` (torque-free),
:mod:`.ml` (likelihood refinement), :mod:`.noise` (noise levels).

Methods (:data:`METHODS`), all built from :mod:`.regressors`:

``auto`` (default)
    ``ml`` for records of up to :data:`ML_AUTO_MAX_SAMPLES` gyro samples, ``integral`` for
    longer ones (``ml`` costs about 6x ``integral`` on a 60 s, 200 Hz record and more on
    long ones, where ``integral``'s error is already small); ``filtered`` below the lowest
    line when the integral fit's residual spectrum shows lines or excess high-frequency power
    (vibration, a spinning part's imbalance) and the candidates' tests favour it
    (:mod:`.method_choice`).  The result's ``method`` names the one used and
    ``diagnostics['method_selection']`` says why.
``integral``
    Momentum form anchored per segment.  For every gyro sample ``b`` of a segment,
    ``I w_b + int_{t0}^{t_b} w x (I w) dt - d t_b - h0 = int_{t0}^{t_b} tau dt``, with the
    segment's initial momentum ``h0`` as three nuisance parameters (eliminated exactly by
    removing the segment mean of every column).  Each equation then carries only the white
    gyro noise of ``w_b`` (``I n_b``) plus the random walk of the integrated torque noise, so
    nothing is differentiated and no window overlaps.  Weighted by ``(I S_g I)^-1`` (``S_g`` the
    gyro noise covariance, ``I`` from a first pass) and bias-compensated for the gyro noise in
    the regressor (errors in variables: ``H = Phi' W Phi - n B``).  The covariance is the
    sandwich with the exact model of both noises: white gyro noise and piecewise-constant torque
    noise integrated over each torque interval, inflated when the residuals exceed that model.
    The segment length trades the information in slow motion against the random walk of the
    integrated torque noise; it is chosen by minimising the predicted variance among 5, 10, 20,
    40 s and the whole record (unless ``segment`` is given).  All statistics are quadratic
    forms in 13 per-sample variables ``[w, m, t, T]``, so the data are reduced once to a
    13 x 13 Gram matrix (plus the torque-noise sums) and every model, weight and segmentation
    is evaluated on those.
``ml``
    Maximum likelihood: the ``integral`` estimate (status, model and bias decision included)
    refined by Gauss-Newton on the likelihood of the exact model (gyro white noise, torque
    noise as process noise held over each torque interval; :mod:`.ml`), with the covariance
    from the Fisher information.  Attains the Cramer-Rao bound of :mod:`inertia_ros.core.crlb`.
    Only an ``ok`` zero-order-hold estimate without torque gaps is refined; otherwise, or when
    the refinement does not converge, the ``integral`` result is returned unchanged and
    ``diagnostics['ml']`` says why.
``integral_ls``
    The same anchored equations, unweighted and without bias compensation.
``integral_sliding``
    Overlapping windows ``I (w_b - w_a) + int_a^b w x I w = int_a^b tau`` of fixed length,
    ordinary least squares, Newey-West (HAC) covariance for the overlap.
``filtered``
    Both sides through the same low-pass filter ``1 / (1 + s T)^2``, the derivative moved onto
    the filter (:mod:`.filtered`); Newey-West covariance.
``differential_fd``
    ``tau(t_b) = I w_dot_b + w_b x I w_b`` with central finite differences: the baseline.
``differential_sg``
    The same with a Savitzky-Golay smoothing differentiator, the same filter on the torque.

    Both differentiate the gyro, so its noise enters the regressor (errors in variables) and
    shrinks the fit by about the noise share of the differentiated gyro.  That share (from the
    estimated gyro noise and the differentiator's noise gain, per axis, in
    ``diagnostics['regressor_noise_share']``) above 2 % gives ``insufficient_excitation``
    instead of a biased tensor with status ``ok``.

Model selection (``model='auto'`` / ``torque_bias='auto'``): Wald tests on the general model
(full tensor plus bias) with its calibrated covariance (an F-test analogue that stays valid
with the correlated residuals of the momentum equations; BIC would need white residuals): the
bias is kept when its test rejects ``d = 0`` at ``alpha``, and the smallest parameter set whose
restriction the MSE test does not reject at ``SelectionPolicy.model_alpha`` (5 %) is used
(:func:`.selection.select_model`).  Every path that selects a model (this estimator, the
window's re-solves, the recursive estimators) concludes through :func:`.assemble.conclude`,
so the rule is one.

Identifiability: the gyro-noise-corrected information matrix, scaled by the total column
energy, shows which directions carry signal; elements in directions that are mostly gyro noise
are undetermined (reported NaN/null, held at a plausible value while the rest is estimated),
and so are elements whose standard error exceeds ``identifiability_tol`` of the tensor scale.
Torque-free data gives the scale-free (homogeneous) solution from the null vector.  A
physically impossible tensor (not positive definite, triangle inequality violated) is replaced
by the nearest valid one and the violation is reported in ``diagnostics['physical']``.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from .._blas import one_blas_thread
from .._numeric import median
from .._validate import as_noise_std, as_samples, as_times, refuse_nanoseconds
from ..tensor import check_physical, theta_to_matrix
from . import refits
from .adequacy import Adequacy
from .assemble import conclude, status_only
from .config import unapplied
from .equations import (
    Equations,
    build_equations,
    shared_integral_equations,
    thinned_inertial_equations,
)
from .filtered import equations_for
from .fit import Fit, fit_two_pass
from .hold_choice import auto_hold, coverage, stated_hold
from .homogeneous import is_torque_free, torque_free_checked
from .model import model_basis, model_parts
from .model import symmetry_axis as unit_axis
from .noise import isotropy_floor, noise_std_from_differences
from .nuisance import nuisance_hook
from .options import (
    ALPHA,
    ATTITUDE_BRIDGE_RAD,
    BATCH_HOLDS,
    GAP_FACTOR,
    IDENTIFIABILITY_TOL,
    INERTIAL_TORQUE,
    MAX_RESIDUAL_EXCESS,
    METHODS,
    MIN_EQUATIONS,
    MIN_GYRO_SAMPLES,
    ML_AUTO_MAX_SAMPLES,
    MODELS,
    TORQUE_BIAS,
    check_choice,
)
from .result import InertiaEstimate
from .selection import SelectionPolicy, screen_inertial, screen_step, select_disturbance
from .statistics import sufficient_stats
from .uncertainty import principal_with_std, ratio_cov

__all__ = ['BATCH_HOLDS', 'METHODS', 'ML_AUTO_MAX_SAMPLES', 'MODELS', 'TORQUE_BIAS', 'estimate',
           'model_basis']

_SELECT_MAX_ROWS = 100_000                     # equations used by the segment-length search
_HOLD_PREFIX_FROM = 300_000                    # gyro samples from which holds are compared on
                                               # the first _SELECT_MAX_ROWS only
_SEGMENT_CANDIDATES = (5.0, 10.0, 20.0, 40.0)   # s, anchored-segment lengths tried
_EIV_MAX_SHARE = 0.02                          # differentiated-gyro noise share tolerated
#: The methods that take ``inertial_torque``: ``ml`` (and ``auto``'s ml) through its integral
#: stage, whose result it keeps when the inertial torque is kept (:func:`_refine`).
_INERTIAL_METHODS = ('auto', 'integral', 'integral_ls', 'ml', 'filtered')


@nuisance_hook
@one_blas_thread()                         # (medium products: a second thread costs more CPU)
def estimate(t_gyro: Any, omega: Any, t_torque: Any, torque: Any, *,
             method: str = 'auto', model: str = 'auto', torque_bias: str = 'auto',
             symmetry_axis: Any = None, hold: str = 'auto', alpha: float = ALPHA,
             gyro_noise: Any = None, torque_noise: Any = None, segment: float | None = None,
             window: float | None = None, identifiability_tol: float = IDENTIFIABILITY_TOL,
             physical: bool = True, torque_scale_std: float = 0.0,
             gyro_scale_std: float = 0.0, nuisance: Any = 'off', rotation_hz: float | None = None,
             inertial_torque: str = 'auto') -> InertiaEstimate:
    """Estimate the inertia tensor from gyro and torque samples (Euler's equations).

    Parameters
    ----------
    t_gyro, omega : array_like, shape (N,), (N, 3)
        Gyro sample times [s], strictly increasing; angular velocity, body axes [rad/s].
    t_torque : array_like, shape (M,)
        Torque sample times [s], strictly increasing; M = 0 means torque-free data.
    torque : array_like, shape (M, 3)
        Known applied torque about the centre of mass, body axes [N m].
    method : str
        One of :data:`METHODS` (``auto``: :mod:`.method_choice`).
    model : {'auto', 'full', 'diagonal', 'axisymmetric'}
        Parameter set; ``auto`` picks the smallest the data supports (the MSE test at 5 %,
        :func:`.selection.select_model`; ``axisymmetric`` is only a candidate when
        ``symmetry_axis`` is given).
    torque_bias : {'auto', 'on', 'off'}
        Estimate a constant unmeasured disturbance torque (3 more parameters).
    symmetry_axis : {'x', 'y', 'z'} or array_like (3,), optional
        Body symmetry axis (axisymmetric model).
    hold : {'auto', 'zoh', 'linear'}
        Torque between samples: held, linear, or both tried (``diagnostics['hold_selection']``).
    alpha : float
        Level of the torque bias's Wald test (0 < alpha < 1); the parameter set's level is
        :data:`.selection.MODEL_ALPHA`.
    gyro_noise, torque_noise : float or array_like (3,), optional
        White-noise std per axis [rad/s] and [N m]; estimated from the data when omitted.
    segment : float, optional
        Longest anchored segment [s] of the integral methods (default: chosen from the data).
    window : float, optional
        Window length [s] of ``integral_sliding`` (default 2 s) or ``differential_sg``
        (default 1 s; the same Savitzky-Golay filter is applied to the torque); the filter
        time constant of ``filtered`` (default: chosen from the data).
    identifiability_tol : float
        Largest standard error of an identifiable element, as a share of the tensor scale.
    physical : bool
        Project an impossible tensor onto the nearest valid one (``diagnostics['physical']``).
    torque_scale_std, gyro_scale_std : float
        Relative one-sigma scale uncertainty of the torque and the gyro calibration (0.01 =
        1 %; default 0): invisible in the data, so stated (``diagnostics['calibration']``).
    nuisance : 'auto', 'off' or list of str
        Sensor nuisance terms, applied by :func:`.nuisance.nuisance_hook` (default ``off``).
    rotation_hz : float, optional
        Lowest rotation frequency of spinning parts [Hz] (``auto``: :mod:`.method_choice`).
    inertial_torque : {'auto', 'off', 'on'}
        A torque constant in inertial axes beside the bias (``InertiaEstimate.inertial_torque``):
        ``auto`` (default) screened (:func:`.selection.screen_inertial`), kept by its Wald test
        at ``alpha``; left out by the sliding and differential methods, which refuse ``on``;
        ``ml`` keeps the integral result when it is kept (``diagnostics['ml']``).

    Returns
    -------
    InertiaEstimate
        For well-formed input always; its status says what the data allowed.

    Raises
    ------
    ValueError
        Malformed input: shapes, NaN/inf, non-increasing times, too few samples, options.
    """
    tg = as_times(t_gyro, 't_gyro')
    w = as_samples(omega, len(tg), 'omega', 't_gyro')
    ts = as_times(t_torque, 't_torque')
    _ = [refuse_nanoseconds(t, name) for t, name in ((tg, 't_gyro'), (ts, 't_torque'))]
    tau = as_samples(torque, len(ts), 'torque', 't_torque')
    return estimate_arrays(tg, w, ts, tau, method=method, model=model, torque_bias=torque_bias,
                           symmetry_axis=symmetry_axis, hold=hold, alpha=alpha,
                           gyro_noise=gyro_noise, torque_noise=torque_noise, segment=segment,
                           window=window, identifiability_tol=identifiability_tol,
                           physical=physical, torque_scale_std=torque_scale_std,
                           gyro_scale_std=gyro_scale_std, rotation_hz=rotation_hz,
                           inertial_torque=inertial_torque)


def estimate_arrays(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray, *,
                    method: str = 'auto', model: str = 'auto', torque_bias: str = 'auto',
                    symmetry_axis: Any = None, hold: str = 'auto', alpha: float = ALPHA,
                    gyro_noise: Any = None, torque_noise: Any = None,
                    segment: float | None = None, window: float | None = None,
                    identifiability_tol: float = IDENTIFIABILITY_TOL, physical: bool = True,
                    torque_scale_std: float = 0.0, gyro_scale_std: float = 0.0,
                    rotation_hz: float | None = None, white_y_cov: np.ndarray | None = None,
                    final: bool = True, walk_cov: np.ndarray | None = None,
                    walk_wh: np.ndarray | None = None,
                    inertial_torque: str = 'auto') -> InertiaEstimate:
    """:func:`estimate` on validated arrays, every input's one dispatch (a momentum input's
    equivalent held torque too, :func:`.momentum.estimate_with_momentum`): the options
    checked, the method choice, ``integral`` then the ``ml`` refinement.

    ``white_y_cov`` (3, 3): a momentum input's white wheel noise in ``y``, ``walk_cov`` (M, 3,
    3) and ``walk_wh`` (M, 9) its time-varying walk on the torque samples
    (:attr:`.equations.Equations.walk_cov`); ``inertial_torque`` as :func:`estimate`'s;
    ``final=False``: a
    method other than ``auto`` and ``ml`` without the adequacy tests (a sensitivity
    re-estimation whose tensor alone is used).
    """
    # :func:`.config.require` checked the other options; a bool torque_bias is 'on'/'off'
    # as there (and in the online estimators)
    check_choice('method', method, METHODS)
    if isinstance(torque_bias, (bool, np.bool_)):
        torque_bias = 'on' if torque_bias else 'off'
    check_choice('torque_bias', torque_bias, TORQUE_BIAS)
    inertial_torque, skipped = _inertial_for(method, inertial_torque)
    policy = SelectionPolicy(alpha, identifiability_tol, physical, torque_scale_std,
                             gyro_scale_std, inertial_torque=inertial_torque)
    axis = unit_axis(symmetry_axis)
    if len(tg) < 6:
        raise ValueError(f't_gyro: {len(tg)} samples is fewer than the 6 inertia parameters')
    if len(ts) == 1:
        raise ValueError('t_torque: a single torque sample covers no time; give at least 2 '
                         '(or none for torque-free data)')
    if method == 'auto':      # the formulation and band by evidence (:mod:`.method_choice`)
        return _auto_method(tg, w, ts, tau, hold, gyro_noise, torque_noise, segment, window,
                            model, torque_bias, axis, policy, rotation_hz,
                            (white_y_cov, walk_cov, walk_wh))
    first = _estimate_direct('integral' if method == 'ml' else method, tg, w, ts, tau, hold,
                             gyro_noise, torque_noise, segment, window, model, torque_bias,
                             axis, policy, (white_y_cov, walk_cov, walk_wh),
                             final or method == 'ml')
    if skipped is not None:
        first.diagnostics['disturbance'] = {'requested': {'inertial_torque': 'auto'},
                                            'chosen': None, 'skipped': skipped}
    if method != 'ml':
        return first
    return _refine(first, tg, w, ts, tau, first.diagnostics.get('hold', hold), axis)


def _inertial_for(method: str, inertial_torque: str) -> tuple[str, str | None]:
    """The ``inertial_torque`` setting a method runs with, and why ``auto`` was left out
    (``None``: it was not): ``auto`` on a method without the term runs without it, ``on``
    there is refused in one line."""
    value = check_choice('inertial_torque', inertial_torque, INERTIAL_TORQUE)
    if value == 'off' or method in _INERTIAL_METHODS:
        return value, None
    if value == 'on':
        raise ValueError(f"inertial_torque: 'on' needs method {', '.join(_INERTIAL_METHODS)} "
                         f"(the other methods have no inertial torque yet); got method="
                         f"{method!r}: use inertial_torque='auto' or 'off'")
    return 'off', f'method {method!r} has no inertial torque term (it runs without it)'


def _auto_method(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray, hold: str,
                 gyro_noise: Any, torque_noise: Any, segment: float | None,
                 window: float | None, model: str, torque_bias: str, axis: np.ndarray | None,
                 policy: SelectionPolicy, rotation_hz: float | None,
                 mom_noise: tuple[Any, ...] = (None, None, None)) -> InertiaEstimate:
    """``method='auto'``: :func:`.method_choice.choose` on the ``integral`` estimate, with
    ``ml`` and ``filtered`` (cutoff ``1 / window`` when ``window`` is given) as candidates;
    ``mom_noise``: a momentum input's ``(white_y_cov, walk_cov, walk_wh)``."""
    from .method_choice import choose

    first = _estimate_direct('integral', tg, w, ts, tau, hold, gyro_noise, torque_noise,
                             segment, window, model, torque_bias, axis, policy, mom_noise)
    used = first.diagnostics.get('hold', hold)
    return choose(
        first, (tg, w, ts, tau), used, len(tg),
        lambda f: _refine(f, tg, w, ts, tau, used, axis),
        lambda fc: _estimate_direct('filtered', tg, w, ts, tau, used, gyro_noise, torque_noise,
                                    None, window or 1.0 / fc, model, torque_bias, axis, policy,
                                    mom_noise),
        rotation_hz)


def _estimate_direct(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray,
                     tau: np.ndarray, hold: str, gyro_noise: Any, torque_noise: Any,
                     segment: float | None, window: float | None, model: str,
                     torque_bias: str, axis: np.ndarray | None, policy: SelectionPolicy,
                     mom_noise: tuple[Any, ...] = (None, None, None),
                     final: bool = True) -> InertiaEstimate:
    """Every method but ``ml``: noise levels, then :func:`_estimate_shifted` from ``t = 0``
    (``final=False``: without the adequacy tests, for a result whose tensor alone is used;
    a given hold only)."""
    # work relative to the first stamp: ROS times are ~1.7e9 s, and prefix sums of absolute
    # times would lose the sub-millisecond differences everything depends on
    t_origin = float(min(tg[0], ts[0])) if len(ts) else float(tg[0])
    if segment is not None and not segment > 0:
        raise ValueError(f'segment: must be > 0 s, got {segment!r}')
    if window is not None and not window > 0:
        raise ValueError(f'window: must be > 0 s, got {window!r}')
    gyro_std, torque_std = _noise_levels(w, tau, gyro_noise, torque_noise)
    diag: dict[str, Any] = {'gyro_noise_std': gyro_std, 'torque_noise_std': torque_std,
                            'warnings': []}

    def run(h: str, head: int | None = None, final: bool = True,
            chosen: tuple[float | None, dict[str, Any]] | None = None,
            shared: dict[str, Any] | None = None,
            inertial: str | None = None,
            plain: InertiaEstimate | None = None) -> InertiaEstimate:
        """The estimate with hold ``h`` on its own copy of the diagnostics so far (on the
        first ``head`` gyro samples when given; without the adequacy tests, which do not
        change the residual excess, unless ``final``: a result only compared, not reported;
        with the segment length ``chosen`` by an earlier run when given; the
        equations shared with the other hold's run through ``shared``; ``inertial``: the
        ``inertial_torque`` setting instead of the requested one; ``plain``: this run's
        result without the inertial torque, returned when its screen keeps none)."""
        pol = policy if inertial is None else replace(policy, inertial_torque=inertial)
        own = dict(diag, warnings=list(diag['warnings']))
        if inertial is not None:                 # (a selection on this run replaces it)
            own['disturbance'] = {'requested': {'torque_bias': torque_bias, 'inertial_torque':
                                                policy.inertial_torque},
                                  'chosen': None, 'inertial_torque_of_the_held_run': inertial}
        n = len(tg) if head is None else head
        m = len(ts) if head is None else int(np.searchsorted(ts, tg[n - 1], side='right')) + 1
        return _estimate_shifted(method, tg[:n] - t_origin, w[:n], ts[:m] - t_origin, tau[:m],
                                 h, gyro_std ** 2, torque_std ** 2, segment, window, model,
                                 torque_bias, axis, pol, own, mom_noise,
                                 final, chosen, shared, plain)
    if hold != 'auto':
        return stated_hold(run, hold, final, policy.inertial_torque == 'auto')
    head = _SELECT_MAX_ROWS if len(tg) > _HOLD_PREFIX_FROM else None
    return auto_hold(run, torque_std, head, policy.inertial_torque != 'off')


def _noise_levels(w: np.ndarray, tau: np.ndarray, gyro_noise: Any,
                  torque_noise: Any) -> tuple[np.ndarray, np.ndarray]:
    """Gyro [rad/s] and torque [N m] white-noise std per axis: given, or from the data."""
    if gyro_noise is None:
        gyro_std = isotropy_floor(noise_std_from_differences(w))
    else:
        gyro_std = as_noise_std(gyro_noise, 'gyro_noise')
    if len(tau) == 0:
        return gyro_std, np.zeros(3)
    torque_std = (noise_std_from_differences(tau) if torque_noise is None
                  else as_noise_std(torque_noise, 'torque_noise'))
    return gyro_std, torque_std


def _estimate_shifted(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray,
                      tau: np.ndarray, hold: str, gyro_var: np.ndarray, torque_var: np.ndarray,
                      segment: float | None, window: float | None, model: str,
                      torque_bias: str, axis: np.ndarray | None, policy: SelectionPolicy,
                      diag: dict[str, Any], mom_noise: tuple[Any, ...] = (None, None, None),
                      final: bool = True, chosen: tuple[float | None, Any] | None = None,
                      shared: dict[str, Any] | None = None,
                      plain: InertiaEstimate | None = None) -> InertiaEstimate:
    """Every method but ``ml`` on validated, origin-shifted data: coverage, rules, fit.

    ``final``, ``chosen``, ``shared``, ``plain``: as :func:`_estimate_direct`'s ``run``.
    """
    mask, tau_end = coverage(tg, ts, hold, diag)
    used = int(np.sum(mask))
    base = dict(method=method, samples_used=used, samples_dropped=len(tg) - used)
    if used < MIN_GYRO_SAMPLES:
        diag['reason'] = (f'only {used} gyro samples inside the torque coverage '
                          f'[{ts[0] if len(ts) else tg[0]:.6g}, {tau_end:.6g}] s')
        return status_only('insufficient_data', diag, base)
    idx = np.flatnonzero(mask)
    med_g = median(np.diff(tg))
    breaks = (np.diff(idx) > 1) | (np.diff(tg[idx]) > GAP_FACTOR * med_g)
    torque_rms = np.sqrt(np.mean(tau ** 2, axis=0)) if len(ts) else np.zeros(3)
    diag['torque_rms'] = torque_rms
    if is_torque_free(torque_rms, np.sqrt(torque_var)):
        diag['warnings'] += unapplied('batch', policy)
        return _homogeneous(method, tg, w, ts, tau, mask, breaks, hold, gyro_var,
                            segment or 10.0, window, diag, base, policy)
    data = (tg, w, ts, tau, mask, breaks)
    eq, policy = _equations(method, data, hold, gyro_var, window, shared, policy, diag)
    wm = w[mask]
    eq.motion = (wm.T @ wm / len(wm), med_g)          # gyroscopic noise walk (fit meat)
    eq.white_y_cov, eq.walk_cov, eq.walk_wh = mom_noise   # a momentum input's noise, walk
    diag.update(eq.info)
    early = _equation_rules(eq, method, diag, base)
    if early is not None:
        return early
    eq, policy, screen, found = _screened(
        eq, method, data, hold, gyro_var, shared, policy, diag,
        (ts, tau_end, torque_var, torque_bias), lambda e: _statistics(
            e, segment, chosen, ts, tau_end, gyro_var, torque_var, torque_bias != 'off', diag),
        chosen if plain is not None else None)
    if plain is not None and screen is not None and policy.inertial_torque == 'off':
        return _as_plain(plain, diag, screen)          # (the same fit: no work twice)
    segments, fit = found
    segment, st = segments[torque_bias != 'off']
    if eq.kind == 'anchored':
        diag['segments'] = st.n_seg
        diag['segment_s'] = segment
        if st.n_eff < MIN_EQUATIONS:
            diag['reason'] = f'{st.n_eff} equations are too few for the parameters'
            return status_only('insufficient_data', diag, base)

    def adequacy(f: Fit, chosen: str) -> Adequacy:
        """The model-adequacy tests of the final fit (window consistency, residual excess).

        Whether one constant tensor explains the data does not depend on the method: the
        sliding and differential methods are tested on the anchored (integral) equations.
        """
        if eq.kind == 'anchored':
            return refits.window_adequacy(eq, segments.get(f.bias, (segment,))[0], ts,
                                          tau_end, gyro_var, torque_var, f)
        eqa = build_equations('integral', tg, w, ts, tau, mask, breaks, hold, gyro_var, None)
        eqa.motion = eq.motion
        return refits.window_adequacy(eqa, None, ts, tau_end, gyro_var, torque_var, f, own=False)

    def gyro_sensitivity(f: Fit) -> np.ndarray | None:
        """``d beta / d g`` of the final fit for a relative gyro scale error ``g``."""
        return refits.gyro_sensitivity(eq, segments.get(f.bias, (segment,))[0], ts, tau_end,
                                       gyro_var, torque_var, f)

    est = conclude(fit, model, torque_bias, axis, policy, diag, base,
                   adequacy if final else None, gyro_sensitivity)
    if screen is not None:                  # what the inertial torque's screen said
        _note_screen(est, screen)
    if eq.kind == 'anchored' and est.inertia is not None and est.torque_bias is None \
            and False in segments:       # the final fit without the bias: its length
        est.diagnostics['segment_s'], st = segments[False]
        est.diagnostics['segments'] = st.n_seg
    return est


def _equations(method: str, data: tuple[np.ndarray, ...], hold: str, gyro_var: np.ndarray,
               window: float | None, shared: dict[str, Any] | None, policy: SelectionPolicy,
               diag: dict[str, Any], wide: bool = False) -> tuple[Equations, SelectionPolicy]:
    """The run's equations (``data``: ``tg, w, ts, tau, mask, breaks``; shared with the other
    hold's run through ``shared``) and its policy: with the inertial torque ``'on'`` (or
    ``wide``, after :func:`_screened`), its columns, and the torque left out
    (``diag['disturbance']['skipped']``, the policy's ``inertial_torque`` off) when a gyro
    gap is too long to carry the attitude over (:data:`.options.ATTITUDE_BRIDGE_RAD`);
    ``'auto'`` starts from the 13 variables."""
    wide = wide or policy.inertial_torque == 'on'     # the inertial torque's columns
    eq = (equations_for(method, *data, hold, gyro_var, window, wide)
          if shared is None or method not in ('integral', 'integral_ls') else
          shared_integral_equations(method, *data, hold, gyro_var, shared, wide))
    gap = eq.info.get('attitude', {}).get('bridge_error_rad', 0.0)
    if gap > ATTITUDE_BRIDGE_RAD:
        policy = _skipped(gap, policy, diag)
    return eq, policy


def _skipped(gap: float, policy: SelectionPolicy, diag: dict[str, Any]) -> SelectionPolicy:
    """The policy without the inertial torque, and why (a gyro gap of attitude error bound
    ``gap`` [rad] beyond :data:`.options.ATTITUDE_BRIDGE_RAD`)."""
    diag['disturbance'] = {
        'requested': {'inertial_torque': policy.inertial_torque}, 'chosen': None,
        'skipped': (f'a gyro gap is too long to carry the attitude over (error bound '
                    f'{gap:.3g} rad > {ATTITUDE_BRIDGE_RAD:g}): the inertial torque is not '
                    'fitted')}
    return replace(policy, inertial_torque='off')


def _screened(eq: Equations, method: str, data: tuple[np.ndarray, ...], hold: str,
              gyro_var: np.ndarray, shared: dict[str, Any] | None, policy: SelectionPolicy,
              diag: dict[str, Any], run: tuple[Any, ...], stats: Any,
              lazy: tuple[float | None, Any] | None = None
              ) -> tuple[Equations, SelectionPolicy, dict[str, Any] | None, Any]:
    """The run's equations, policy, screen record and ``stats(eq) -> (segments, fit)``
    (:func:`_statistics`).  ``inertial_torque='auto'``: the 13-variable equations ``eq`` and
    the policy without the inertial torque, unless its screen
    (:func:`.selection.screen_inertial`, on every :func:`.selection.screen_step`-th
    equation, at the segment length the 13-variable run chose) keeps it and then the rule at
    its own level on the wide statistics does too: then the wide equations (otherwise the
    13-variable estimate, as ``'off'``).  ``run``: ``ts, tau_end, torque_var,
    torque_bias``; ``lazy``: the segment length chosen by a run without the inertial torque
    whose result stands unless it is kept (the statistics then ``None`` when it is not)."""
    found = None if lazy is not None else stats(eq)
    if policy.inertial_torque != 'auto' or eq.V.shape[1] != 13:
        return eq, policy, None, found or stats(eq)
    ts, tau_end, torque_var, torque_bias = run
    segment = lazy[0] if lazy is not None else found[0][torque_bias != 'off'][0]
    step = screen_step(len(eq.t))
    thin = thinned_inertial_equations(eq, data[0], data[1], np.flatnonzero(data[4]), step)
    gap = thin.info['attitude']['bridge_error_rad']
    if gap > ATTITUDE_BRIDGE_RAD:
        diag['attitude'] = thin.info['attitude']
        return eq, _skipped(gap, policy, diag), None, found or stats(eq)
    # the torque noise on a grid about as coarse as the kept equations (the walk between
    # them is the same; g intervals' held noise as one with 1/g of the variance)
    g = 1 if eq.walk_cov is not None or len(ts) < 3 else max(
        1, int(median(np.diff(thin.t)) / median(np.diff(ts))))
    st = sufficient_stats(thin, segment, ts[::g], tau_end, torque_var / g)
    wide, screen = screen_inertial(
        lambda basis, bias, offset=None, theta0=None, inertial=False: fit_two_pass(
            st, basis, bias, gyro_var, torque_var / g, offset, theta0, inertial=inertial),
        torque_bias, len(thin.t), step, level=policy.alpha)
    screen['torque_grid_coarser_by'] = g
    if not wide:
        diag['disturbance'] = {'requested': {'torque_bias': torque_bias,
                                             'inertial_torque': 'auto'}, 'chosen': None}
        return eq, replace(policy, inertial_torque='off'), screen, found
    full, wide_policy = _equations(method, data, hold, gyro_var, None, shared, policy, diag,
                                   True)
    full.motion, full.white_y_cov, full.walk_cov, full.walk_wh = (
        eq.motion, eq.white_y_cov, eq.walk_cov, eq.walk_wh)
    searched = diag.get('segment_selection')
    wide_found = stats(full)
    if wide_policy.inertial_torque != 'off':
        # the rule at its own level (conclude runs it again, on the same fit): without d the
        # estimate is the 13-variable one, as 'off' (its segment length, its bias test)
        keep_d, rule = select_disturbance(wide_found[1], torque_bias, 'auto', policy.alpha)[1:]
        if keep_d:
            diag.update(full.info)
            return full, wide_policy, screen, wide_found
        if searched is None:        # (the filtered method searches no segment length)
            diag.pop('segment_selection', None)
        else:
            diag['segment_selection'] = searched
        diag['disturbance'] = {'requested': {'torque_bias': torque_bias,
                                             'inertial_torque': 'auto'}, 'chosen': None,
                               'tests': rule['tests'], 'rule': rule['rule'] + (
                                   '; d not kept: the 13-variable estimate')}
    return eq, replace(policy, inertial_torque='off'), screen, found


def _as_plain(plain: InertiaEstimate, diag: dict[str, Any],
              screen: dict[str, Any]) -> InertiaEstimate:
    """``plain`` (the run without the inertial torque) as the result of the run whose screen
    or rule kept none, with that run's disturbance record."""
    est = replace(plain, diagnostics=dict(plain.diagnostics,
                                          disturbance=dict(diag.get('disturbance') or {})))
    _note_screen(est, screen)
    return est


def _note_screen(est: InertiaEstimate, screen: dict[str, Any]) -> None:
    """``diagnostics.disturbance.screen`` of the result, and its choice when the estimate
    is the 13-variable one (the bias selected as without the option)."""
    dist = est.diagnostics.setdefault('disturbance', {})
    dist['screen'] = screen
    if dist.get('chosen') is None and '+inertial' not in est.model:
        dist['chosen'] = 'none' if est.torque_bias is None else 'body'


def _statistics(eq: Equations, segment: float | None,
                chosen: tuple[float | None, dict[str, Any]] | None, ts: np.ndarray,
                tau_end: float, gyro_var: np.ndarray, torque_var: np.ndarray, bias: bool,
                diag: dict[str, Any]) -> tuple[dict[bool, tuple[Any, Any]], Any]:
    """The segment length (given, ``chosen`` earlier or searched), the statistics and the fit
    function ``fit(basis, bias, offset=None, theta0=None) -> Fit`` on them.

    The search's statistics and general-model fit of the chosen length are the ones the
    estimate needs first (the same calls on the same equations): taken, not computed again.
    The best length depends on the model: searched with the bias (``bias``, the general model
    of ``torque_bias='auto'``), a fit without it (the bias dropped by its test) uses the
    length searched without it (``diag['segment_selection']['without_bias']``), so that the
    answer does not depend on whether a bias was tried.  Returns ``({bias: (segment,
    stats)}, fit)``, the lengths filled in as the fits need them.
    """
    tried: dict[Any, tuple[Any, Fit]] = {}
    known: dict[Any, Any] = {}                        # the searched candidates' statistics
    searched = eq.kind == 'anchored' and segment is None
    if searched:
        segment, rec = chosen if chosen is not None else _choose_segment(
            eq, ts, tau_end, gyro_var, torque_var, bias, tried, known)
        diag['segment_selection'] = rec = dict(rec)
    st, first = tried.pop(segment, (None, None))
    tried.clear()
    if st is None:
        st = sufficient_stats(eq, segment, ts, tau_end, torque_var)
    once = [first]
    segments = {bias: (segment, st)}

    def stats(b: bool) -> Any:
        """The statistics of a fit with (``b``) or without the bias."""
        if b not in segments and not (searched and bias and not b):
            return st
        if b not in segments:
            if 'without_bias' in rec:
                c = rec['without_bias']['chosen_s']
                seg0 = None if c == 'whole' else float(c)
            else:
                seg0, rec['without_bias'] = _choose_segment(
                    eq, ts, tau_end, gyro_var, torque_var, False, None, known)
            s0 = st if seg0 == segment else (
                known.get(seg0) if len(eq.t) <= _SELECT_MAX_ROWS else None)   # (not a head's)
            known.clear()
            segments[b] = (seg0, s0 if s0 is not None else sufficient_stats(
                eq, seg0, ts, tau_end, torque_var))
        return segments[b][1]

    def fit(basis: np.ndarray, bias: bool, offset: np.ndarray | None = None,
            theta0: np.ndarray | None = None, inertial: bool = False) -> Fit:
        """Fit one parameter set on the statistics (weights from ``theta0`` when given)."""
        f = once[0]
        if (f is not None and offset is None and theta0 is None and bias == f.bias
                and inertial == f.inertial and np.array_equal(basis, np.eye(6))):
            once[0] = None
            return f
        return fit_two_pass(stats(bias), basis, bias, gyro_var, torque_var, offset, theta0,
                            inertial=inertial)
    return segments, fit


def _equation_rules(eq: Equations, method: str, diag: dict[str, Any],
                    base: dict[str, Any]) -> InertiaEstimate | None:
    """The result when the equations cannot give a fair fit (noisy regressor, too few)."""
    share = eq.info.get('regressor_noise_share')
    if share is not None and float(np.max(share)) > _EIV_MAX_SHARE:
        diag['reason'] = (
            f'errors in variables: gyro noise is {100 * float(np.max(share)):.3g} % of the '
            f'differentiated gyro (limit {100 * _EIV_MAX_SHARE:g} %), which biases the '
            f'{method} fit towards zero by about as much; use the integral or ml method '
            '(no differentiation)' + (', or a longer window' if method == 'differential_sg'
                                      else ''))
        return status_only('insufficient_excitation', diag, base)
    if len(eq.t) < MIN_EQUATIONS:
        diag['reason'] = f'{len(eq.t)} equations are too few for the parameters'
        return status_only('insufficient_data', diag, base)
    return None


def _choose_segment(eq: Equations, ts: np.ndarray, tau_end: float, gyro_var: np.ndarray,
                    torque_var: np.ndarray, bias: bool,
                    tried: dict[Any, tuple[Any, Fit]] | None = None,
                    known: dict[Any, Any] | None = None
                    ) -> tuple[float | None, dict[str, Any]]:
    """Anchored-segment length that minimises the predicted relative variance of the tensor.

    Short segments lose the information in slow motion and leave more errors-in-variables
    bias; long ones let the integrated torque noise (a random walk) grow.  The candidates are
    evaluated with the calibrated covariance of the full model; all candidates share the raw
    statistics (see :func:`.statistics.sufficient_stats`), so the search costs little.  Long
    records are searched on their first ``_SELECT_MAX_ROWS`` equations (the optimum depends on
    the dynamics, not on the record length).  ``tried`` receives every candidate's statistics
    and general-model fit (``{segment: (stats, fit)}``) when the whole record was searched;
    ``known`` (``{segment: stats}`` of the searched part) keeps the candidates' statistics
    for another search of the same equations (the length without the bias).
    """
    if len(eq.t) > _SELECT_MAX_ROWS:
        sub = eq.head(_SELECT_MAX_ROWS)
        ts = ts[:max(int(np.searchsorted(ts, sub.t[-1], side='right')), 2)]
        tau_end = max(float(sub.t[-1]), float(ts[-1]))
    else:
        sub = eq
    span = float(sub.t[-1] - sub.t[0])
    cands: list[float | None] = [s for s in _SEGMENT_CANDIDATES if s < 0.75 * span]
    cands.append(None)
    scores: dict[str, float] = {}
    best, best_score = None, np.inf
    for cand in cands:
        st = None if known is None else known.get(cand)
        if st is None:
            st = sufficient_stats(sub, cand, ts, tau_end, torque_var)
            if known is not None:
                known[cand] = st
        if st.n_eff < 3 * (6 + 3):
            continue
        # the general model: the bias, and the inertial torque when its columns are built
        f = fit_two_pass(st, np.eye(6), bias, gyro_var, torque_var, inertial=sub.V.shape[1] > 13)
        if tried is not None and sub is eq:
            tried[cand] = (st, f)
        scale = float(np.mean(np.abs(f.beta[:3])))
        score = float(np.trace(f.cov[:6, :6])) / scale ** 2 if scale > 0 else np.inf
        scores['whole' if cand is None else f'{cand:g}'] = score
        if score < best_score:
            best, best_score = cand, score
    if best is None and sub is not eq:
        best = span                     # 'whole' of the searched part, not of the record
    return best, {'candidates_s': scores, 'chosen_s': 'whole' if best is None else best,
                  'rule': 'minimum predicted relative variance of theta'}


def _homogeneous(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                 mask: np.ndarray, breaks: np.ndarray, hold: str, gyro_var: np.ndarray,
                 segment: float | None, window: float | None, diag: dict[str, Any],
                 base: dict[str, Any], policy: SelectionPolicy) -> InertiaEstimate:
    """Torque-free data: ratios and axes from the null vector of the homogeneous problem,
    with the adequacy tests and the stated calibration (:func:`.torque_free_checked`)."""
    if len(ts) == 0:
        ts = np.array([tg[0], tg[-1]])
        tau = np.zeros((2, 3))
    meth = method if method != 'integral_ls' else 'integral'
    eq = equations_for(meth, tg, w, ts, tau, mask, breaks, hold, gyro_var, window)
    return torque_free_checked(eq, tg[mask], w[mask], segment, gyro_var, diag, base,
                               policy.gyro_scale_std, policy.torque_scale_std)


def _refine(first: InertiaEstimate, tg: np.ndarray, w: np.ndarray, ts: np.ndarray,
            tau: np.ndarray, hold: str, axis: np.ndarray | None) -> InertiaEstimate:
    """The ``ml`` result from the ``integral`` one (that one, reasoned, when not refined)."""
    diag = dict(first.diagnostics)
    diag['warnings'] = list(diag.get('warnings', []))
    info: dict[str, Any] = {'refined': False, 'start': 'integral'}
    diag['ml'] = info

    def keep(reason: str) -> InertiaEstimate:
        # the method name says what ran: the integral estimate, not a likelihood one
        info['reason'] = reason + '; the integral estimate is reported'
        return replace(first, method='integral', diagnostics=diag)

    if model_parts(first.model)[2]:
        return keep('the integral stage kept a torque fixed in inertial axes, which the '
                    'likelihood model does not have yet')
    if hold != 'zoh':
        return keep("the likelihood model holds each torque sample (hold='zoh' only)")
    if first.status != 'ok' or first.inertia is None:
        return keep(f'the starting estimate is {first.status!r}, only ok estimates are refined')
    if any('torque gap' in str(m) for m in diag['warnings']):
        return keep('torque gaps: the held-torque model does not cover them')
    t0 = float(min(tg[0], ts[0]))
    tg, ts = tg - t0, ts - t0
    # the gyro samples the integral stage used: inside the held torque's coverage
    inside = (tg >= ts[0]) & (tg <= ts[-1] + median(np.diff(ts)))
    name = model_parts(first.model)[0]
    basis = model_basis(name, axis)
    theta0 = first.theta
    assert theta0 is not None
    from .ml import refine  # lazily: the integral path (long logs) never needs it

    res = refine(tg[inside], w[inside], ts, tau, theta0, basis,
                 None if first.torque_bias is None else np.asarray(first.torque_bias),
                 np.asarray(diag['gyro_noise_std']), np.asarray(diag['torque_noise_std']))
    info.update(iterations=res.iterations, steps_in_std=res.steps, residual_excess=res.excess)
    if not res.converged:
        return keep(f'the refinement did not converge ({res.reason})')
    if res.excess > MAX_RESIDUAL_EXCESS:
        # the likelihood model does not explain the data although the integral tests passed:
        # its Fisher-information sigma would not be honest
        return keep(f'likelihood residuals are {res.excess:.3g} times the noise model (limit '
                    f'{MAX_RESIDUAL_EXCESS:g})')
    k = basis.shape[1]
    theta = basis @ res.beta
    # the widening the adequacy tests gave the integral sigma (over the noise model) holds
    # for the likelihood's too: its model is the same
    rcov = res.cov * float(diag.get('adequacy', {}).get('sigma_widened_by', 1.0)) ** 2
    cov6 = basis @ rcov[:k, :k] @ basis.T
    calib = diag.get('calibration')
    if calib is not None:                   # the stated scale uncertainties, as for integral
        cov6 = cov6 + basis @ np.asarray(calib['covariance_added'])[:k, :k] @ basis.T
    # elements a test held keep the full fit's covariance, as for integral
    held = (diag.get('model_selection') or {}).get('held_covariance_added')
    held = np.zeros((6 + len(rcov) - k, 6 + len(rcov) - k)) if held is None else held
    cov6 = cov6 + np.asarray(held)[:6, :6]
    I = theta_to_matrix(theta, check_finite=False)
    chk = check_physical(I)
    if not chk.valid:
        return keep('the refined tensor is not physical (' + '; '.join(chk.failures) + ')')
    info['refined'] = True
    moments, axes = principal_with_std(I, cov6, diag)
    diag['physical'] = {'valid': True, 'projected': False}
    if res.bias is not None:
        diag['torque_bias_std'] = np.sqrt(np.maximum(np.diag(rcov)[k:k + 3]
                                                     + np.diag(np.asarray(held))[6:], 0.0))
    # the ratios' sigma from the refined covariance too (it kept the integral stage's)
    r_se = theta_to_matrix(np.sqrt(np.maximum(np.diag(ratio_cov(theta, cov6)), 0.0)),
                           check_finite=False)
    return replace(first, method='ml', inertia=I, covariance=0.5 * (cov6 + cov6.T),
                   inertia_std=theta_to_matrix(np.sqrt(np.maximum(np.diag(cov6), 0.0)),
                                               check_finite=False),
                   ratios_std=np.where(np.isnan(first.ratios_std), np.nan, r_se)
                   if first.ratios_std is not None else None,
                   principal_moments=moments, principal_axes=axes, ratios=I / np.trace(I),
                   torque_bias=res.bias, diagnostics=diag)
