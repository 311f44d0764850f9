"""The anchored fit refitted on other views of the same equations: the batch's checks.

:func:`window_adequacy` (time windows and shorter segments: the adequacy tests of
:mod:`.adequacy`), :func:`shift_test` (the segment-shift test on segments 4x shorter),
:func:`bias_split_test` (one torque bias over the record's quarters) and
:func:`gyro_sensitivity` (the fit's derivative with respect to a gyro scale).  Each works on
the sufficient statistics of :mod:`.statistics` and the two-pass fit of :mod:`.fit`; none
rebuilds equations from the data.
"""
from __future__ import annotations

import numpy as np

from .adequacy import Adequacy, bias_split, check_adequacy, segment_shift
from .equations import Equations
from .fit import Fit, fit_two_pass
from .options import ADEQUACY_MIN_WINDOW_S, ADEQUACY_WINDOWS, MIN_EQUATIONS
from .statistics import sufficient_stats, window_raw

__all__ = ['bias_split_test', 'gyro_sensitivity', 'shift_test', 'window_adequacy']


def gyro_sensitivity(eq: Equations, segment: float | None, ts: np.ndarray, tau_end: float,
                      gyro_var: np.ndarray, torque_var: np.ndarray, f: Fit,
                      step: float = 1e-4) -> np.ndarray | None:
    """``d beta / d g`` by refitting the equations of a gyro read ``1 + step`` times larger.

    The 13 variables scale exactly: ``w`` by ``1 + g``, the squared-rate integrals ``m`` by
    ``(1 + g)^2``, time and torque not at all, so the scaled statistics need no new data.
    (The inertial torque's attitude integral is not a power of the scale: kept as measured,
    a first-order approximation; see notes/space_fixed_design.md, refits.)
    ``None`` for equations that are not anchored (the caller then uses a bound).
    """
    if eq.kind != 'anchored':
        return None
    k = f.basis.shape[1]
    theta0 = f.basis @ f.beta[:k] + (0.0 if f.offset is None else f.offset)
    scaled = eq.rows(0, len(eq.t))
    scaled.V[:, :3] *= 1.0 + step
    scaled.V[:, 3:9] *= (1.0 + step) ** 2
    betas = [fit_two_pass(sufficient_stats(e, segment, ts, tau_end, torque_var), f.basis,
                          f.bias, gyro_var, torque_var, f.offset, theta0,
                          inertial=f.inertial).beta
             for e in (eq, scaled)]
    return (betas[1] - betas[0]) / step


def window_adequacy(eq: Equations, segment: float | None, ts: np.ndarray, tau_end: float,
                     gyro_var: np.ndarray, torque_var: np.ndarray, f: Fit,
                     own: bool = True) -> Adequacy:
    """Refit ``f``'s parameter set on time windows and on shorter segments; test both.

    Up to :data:`ADEQUACY_WINDOWS` windows of at least :data:`ADEQUACY_MIN_WINDOW_S` each,
    weighted as the final fit (its tensor gives the weights), each with its own anchored
    segments and torque-noise statistics; and the whole record refitted with anchored
    segments a quarter of ``segment`` (:func:`shift_test`), which needs no room for windows;
    too short for windows, a fitted torque bias is tested per quarter (:func:`bias_split_test`).
    Neither runs with a momentum input's equations.
    """
    p = len(f.beta)
    empty = np.zeros((0, p)), np.zeros((0, p, p)), np.zeros(0)
    # a torque stream's equations only: with a wheel or rotor momentum input (white noise in
    # y from the speeds) the shorter fit's covariance misses the speeds' lagged, correlated
    # errors, and the test cried wolf on correct rotor records (chi2 36/6 at 1.5 % error,
    # RMS z 0.78, test_capability_matrix rotors seed 2); there the window test decides
    own = own and eq.white_y_cov is None       # (the bias split too: the same covariances)
    shift = shift_test(eq, segment, ts, tau_end, gyro_var, torque_var, f) if own else None
    span = float(eq.t[-1] - eq.t[0])
    n_win = min(ADEQUACY_WINDOWS, int(span // ADEQUACY_MIN_WINDOW_S))
    if eq.kind != 'anchored' or n_win < 2 or len(ts) < 2:
        # too short for windows: a torque bias the fit found must hold over the record
        split = bias_split_test(eq, segment, ts, gyro_var, torque_var, f) \
            if own and (f.bias or f.inertial) and len(ts) >= 2 else None
        return check_adequacy(*empty, f.excess, shift=shift, split=split)
    # the inertial torque held at the fit's value only where the fit is of these equations
    # (a sliding, differential or filtered fit's disturbances are not the integral
    # equations' ones: its bias held, a single-axis filtered record's windows disagreed at
    # p 1e-276)
    fits, mids = _window_fits(eq, segment, ts, gyro_var, torque_var, f, n_win, f.bias,
                              hold_inertial=own)
    if len(fits) < 2:
        return check_adequacy(*empty, f.excess, shift=shift)
    return check_adequacy(np.array([fk.beta for fk in fits]), np.array([fk.cov for fk in fits]),
                          np.array(mids), f.excess, shift=shift)


def _window_fits(eq: Equations, segment: float | None, ts: np.ndarray, gyro_var: np.ndarray,
                 torque_var: np.ndarray, f: Fit, n_win: int, bias: bool,
                 noise_at_f: bool = False, hold_inertial: bool = False
                 ) -> tuple[list[Fit], list[float]]:
    """``f``'s parameter set (with the bias if ``bias``) fitted on ``n_win`` equal time windows.

    Weighted as ``f`` (its tensor gives the weights), each window with its own anchored
    segments and torque-noise statistics; windows with too few equations are left out.  With
    ``noise_at_f`` (the bias split's pieces) each window's noise model is evaluated at
    ``f``'s tensor too (:func:`.fit.fit_weighted`'s ``noise_theta``).  With
    ``hold_inertial`` (the window test) ``f``'s torque fixed in inertial axes is held at its
    value in every window: constant over the record under the model, it is not what the
    windows compare, and fitted per window beside a weakly excited tensor (one torqued
    axis: the others known only through the gyroscopic coupling) it made short windows'
    estimates disagree far beyond their sigmas on records the model explains (peer-like
    single-axis sines, 20 s: 10 of 20 ``model_mismatch`` at |z| < 1; held, 1).  The torque
    bias stays fitted per window: a gyro bias, whose effect follows the motion, shows as
    windows' biases that differ (held too, continuous torque with a 0.01 rad/s gyro bias,
    30 s: 5 of 10 ``model_mismatch`` instead of 9, the others ok only widened).
    Returns the fits and the windows' mid-times [s].
    """
    theta0 = f.basis @ f.beta[:f.basis.shape[1]]
    held = f.beta[f.inertial_at] if hold_inertial and f.inertial else None
    cuts = np.searchsorted(eq.t, np.linspace(eq.t[0], eq.t[-1], n_win + 1)[1:-1])
    bounds = [0, *cuts.tolist(), len(eq.t)]
    fits, mids = [], []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        if b - a < MIN_EQUATIONS:
            continue
        # the window's statistics from the whole fit's (its Gram and torque sums)
        sub, (j0, j1) = window_raw(eq, a, b, ts, torque_var)
        tsk = ts[j0:j1]
        if len(tsk) < 2:
            continue
        st = sufficient_stats(sub, segment, tsk, float(sub.t[-1]), torque_var)
        if st.n_eff < MIN_EQUATIONS:
            continue
        fits.append(fit_two_pass(st, f.basis, bias, gyro_var, torque_var, None, theta0,
                                 theta0 if noise_at_f else None,
                                 inertial=f.inertial and held is None, held=held))
        mids.append(0.5 * float(sub.t[0] + sub.t[-1]))
    return fits, mids


def bias_split_test(eq: Equations, segment: float | None, ts: np.ndarray, gyro_var: np.ndarray,
                    torque_var: np.ndarray, f: Fit, pieces: int = 4
                    ) -> tuple[float, int, float, int] | None:
    """Wald test that one constant torque bias serves the whole record (the tensor shared).

    The record is cut into ``pieces`` time pieces, each fitted with ``f``'s parameter set and
    a torque bias; :func:`.adequacy.bias_split` tests them (one tensor, a bias each).  Under
    the model the biases agree; a slow unmodelled torque (fixed in space while the body
    turns) or a gyro bias (whose effect follows the motion) makes them differ, on records too
    short for the window test.  ``None`` when fewer than two pieces could be fitted.
    """
    if eq.kind != 'anchored':
        return None
    fits = _window_fits(eq, segment, ts, gyro_var, torque_var, f, pieces, f.bias, True)[0]
    if len(fits) < 2:
        return None
    return bias_split(fits, f.basis.shape[1])


def shift_test(eq: Equations, segment: float | None, ts: np.ndarray, tau_end: float,
                   gyro_var: np.ndarray, torque_var: np.ndarray, f: Fit
                   ) -> tuple[float, int, float, float] | None:
    """:func:`.adequacy.segment_shift` of ``f`` against the same fit on segments 4x shorter.

    Both covariances are the noise model's (``f``'s excess inflation taken out).  ``None``
    when the equations are not anchored or the shorter fit has too few equations.
    """
    if eq.kind != 'anchored':
        return None
    span = float(eq.t[-1] - eq.t[0])
    st = sufficient_stats(eq, (segment or span) / 4.0, ts, tau_end, torque_var)
    if st.n_eff < MIN_EQUATIONS:
        return None
    k = f.basis.shape[1]
    theta0 = f.basis @ f.beta[:k] + (0.0 if f.offset is None else f.offset)
    fs = fit_two_pass(st, f.basis, f.bias, gyro_var, torque_var, f.offset, theta0,
                      inertial=f.inertial)
    return segment_shift(f.beta[:k], f.cov[:k, :k] / max(f.excess, 1.0), fs.beta[:k],
                         fs.cov[:k, :k] / max(fs.excess, 1.0))
