"""Torque-free data: the inertia ratios and principal axes (the scale is unobservable).

With no torque Euler's equations are homogeneous in ``theta``: any multiple of the tensor
explains the motion.  :func:`is_torque_free` is the one rule that declares a record
torque-free (batch and online); :func:`homogeneous_estimate` fits the ratios
``inertia / trace`` under ``trace = 1`` from the same statistics as the torque-driven fits;
:func:`torque_free_stats` builds those statistics for a batch record.

The covariance carries the same noise model as the torque-driven fits: the white gyro noise
of each equation and the random walk that the integrated gyroscopic term ``int w x (I w)``
makes of the gyro noise (:func:`.noise.gyroscopic_walk_cov`).  With no torque stream that
walk is held over the gyro intervals.  Without it the ratios' sigma was about half their
scatter on fast tosses (12 rad/s, 1.5 s: RMS z 1.9; 5 s: up to 2.6 and 16 for an axis),
since at ``|w| dt`` of order 0.1 the walk's share of the equation error is comparable to
the white part and, being correlated in time, it does not average out.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from ..tensor import THETA_NAMES, check_physical, nearest_physical, principal_axes, theta_to_matrix
from .equations import Equations
from .fit import fit_two_pass
from .model import TRACE, TRACE_FREE, describe_direction
from .options import TORQUE_FREE_SIGMAS
from .regressors import MOMENTUM_BASIS, metric
from .result import InertiaEstimate
from .statistics import SufficientStats, sufficient_stats
from .uncertainty import axis_std, moment_std

__all__ = ['homogeneous_estimate', 'is_torque_free', 'torque_free_stats']


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


def torque_free_stats(eq: Equations, omega: np.ndarray, segment: float | None) -> SufficientStats:
    """Statistics of torque-free equations, with the gyroscopic noise walk of the covariance.

    The walk (:func:`.noise.gyroscopic_walk_cov`) needs the motion's second moment and the
    sums of the regressors after each step of the walk (``CP`` of
    :class:`~.statistics.SufficientStats`); with no torque stream the steps are the gyro
    intervals of the equations.  Equations of another kind (``hac``) get plain statistics.

    Parameters
    ----------
    eq : Equations
        Equations of a torque-free record (``motion`` is set here).
    omega : ndarray, shape (N, 3)
        The used gyro samples [rad/s].
    segment : float, optional
        Segment length [s] of the anchored equations.

    Returns
    -------
    SufficientStats
    """
    t = eq.t
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    eq.motion = (omega.T @ omega / max(len(omega), 1), dt)
    if eq.kind != 'anchored' or len(t) < 2:
        return sufficient_stats(eq, segment, t[:1], float(t[-1]) if len(t) else 0.0,
                                np.zeros(3))
    # walk steps at the equations' stamps; the unit "torque variance" only asks for the
    # walk's statistics (the fit is given zero torque noise: the walk is all gyroscopic)
    return sufficient_stats(eq, segment, t, float(t[-1]), np.ones(3))


def homogeneous_estimate(st: SufficientStats, gyro_var: np.ndarray, diag: dict[str, Any],
                         base: dict[str, Any], cov_scale: float = 1.0) -> InertiaEstimate:
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

    Returns
    -------
    InertiaEstimate
        ``scale_unobservable`` with ``ratios``, ``ratios_std`` and ``principal_axes`` (and
        ``principal_ratios`` with their std in the diagnostics), or
        ``insufficient_excitation`` when the motion does not single out the ratios.
    """
    C = st.C.copy()
    C[:, :, 9, :] = 0.0                  # the (integrated) torque column: noise only here
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
    st = replace(st, C=C, CP=CP, A=A)
    eiv_var = st.eiv_var
    n_eff = st.n_eff
    H0 = metric(C, np.eye(3))[:6, :6]
    H = H0.copy()
    if eiv_var is not None:
        H -= n_eff * np.einsum('c,crk,csl->kl', eiv_var, MOMENTUM_BASIS, MOMENTUM_BASIS)
    d = np.sqrt(np.diag(H0))
    diag['reason'] = 'no torque excitation: only ratios and principal axes are observable'
    if np.any(d == 0):
        diag['reason'] = 'torque-free data without rotation about every axis'
        return InertiaEstimate(status='insufficient_excitation', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    lam0 = np.linalg.eigvalsh(H0 / d[:, None] / d[None, :])
    _, vec = np.linalg.eigh(H / d[:, None] / d[None, :])
    gap = float(lam0[1] / max(lam0[0], 1e-300))
    diag['eigenvalue_gap'] = gap
    diag['condition_number'] = float(lam0[-1] / max(lam0[0], 1e-300))
    if gap < 10.0:
        diag['reason'] = ('torque-free data whose motion does not single out the inertia '
                          'ratios (e.g. a spin about a principal axis)')
        diag['weakest_direction'] = describe_direction(vec[:, 1] / d, list(THETA_NAMES))
        return InertiaEstimate(status='insufficient_excitation', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    return _ratios(st, gyro_var, diag, base, cov_scale)


def _ratios(st: SufficientStats, gyro_var: np.ndarray, diag: dict[str, Any],
            base: dict[str, Any], cov_scale: float) -> InertiaEstimate:
    """The ``scale_unobservable`` result: ``theta`` fitted under ``trace = 1`` (torque column
    of ``st`` already dropped), projected onto a physical tensor when needed."""
    offset = TRACE / 3.0
    f = fit_two_pass(st, TRACE_FREE, False, gyro_var, np.zeros(3), offset)
    theta = TRACE_FREE @ f.beta + offset
    cov6 = cov_scale * (TRACE_FREE @ f.cov @ TRACE_FREE.T)
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
    return InertiaEstimate(status='scale_unobservable', ratios=R, ratios_std=ratios_std,
                           principal_axes=axes, identifiable=dict.fromkeys(THETA_NAMES, False),
                           model='homogeneous', diagnostics=diag,
                           **base)   # type: ignore[arg-type]
