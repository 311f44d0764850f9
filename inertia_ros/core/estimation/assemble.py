"""From fits to the result: identifiability, model choice, status and the estimate.

:func:`conclude` runs the rules of :mod:`.selection` on a ``fit`` function (fixed statistics,
any parameter set) and returns the :class:`InertiaEstimate` with its status:

``insufficient_excitation``
    no principal-diagonal element is determined;
``partially_identifiable``
    some elements are not: they are reported NaN (held at a plausible value while the rest is
    estimated, with the covariance that costs);
``ok``
    every element: the bias and the parameter set chosen by Wald tests, then :func:`assemble`
    (principal moments and axes with their std, ratios, physical projection);
``model_mismatch``
    as ``ok``, but the model-adequacy tests (:mod:`.adequacy`, through the ``adequacy``
    callable) say the model does not explain the data: the covariance is inflated by what
    the tests saw and the reason names the likely cause.

Used by the batch estimator and the recursive one alike.
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np

from ..tensor import THETA_NAMES, check_physical, nearest_physical, theta_to_matrix
from .adequacy import Adequacy, widening_weight
from .fit import Fit
from .model import model_basis, model_name, parameter_names
from .options import MIN_RESIDUAL_EXCESS
from .result import InertiaEstimate
from .selection import (
    FitFunction,
    SelectionPolicy,
    bias_test,
    conditioning,
    dropped_bias_cov,
    held_by_test,
    held_leak,
    identifiable,
    select_bias,
    select_disturbance,
    select_model,
    undetermined,
)
from .uncertainty import principal_with_std, ratio_cov

__all__ = ['assemble', 'conclude', 'status_only']

_NONE_DETERMINED = 'no principal-diagonal element is determined by the data'
#: The frame of ``InertiaEstimate.inertial_torque`` in words (``diagnostics.disturbance``).
INERTIAL_FRAME = 'body axes at the first gyro sample of the epoch (the first one used)'


def _matrix(theta: np.ndarray) -> np.ndarray:
    """theta (6,) -> (3, 3) letting NaN through (unidentified elements)."""
    return theta_to_matrix(theta, check_finite=False)


def status_only(status: str, diag: dict[str, Any], base: dict[str, Any]) -> InertiaEstimate:
    """A result without a tensor (``insufficient_*``): the status, its diagnostics and counts."""
    return InertiaEstimate(status=status, diagnostics=diag, **base)   # type: ignore[arg-type]


def _hold_undetermined(fit: FitFunction, f: Fit, und: np.ndarray, bias: bool,
                       diag: dict[str, Any]) -> Fit:
    """Refit with the undetermined elements held at a plausible value.

    The held moments take the mean determined moment, the held products zero, so that the
    weights and the other elements see a physical tensor (two passes).
    """
    free = ~und
    det = [abs(float(f.beta[i])) for i in range(3) if free[i]]
    hold = float(np.median(det))
    offset = np.zeros(6)
    for _ in range(2):
        offset = np.zeros(6)
        offset[:3][und[:3]] = hold
        f = fit(np.eye(6)[:, free], bias, offset)
        theta_f = np.eye(6)[:, free] @ f.beta[:int(np.sum(free))]
        hold = float(np.mean([abs(theta_f[i]) for i in range(3) if free[i]]))
    diag['undetermined_held_at'] = dict(zip(
        [n for n, u in zip(THETA_NAMES, und, strict=True) if u], offset[und], strict=True))
    return f


def _without_inseparable_bias(fit: FitFunction, f: Fit, und: np.ndarray, diag: dict[str, Any]
                              ) -> tuple[Fit, np.ndarray, bool, str]:
    """Drop the bias when it is what leaves elements undetermined (``torque_bias='auto'``).

    A constant known torque cannot be told from a constant disturbance: ``(1 + c) I`` with
    ``d = c tau`` fits as well as ``I`` with ``d = 0``, so the scale is lost with the bias and
    found without it.  Then the bias is left out, with a warning, instead of refusing.
    Returns the fit, the undetermined mask, whether the bias stays and the bias setting.
    """
    f0 = fit(np.eye(6), False)
    und0 = undetermined(f0)
    if int(np.sum(und0)) >= int(np.sum(und)):
        return f, und, True, 'auto'
    diag['warnings'].append(
        'a constant disturbance torque cannot be told apart from the known torque here (it '
        'does not vary enough): estimated without the torque bias; if a disturbance is '
        'present the tensor scale absorbs it')
    diag['bias_inseparable'] = True
    return f0, und0, False, 'off'


def _scale(f: Fit, free: np.ndarray) -> float | None:
    """The tensor scale: the largest principal-diagonal element determined to 20 %, or None."""
    k = int(np.sum(free))
    basis = np.eye(6)[:, free]
    theta = basis @ f.beta[:k]
    se = basis @ np.sqrt(np.maximum(np.diag(f.cov)[:k], 0.0))
    good = [float(theta[i]) for i in range(3)
            if free[i] and theta[i] > 0 and se[i] < 0.2 * theta[i]]
    return max(good) if good else None


def _partial(fit: FitFunction, f: Fit, free: np.ndarray, scale: float, torque_bias: str,
             bias: bool, alpha: float, diag: dict[str, Any]) -> Fit:
    """The fit of a partially identifiable tensor: the bias kept only if a Wald test says so."""
    if torque_bias == 'auto' and bias:
        test = bias_test(f, alpha)
        diag['model_selection'] = {'bias': test}
        if test['p_value'] >= alpha:
            held = f.offset if f.offset is not None else np.zeros(6)
            f = fit(np.eye(6)[:, free], False, held)
            f.cov = f.cov + held_leak(f, free, scale)
    return f


def _select(fit: FitFunction, f: Fit, model: str, torque_bias: str, axis: np.ndarray | None,
            policy: SelectionPolicy, diag: dict[str, Any], by_test: bool = False
            ) -> tuple[Fit, str, np.ndarray | None]:
    """Bias first (a Wald test at ``policy.alpha``), then the parameter set (the MSE test at
    ``policy.model_alpha``, :func:`.selection.select_model`); returns the final fit,
    the model's name and, for a restricted model a test chose (``model='auto'``, or
    ``by_test``: an earlier test's choice reused), the covariance its held elements add
    (:func:`.selection.held_by_test`; ``None``: a model the user stated holds them exactly),
    with that of a bias dropped on a suspect test (:func:`.selection.dropped_bias_cov`)."""
    selection: dict[str, Any] = {}
    bias_on = torque_bias == 'on'
    dropped = None
    if torque_bias == 'auto':
        with_bias = f
        f, bias_on, selection['bias'] = select_bias(fit, f, policy.alpha)
        weight = 0.0 if bias_on else widening_weight(selection['bias']['p_value'])
        if weight > 0.0:
            dropped = dropped_bias_cov(f, with_bias, weight)
            selection['bias']['covariance_added_weight'] = weight
    chosen = model
    if model == 'auto':
        chosen, record = select_model(f, axis, policy.model_alpha)
        selection.update(record)
    held = None
    if chosen != 'full':
        theta0 = f.basis @ f.beta[:6]
        basis = model_basis(chosen, axis)
        full, f = f, fit(basis, bias_on, theta0=theta0)
        if model == 'auto' or by_test:
            held = held_by_test(f, full)
            selection.update(held_sigma_from='full fit', held_covariance_added=held)
    if dropped is not None:                    # (with the held elements', for ml too)
        held = dropped if held is None else held + dropped
        selection['held_covariance_added'] = held
    if selection:
        diag['model_selection'] = selection
    return f, chosen, held


#: ``adequacy(final_fit, model_name) -> Adequacy``: the model-adequacy tests of a final fit.
AdequacyFunction = Callable[[Fit, str], Adequacy]
#: ``gyro_sensitivity(final_fit) -> d beta / d g`` (p,): the fit's change per unit relative
#: gyro scale error (``None``: the bound ``-2 beta``, the gyroscopic term's exponent).
SensitivityFunction = Callable[[Fit], np.ndarray]


def conclude(fit: FitFunction, model: str, torque_bias: str, axis: np.ndarray | None,
             policy: SelectionPolicy, diag: dict[str, Any], base: dict[str, Any],
             adequacy: AdequacyFunction | None = None,
             gyro_sensitivity: SensitivityFunction | None = None,
             by_test: bool = False) -> InertiaEstimate:
    """Identifiability, model selection and the result, given ``fit(basis, bias) -> Fit``.

    Parameters
    ----------
    fit : callable
        ``fit(basis (6, k), bias, offset=None, theta0=None) -> Fit`` on fixed statistics.
    model : {'auto', 'full', 'diagonal', 'axisymmetric'}
        Requested parameter set.
    torque_bias : {'auto', 'on', 'off'}
        Requested torque-bias handling.
    axis : ndarray, shape (3,), optional
        Unit symmetry axis.
    policy : SelectionPolicy
        Test level, identifiability tolerance, physical projection.
    diag, base : dict
        Diagnostics (updated in place) and the common result fields.
    adequacy : callable, optional
        ``adequacy(fit, model) -> Adequacy`` on the final fit of a fully identified tensor;
        a failed test gives ``model_mismatch`` (see the module docstring).
    gyro_sensitivity : callable, optional
        ``d beta / d g`` of the final fit for ``policy.gyro_scale_std`` (see
        :func:`add_calibration`).
    by_test : bool
        A restricted ``model`` is an earlier test's choice (reused), not the user's: its held
        elements keep the full fit's covariance as with ``model='auto'``.

    Returns
    -------
    InertiaEstimate
    """
    requested = torque_bias                 # (the inseparable bias: dropped if it was 'auto')
    if policy.inertial_torque != 'off':     # which disturbances, before anything else
        keep_b, keep_i, diag['disturbance'] = select_disturbance(
            fit, torque_bias, policy.inertial_torque, policy.alpha)
        diag['disturbance']['frame'] = INERTIAL_FRAME
        torque_bias = 'on' if keep_b else 'off'
        fit = functools.partial(fit, inertial=keep_i) if keep_i else fit
    gen_bias = torque_bias != 'off'
    # ---- identifiability on the general model
    f = fit(np.eye(6), gen_bias)
    und = undetermined(f)
    if requested == 'auto' and gen_bias and np.any(und):   # (kept: as selected)
        f, und, gen_bias, dropped = _without_inseparable_bias(fit, f, und, diag)
        torque_bias = torque_bias if gen_bias else dropped
    diag.update(conditioning(f, parameter_names(np.eye(6), gen_bias, 'full', f.inertial)))
    none_determined = dict(diag, reason=_NONE_DETERMINED)
    if not np.any(~und[:3]):
        return status_only('insufficient_excitation', none_determined, base)
    if np.any(und):
        f = _hold_undetermined(fit, f, und, gen_bias, diag)
    free = ~und
    scale = _scale(f, free)
    if scale is None:
        return status_only('insufficient_excitation', none_determined, base)
    if np.any(und):
        f.cov = f.cov + held_leak(f, free, scale)
    free = identifiable(f, free, scale, policy.identifiability_tol)
    if not np.any(free[:3]):
        diag['reason'] = _NONE_DETERMINED
        return status_only('insufficient_excitation', diag, base)
    if not np.all(free):
        f = _partial(fit, f, free, scale, torque_bias, gen_bias, policy.alpha, diag)
        return assemble('partially_identifiable', f, 'full', free, diag, base, physical=False)
    f, chosen, held = _select(fit, f, model, torque_bias, axis, policy, diag, by_test)
    status = 'ok' if adequacy is None else _adequate(adequacy, f, chosen, diag)
    add_calibration(f, policy, gyro_sensitivity, diag)
    return assemble(status, f, chosen, free, diag, base, physical=policy.physical, held=held)


def add_calibration(f: Fit, policy: SelectionPolicy, gyro_sensitivity: SensitivityFunction
                    | None, diag: dict[str, Any]) -> None:
    """Add the stated sensor-scale uncertainties to the fit's covariance (in place).

    The fit is linear in the torque, so a torque read ``(1 + s)`` times too large scales every
    parameter by ``1 + s``: ``cov += s_std^2 beta beta'``.  A gyro scale error ``g`` scales the
    momentum term by ``1 + g`` and the gyroscopic term by ``(1 + g)^2``; its effect
    ``d beta / d g`` comes from ``gyro_sensitivity`` (a refit of the scaled statistics) or,
    without one, the bound ``-2 beta``: ``cov += g_std^2 J J'``.  Both are recorded in
    ``diag['calibration']``.
    """
    ts, gs = policy.torque_scale_std, policy.gyro_scale_std
    if not (ts or gs):
        return
    add = ts ** 2 * np.outer(f.beta, f.beta)
    how = None
    if gs:
        J = gyro_sensitivity(f) if gyro_sensitivity is not None else None
        how = 'refit of the gyro-scaled statistics' if J is not None else 'bound -2 beta'
        J = -2.0 * f.beta if J is None else J
        add = add + gs ** 2 * np.outer(J, J)
    f.cov = f.cov + add
    diag['calibration'] = {'torque_scale_std': ts, 'gyro_scale_std': gs,
                           'gyro_sensitivity': how, 'covariance_added': add}


def _adequate(adequacy: AdequacyFunction, f: Fit, chosen: str, diag: dict[str, Any]) -> str:
    """Run the adequacy tests on the final fit: ``'ok'`` or ``'model_mismatch'``.

    What the tests saw widens the covariance by :func:`.adequacy.widening`'s factor (the fit's
    own excess inflation is not counted twice).  ``diag['adequacy']['sigma_widened_by']`` is
    the sigma over the noise model's (1: not widened).  When the widening covers what the
    tests saw (benign) the status stays ``ok`` and a warning says by how much and why;
    otherwise ``model_mismatch`` with the reason.
    """
    a = adequacy(f, chosen)
    rec = diag['adequacy'] = a.as_dict()
    if f.excess < MIN_RESIDUAL_EXCESS and not f.momentum_noise:
        # (a single-axis sine of 10 s, peer-like sine_x_0.005 seed 12: a bias and an inertial
        # torque beside two weakly excited moments, excess 0.12, ok at |z| 45); not with a
        # momentum input, whose noise model bounds the speeds' noise from above (correct
        # rotor fits: 0.28-0.96)
        rec['ok'] = False
        diag['reason'] = (f'the residuals are {f.excess:.2g} of what the noise model predicts '
                          f'(below {MIN_RESIDUAL_EXCESS:g}): the fit absorbs the noise, a '
                          'near-degenerate fit (too little excitation for its parameters) or '
                          'a noise level given too high; its sigma is not to be trusted')
        return 'model_mismatch'
    factor = max(1.0, a.inflation / max(f.excess, 1.0))
    # over the noise model's sigma (what the tests saw; a verdict the node may report one
    # estimate later, so not relative to the current fit's own excess inflation)
    rec['sigma_widened_by'] = float(np.sqrt(a.inflation))
    if factor == 1.0:
        rec['covariance'] = 'noise model' + (' x residual excess' if f.excess > 1.0 else '')
        if a.ok:
            return 'ok'
    else:
        f.cov = f.cov * factor
        rec['covariance'] = 'noise model x ' + _widened_by(a)
    if a.benign:
        diag['warnings'].append(
            f'sigma widened {np.sqrt(a.inflation):.3g}x by the ' + _widened_by(a) + ': '
            + (a.reason or _suspect(a)) + '; covered, the answer does not move beyond the '
            'widened sigma')
        return 'ok'
    diag['reason'] = 'the model does not explain the data: ' + a.reason
    return 'model_mismatch'


def _suspect(a: Adequacy) -> str:
    """What the tests saw when they widened the sigma (a chi2 above its dof) and none failed."""
    return (f'window p = {a.p_value:.1e}, segment shift p = {a.shift_p_value:.1e}, bias split '
            f'p = {a.split_p_value:.1e} (a small unmodelled effect or correlated noise)')


def _widened_by(a: Adequacy) -> str:
    """Which test's ratio set the widening (the largest)."""
    cands = {'window scatter (1 + K (B - 1), B the windows\' Birge ratio)':
             1.0 + a.windows * (a.chi2 / a.dof - 1.0) if a.dof > 0 else 0.0,
             'segment shift (chi2 per dof)': a.shift_chi2 / a.shift_dof if a.shift_dof > 0
             else 0.0,
             'bias split scatter (1 + K (B - 1), B its chi2 per dof)':
             a.split_widening if a.split_dof else 0.0,
             'residual excess': a.excess}
    return max(cands, key=lambda k: cands[k] if np.isfinite(cands[k]) else 0.0)


def assemble(status: str, f: Fit, model: str, free: np.ndarray, diag: dict[str, Any],
              base: dict[str, Any], physical: bool, held: np.ndarray | None = None
              ) -> InertiaEstimate:
    """Build the :class:`InertiaEstimate` from a fit of the elements in ``free``.

    Parameters
    ----------
    status : str
        ``'ok'`` or ``'partially_identifiable'``.
    f : Fit
        The final fit.
    model : str
        Its parameter set's name (``'+bias'`` is appended when the bias was fitted).
    free : ndarray of bool, shape (6,)
        Identifiable elements (the others are reported NaN).
    diag, base : dict
        Diagnostics (updated in place) and the common result fields.
    physical : bool
        Project an impossible tensor onto the nearest physical one.
    held : ndarray, shape (6 + b, 6 + b), optional
        Covariance added in ``[theta, d]`` coordinates by the elements a test held
        (:func:`.selection.held_by_test`).
    """
    k = f.basis.shape[1]
    theta = f.basis @ f.beta[:k]
    cov6 = f.basis @ f.cov[:k, :k] @ f.basis.T
    bias_var = np.diag(f.cov)[k:]                  # the bias, then the inertial torque
    if held is not None:
        cov6 = cov6 + held[:6, :6]
        bias_var = bias_var + np.diag(held)[6:]
    inertial = f.beta[f.inertial_at] if f.inertial else None
    if f.inertial:                                 # [d_i]; its std in the diagnostics
        diag['inertial_torque_std'] = np.sqrt(np.maximum(bias_var[-3:], 0.0))
        bias_var = bias_var[:-3]
    se = np.sqrt(np.maximum(np.diag(cov6), 0.0))
    theta = np.where(free, theta, np.nan)
    se = np.where(free, se, np.nan)
    I = _matrix(theta)
    I_std = _matrix(se)
    diag['residual_rms'] = f.resid_rms
    diag['residual_excess'] = f.excess
    if f.excess > 1.5:
        diag['warnings'].append(f'residuals are {f.excess:.3g} times the noise model: '
                                'standard errors inflated accordingly')
    diag['equations'] = f.n_eq
    moments = axes = ratios = None
    if np.all(free):
        chk = check_physical(I)
        if not chk.valid:
            diag['physical'] = {'valid': False, 'failures': list(chk.failures),
                                'projected': bool(physical)}
            if physical:
                I = nearest_physical(I, min_moment=1e-9 * float(np.max(np.abs(chk.moments))))
        else:
            diag['physical'] = {'valid': True, 'projected': False}
        moments, axes = principal_with_std(I, cov6, diag)
    else:
        undetermined = [n for n, ok in zip(THETA_NAMES, free, strict=True) if not ok]
        diag['undetermined'] = undetermined
        diag['reason'] = ('the excitation does not determine ' + ', '.join(undetermined)
                          + ' (reported as null)')
    ratios = I / np.trace(I)
    # undetermined products leave the other ratios defined; an undetermined moment, none
    r_se = np.sqrt(np.maximum(np.diag(ratio_cov(np.where(free, theta, 0.0), cov6)), 0.0))
    ratios_std = _matrix(np.where(free & bool(np.all(free[:3])), r_se, np.nan))
    bias = f.beta[k:k + 3] if f.bias else None
    if f.bias:
        diag['torque_bias_std'] = np.sqrt(np.maximum(bias_var, 0.0))
    name = model_name(model, f.bias, f.inertial)
    both = free[:, None] & free[None, :]
    return InertiaEstimate(status=status, inertia=I, inertia_std=I_std,
                           covariance=np.where(both, 0.5 * (cov6 + cov6.T), np.nan),
                           principal_moments=moments, principal_axes=axes, ratios=ratios,
                           ratios_std=ratios_std,
                           identifiable=dict(zip(THETA_NAMES, map(bool, free), strict=True)),
                           torque_bias=bias, inertial_torque=inertial, model=name,
                           diagnostics=diag,
                           **base)   # type: ignore[arg-type]
