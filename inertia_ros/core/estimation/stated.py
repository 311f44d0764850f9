"""Stated input uncertainties of a momentum input, profiled under their prior.

A stated uncertainty (a wheel's spin inertia, a rotor's ``k_f``, ``k_m`` or ``J``, the gyro
scale) is an unknown error ``u_j`` of one stated sigma per unit, ``u ~ N(0, 1)``.  Its effect on
the anchored equations is known to first order: the column ``c_j`` (n, 3) is the change of the
equation error ``X(w) theta - Y`` (``X`` the angular-momentum side, ``Y`` the known angular
impulse ``int tau - dh - int w x h``) for ``u_j = 1``: ``-dY/dp_j`` for an input of ``Y``; for
the gyro scale also the change of the measured rate in ``X`` and in ``w x h``.

:func:`profile_inputs` fits ``X theta + (d t) + C u = Y`` on anchored segments (the segment
intercepts removed by demeaning), the equations weighted per axis by the residual variance of
the fit without the prior, with the prior rows ``u`` appended: the posterior mean ``u_hat`` and
covariance ``cov_u``.  The caller corrects the inputs by ``u_hat`` (so the adequacy tests see
no residual the stated uncertainty explains) and adds ``D cov_u D'`` to the estimate's
covariance (``D`` its sensitivity to ``u``), which in the linear Gaussian model is exactly the
marginal covariance of the tensor: never smaller than with the inputs known exactly.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any

import numpy as np

from .align import cumtrapz, gap_starts
from .momentum import Momentum, Reduction
from .regressors import MOMENTUM_BASIS, cumulative_torque, momentum_matrix
from .uncertainty import widen

__all__ = ['Stated', 'intervals', 'lhs_columns', 'profile_inputs',
           'propagate', 'record_inputs', 'rerun', 'widened']

#: Rows the profile of the stated inputs needs (fewer: the inputs stay at their prior).
_MIN_PROFILE_ROWS = 20

_STEPS = 4                      # Gauss-Newton steps of the profile at most
_PER_UNKNOWN = 4                # intervals per unknown of the profile
_SMOOTH_S = 0.2                 # window of the smoothed input changes [s]
_MIN_INFORMATION = 4.0          # data information per prior information kept
_MIN_INTERVAL_S = 0.5           # shortest interval of the profile [s]
_DU = 0.1                       # finite-difference step of the columns [stated sigmas]
#: Rows per product of :func:`_tall_lstsq`: below this the BLAS keeps to one thread (a
#: least-squares solve of all the rows woke its threads, whose spinning cost more CPU than
#: the work on a loaded machine)
_ROWS = 4096
_MIN_EIGEN = 1e-10              # equilibrated normal equations' smallest relative eigenvalue


def lhs_columns(t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``d/d theta_j`` of ``I w(t) + int_0^t w x I w`` (n, 3, 6) [rad/s, rad] at the gyro
    stamps ``t`` (n,) [s] for the rates ``w`` (n, 3) [rad/s] (trapezoid)."""
    Iw = momentum_matrix(w)                                 # (n, 3, 6)
    gyro = np.cross(w[:, :, None], Iw, axisa=1, axisb=1, axisc=1)
    return Iw + cumtrapz(t, gyro)


def intervals(t: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Start and end indices (k,) of about ``count`` non-overlapping intervals of the stamps
    ``t`` (n,) [s] that share no sample (one skipped between them) and span no gap (the one
    gap rule, :func:`.align.gap_starts`): their equations have independent noise (white gyro
    noise at the ends, torque-noise walk increments inside)."""
    bad = np.zeros(len(t) - 1, dtype=bool)
    bad[gap_starts(t)] = True
    edges = np.linspace(0, len(t) - 1, max(count, 1) + 1).round().astype(int)
    a, b = edges[:-1] + (np.arange(len(edges) - 1) > 0), edges[1:]
    cum = np.r_[0, np.cumsum(bad)]
    keep = (b - a >= 2) & (cum[b] == cum[a])
    return a[keep], b[keep]


def _tall_lstsq(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares solution (k,) of the tall ``A x = y`` (``A`` (n, k), ``y`` (n,)) and its
    residual ``y - A x`` (n,), without waking the BLAS threads.

    The equilibrated normal equations, summed over blocks of :data:`_ROWS` rows, solved and
    refined once by the residual (semi-normal equations with a correction step: a QR
    solution's accuracy for a well-conditioned ``A``); ``np.linalg.lstsq`` when ``A`` is near
    rank-deficient (eigenvalue ratio below :data:`_MIN_EIGEN`).
    """
    n, k = A.shape
    G = np.zeros((k, k))
    for a in range(0, n, _ROWS):
        G += A[a:a + _ROWS].T @ A[a:a + _ROWS]
    d = np.sqrt(np.diag(G))
    Gs = G / np.outer(d, d) if np.all(d > 0) else np.zeros((k, k))
    lam = np.linalg.eigvalsh(Gs)
    if not lam[0] > _MIN_EIGEN * lam[-1]:
        x = np.linalg.lstsq(A, y, rcond=None)[0]
        return x, y - A @ x
    x, r = np.zeros(k), y.copy()
    for step in range(3):               # the solution, its correction, the final residual
        g = np.zeros(k)
        for a in range(0, n, _ROWS):
            if step:
                r[a:a + _ROWS] = y[a:a + _ROWS] - A[a:a + _ROWS] @ x
            if step < 2:
                g += A[a:a + _ROWS].T @ r[a:a + _ROWS]
        if step < 2:
            x = x + np.linalg.solve(Gs, g / d) / d
    return x, r


def _demean(a: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """``a`` (n, ...) minus its mean over each group of ``ids`` (n,)."""
    flat = a.reshape(len(a), -1)
    sums = np.zeros((ids.max() + 1, flat.shape[1]))
    np.add.at(sums, ids, flat)
    return (flat - (sums / np.bincount(ids)[:, None])[ids]).reshape(a.shape)


def _larger(M: np.ndarray, H: np.ndarray) -> np.ndarray:
    """The clustered meat ``M``, never below the white-noise one ``H`` along any direction
    (a few clusters can understate it): ``H^1/2 max(1, eig(H^-1/2 M H^-1/2)) H^1/2``."""
    lam, V = np.linalg.eigh(H)
    lam = np.maximum(lam, 1e-12 * max(float(lam.max()), 1e-300))
    R = V * np.sqrt(lam)
    Ri = V / np.sqrt(lam)
    mu, U = np.linalg.eigh(Ri.T @ M @ Ri)
    return R @ (U * np.maximum(mu, 1.0)) @ U.T @ R.T


def profile_inputs(t: np.ndarray, X: np.ndarray, y: np.ndarray, C: np.ndarray,
                   ends: tuple[np.ndarray, np.ndarray], bias: bool, u0: np.ndarray | None = None,
                   gyro_var: np.ndarray | None = None, scale_dir: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Posterior of the stated input errors ``u`` (q,) [stated sigmas] under ``N(0, 1)``.

    The equations are linearised at ``u0`` (q,) (default 0): ``y`` and ``C`` are taken there,
    and the unknown is the step ``u - u0`` (a Gauss-Newton step of the posterior).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Gyro stamps [s].
    X : ndarray, shape (n, 3, 6)
        Angular-momentum side per tensor element (:func:`lhs_columns`).
    y : ndarray, shape (n, 3)
        Known angular impulse [N m s].
    C : ndarray, shape (n, 3, q)
        Change of the equation error per stated sigma of each input [N m s].
    ends : (ndarray, ndarray) of int, shape (k,) each
        Start and end of each interval (:func:`intervals`): the equations are the changes
        over them.
    bias : bool
        A constant torque bias is fitted too.
    u0 : ndarray, shape (q,), optional
        The linearisation point [stated sigmas].
    gyro_var : ndarray, shape (3,), optional
        Gyro white-noise variance [rad^2/s^2]: its share of ``X' X`` (errors in variables,
        which would shrink the tensor and with it every input along the scale direction) is
        subtracted, as the estimator's own fit does.
    scale_dir : ndarray, shape (q,), optional
        The inputs' common scale (every stated coefficient moved in proportion, the known
        impulse scaled with the tensor): the data cannot determine it, and a least-squares
        fit would shrink it (its residual shrinks with it), so it keeps its prior.

    Returns
    -------
    u_hat : ndarray, shape (q,)
        Posterior mean [stated sigmas] (after the one step from ``u0``).
    cov_u : ndarray, shape (q, q)
        Posterior covariance (its diagonal <= 1).
    sigma : ndarray, shape (3,)
        Residual std per axis of the fit without the prior [N m s].
    """
    q = C.shape[2]
    cols = [X, C]
    if bias:
        cols.append(np.broadcast_to(np.eye(3)[None] * t[:, None, None], (len(t), 3, 3)))
    i, j = ends
    rows = np.concatenate([np.arange(a, b + 1) for a, b in zip(i, j, strict=True)])
    cl = np.repeat(np.arange(len(i)), j - i + 1)
    A = _demean(np.concatenate(cols, axis=2)[rows], cl)      # (N, 3, m): free intercepts
    b = _demean(y[rows], cl)
    m = A.shape[2]
    # residual variance per axis of the fit with the inputs at u0 (free, they could scale
    # the known impulse away with the tensor): the equations' noise scale
    keep = np.r_[0:6, 6 + q:m]
    r = _tall_lstsq(A[:, :, keep].reshape(-1, len(keep)), b.reshape(-1))[1].reshape(b.shape)
    dof = max(len(rows) - len(i) - len(keep) / 3.0, 1.0)
    sigma = np.sqrt(np.maximum(np.sum(r ** 2, axis=0) / dof, 1e-300))
    Aw = A / sigma[None, :, None]
    H = np.einsum('nai,naj->ij', Aw, Aw)
    if gyro_var is not None:          # E[(E_j n)(E_k n)'] on the demeaned rows, per axis
        H[:6, :6] -= (len(rows) - len(i)) * np.einsum(
            'c,crk,r,crl->kl', np.asarray(gyro_var, float), MOMENTUM_BASIS, sigma ** -2.0,
            MOMENTUM_BASIS)
    # the interval-clustered scores: residuals correlated within an interval (a torque-noise
    # walk, an interpolated momentum sample) count once per interval
    sc = np.zeros((len(i), m))
    np.add.at(sc, cl, np.einsum('nai,na->ni', Aw, r / sigma[None, :]))
    g = np.einsum('nai,na->i', Aw, b / sigma[None, :])
    u0 = np.zeros(q) if u0 is None else np.asarray(u0, dtype=float)
    step, cov = _posterior(H, g, sc, q, u0, scale_dir)
    return u0 + step, cov, sigma


def _posterior(H: np.ndarray, g: np.ndarray, sc: np.ndarray, q: int, u0: np.ndarray,
               scale_dir: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The step (q,) from ``u0`` and the posterior covariance (q, q) of ``u`` from the
    whitened information ``H`` (m, m), gradient ``g`` (m,) and interval scores ``sc``
    (k, m) of ``[theta (6), u (q), bias]``: the tensor and bias profiled out, the common
    scale ``scale_dir`` and every direction the data inform less than the prior left at
    the prior, the clustered scores' covariance (never below the model's) as the meat."""
    m = H.shape[0]
    # the tensor and the bias profiled out: the information, gradient and scores of u
    u_i = np.arange(6, 6 + q)
    n_i = np.setdiff1d(np.arange(m), u_i)
    K = np.linalg.pinv(H[np.ix_(n_i, n_i)], rcond=1e-12, hermitian=True) @ H[np.ix_(n_i, u_i)]
    Hu = H[np.ix_(u_i, u_i)] - H[np.ix_(u_i, n_i)] @ K
    gu = g[u_i] - K.T @ g[n_i]
    su = sc[:, u_i] - sc[:, n_i] @ K
    if scale_dir is not None:
        P = np.eye(q) - np.outer(scale_dir, scale_dir) / float(scale_dir @ scale_dir)
        Hu, gu, su = P @ Hu @ P, P @ gu, su @ P
    # directions the data inform less than the prior keep the prior: among them the common
    # scale of the inputs and the tensor, which a momentum-only input cannot determine (its
    # residual shrinks with the scale, a spurious pull the prior alone would not stop)
    lam, V = np.linalg.eigh(0.5 * (Hu + Hu.T))
    if not np.any(lam >= _MIN_INFORMATION):
        return -u0, np.eye(q)                                # the prior alone
    V = V[:, lam >= _MIN_INFORMATION]
    lam = lam[lam >= _MIN_INFORMATION]
    M = V.T @ su.T @ su @ V * len(sc) / max(len(sc) - 1, 1)
    Bi = V @ np.diag(1.0 / (lam + 1.0)) @ V.T + (np.eye(q) - V @ V.T)   # (Hu_kept + I)^-1
    step = Bi @ (V @ (V.T @ gu) - u0)                       # prior on u0 + step
    cov = Bi @ (V @ _larger(M, np.diag(lam)) @ V.T + np.eye(q)) @ Bi
    # data noisier than modelled add less, never a negative amount: at most the prior
    ev, U = np.linalg.eigh(0.5 * (cov + cov.T))
    return step, (U * np.minimum(ev, 1.0)) @ U.T


@dataclass(frozen=True)
class Stated:
    """A momentum input's data with its stated uncertainties.

    ``tg``, ``w`` (n,), (n, 3): the gyro samples inside the coverage [s], [rad/s]; ``ts``,
    ``tau``: the other torque [s], [N m]; ``mom``: the momentum input (its ``h_std`` and
    ``torque_std`` one-sigma changes); ``hold``: the other torque's hold; ``scale`` and
    ``gscale``: the stated relative torque-sensor and gyro scale sigmas (0: none).
    """

    tg: np.ndarray
    w: np.ndarray
    ts: np.ndarray
    tau: np.ndarray
    mom: Momentum
    hold: str
    scale: float = 0.0
    gscale: float = 0.0

    @property
    def names(self) -> list[str]:
        """The stated inputs, in the order of ``u``."""
        return (list(self.mom.names) + ['torque_scale'] * bool(self.scale)
                + ['gyro_scale'] * bool(self.gscale))

    def data(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                            np.ndarray]:
        """``(w, h, torque on the momentum stamps, other torque)`` with the stated inputs
        ``u`` (q,) sigmas off: the true rates of a gyro that reads ``1 + u g`` times high."""
        m, p = self.mom, len(self.mom.names)
        h = m.h + np.tensordot(u[:p], m.h_std, axes=1)
        tq = None if m.torque is None else m.torque + np.tensordot(u[:p], m.torque_std, axes=1)
        tau = self.tau * (1.0 + u[p] * self.scale) if self.scale else self.tau
        w = self.w / (1.0 + u[-1] * self.gscale) if self.gscale else self.w
        return w, h, tq, tau

    @cached_property
    def reduction(self) -> Reduction:
        """:func:`.momentum.equivalent_torque` on these stamps (grid and weights once)."""
        return Reduction(self.tg, self.mom.t, self.ts, self.hold)

    def torque(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rates (n, 3), grid (G,) and equivalent torque (G, 3) with the inputs ``u`` off."""
        w, h, tq, tau = self.data(u)
        grid, out, _ = self.reduction(w, h, tau, tq)
        return w, grid, out


def _profile(res: Any, st: Stated) -> tuple[np.ndarray, np.ndarray]:
    """:func:`profile_inputs` of the stated inputs around the estimate ``res``: the
    equation-error change per sigma of each input, at ``res.theta``."""
    q = len(st.names)
    t = st.tg - st.tg[0]
    theta = np.asarray(res.theta, dtype=float)
    lhs0 = lhs_columns(t, st.w)            # the rates as measured (all but the gyro scale's)
    momentum0 = lhs0 @ theta

    def lhs(w: np.ndarray) -> np.ndarray:
        return lhs0 if w is st.w else lhs_columns(t, w)

    def error(u: np.ndarray, src: Stated = st) -> np.ndarray:
        w, grid, tq = src.torque(u)
        return ((momentum0 if w is st.w else lhs(w) @ theta)
                - cumulative_torque(grid - st.tg[0], tq, t))

    u, cov = np.zeros(q), np.eye(q)
    if len(t) < _MIN_PROFILE_ROWS:
        return u, cov
    # the columns from smoothed changes: a change computed from the noisy speeds carries
    # the noise of y itself (errors in variables that would shrink every input)
    m = st.mom
    sm = replace(st, mom=replace(m, h_std=_smooth(m.t, m.h_std), torque_std=None
                                 if m.torque_std is None else _smooth(m.t, m.torque_std)))
    # intervals of at least _MIN_INTERVAL_S (the motion inside one must stand out of the gyro
    # noise), as many as the unknowns need when the record allows
    ends = intervals(t, min(max(_PER_UNKNOWN * (9 + q), 20), int(t[-1] / _MIN_INTERVAL_S),
                            len(t) // 10))
    gv = res.diagnostics.get('gyro_noise_std')
    gv = None if gv is None else np.asarray(gv, dtype=float) ** 2
    scale_dir = _scale_direction(st)
    # the known inputs' columns are exact (the impulse is linear in them): computed once;
    # the gyro scale's (the rate in both sides) is re-linearised at each Gauss-Newton step
    lin = q - bool(st.gscale)
    e_0 = error(u, sm)
    C = np.zeros((len(t), 3, q))
    for j in range(lin):
        C[:, :, j] = (error(_DU * np.eye(q)[j], sm) - e_0) / _DU
    for _ in range(_STEPS if st.gscale else 2):     # linear: the 2nd rescales the noise
        w0, grid0, tq0 = st.torque(u)
        if st.gscale:
            d = np.eye(q)[-1] * _DU
            C[:, :, -1] = (error(u + d, sm) - error(u, sm)) / _DU
        new, cov, _ = profile_inputs(t, lhs(w0),
                                     cumulative_torque(grid0 - st.tg[0], tq0, t), C, ends,
                                     res.model.endswith('+bias'), u, gv, scale_dir)
        done = np.all(np.abs(new - u) <= 0.01 * np.sqrt(np.maximum(np.diag(cov), 1e-30)))
        u = new
        if done:
            break
    return u, 0.5 * (cov + cov.T)


def _scale_direction(st: Stated) -> np.ndarray | None:
    """The ``u`` (q,) that scales the whole known input (momentum, its torque and the other
    torque, unless all zero) by one: every coefficient of it stated (None when it is not)."""
    m, q = st.mom, len(st.names)
    if not len(m.names) or (np.any(st.tau != 0.0) and not st.scale):  # a torque fixes it
        return None
    cols = [m.h_std.reshape(len(m.names), -1)]
    target = [m.h.reshape(-1)]
    if m.torque is not None:
        cols.append(m.torque_std.reshape(len(m.names), -1))
        target.append(m.torque.reshape(-1))
    A = np.concatenate(cols, axis=1).T
    y = np.concatenate(target)
    if not A.size or not np.any(y):
        return None
    s, r = _tall_lstsq(A, y)
    if np.sqrt(np.sum(r * r)) > 1e-6 * np.sqrt(np.sum(y * y)):     # (no BLAS dot: threads)
        return None
    out = np.zeros(q)
    out[:len(s)] = s
    if st.scale:
        out[len(s)] = 1.0 / st.scale
    return out


def _smooth(t: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Centred moving average of the changes ``d`` (P, K, 3) over about :data:`_SMOOTH_S`
    (odd, >= 3 samples; shorter at the ends)."""
    n = int(_SMOOTH_S / max(float(np.median(np.diff(t))), 1e-12)) // 2 * 2 + 1
    n = min(max(n, 3), (d.shape[1] - 1) // 2 * 2 + 1)
    if d.size == 0 or n < 3:
        return d
    c = np.concatenate([np.zeros_like(d[:, :1]), np.cumsum(d, axis=1)], axis=1)
    k = np.arange(d.shape[1])
    lo, hi = np.maximum(k - n // 2, 0), np.minimum(k + n // 2 + 1, d.shape[1])
    return (c[:, hi] - c[:, lo]) / (hi - lo)[None, :, None]


def _fixed(res: Any, options: dict[str, Any]) -> dict[str, Any] | None:
    """``res``'s method, model, bias, noise and segments, fixed (None: not propagated)."""
    diag = res.diagnostics
    fixed = dict(options)
    fixed.update(method='integral' if res.method == 'ml' else res.method,
                 model=res.model.removesuffix('+bias'),
                 torque_bias='on' if res.model.endswith('+bias') else 'off',
                 gyro_noise=diag.get('gyro_noise_std'))
    if diag.get('segment_s') is not None:
        fixed['segment'] = diag['segment_s']
    if diag.get('filter_cutoff_hz'):    # the same band (method='auto' may pick filtered)
        fixed['window'] = 1.0 / float(diag['filter_cutoff_hz'])
    return fixed if fixed['model'] in ('full', 'diagonal', 'axisymmetric') else None


def rerun(res: Any, run: Any, st: Stated, u: np.ndarray, options: dict[str, Any]) -> Any:
    """``run`` with ``options`` on the data with the stated inputs ``u`` (q,) off, keeping
    the other torque's hold chosen for ``res`` (its ``hold`` and ``hold_selection``)."""
    out = run(*st.torque(u), **options)
    for key in ('hold', 'hold_selection'):
        if key in res.diagnostics:
            out.diagnostics[key] = res.diagnostics[key]
    return out


def propagate(res: Any, run: Any, st: Stated, options: dict[str, Any]) -> Any:
    """The estimate with the stated inputs profiled (module docstring).

    Parameters
    ----------
    res : InertiaEstimate
        The estimate with the inputs as stated.
    run : callable
        ``run(w (n, 3), grid (G,), torque (G, 3), **options) -> InertiaEstimate``.
    st : Stated
    options : dict
        The estimate's options.

    Returns
    -------
    InertiaEstimate
        The estimate on the inputs corrected by ``u_hat`` with ``D cov_u D'`` added
        (``diagnostics['input_uncertainty']``, also ``['wheel_inertia']``).
    """
    names = st.names
    u_hat, cov_u = _profile(res, st)
    out = rerun(res, run, st, u_hat, options)
    fixed = _fixed(out, options) if out.inertia is not None \
        and np.all(np.isfinite(out.inertia)) else None
    if fixed is None:
        return res if out.inertia is None else out
    # the reference and the sensitivity runs are used for their tensors alone: without the
    # adequacy tests (which only widen a covariance)
    ref = out if out.method != 'ml' else run(*st.torque(u_hat), **fixed, final=False)
    D = np.zeros((len(names), 6))                   # d theta (6,) per input sigma
    for j in range(len(names)):
        p = run(*st.torque(u_hat + np.eye(len(names))[j]), **fixed, final=False)
        if p.inertia is not None and np.all(np.isfinite(p.inertia)):
            D[j] = np.nan_to_num(p.theta - ref.theta)
    return widened(out, D, u_hat, cov_u, names, 'the anchored equations, the data corrected '
                   'by the posterior mean', st.scale, st.gscale)


def widened(est: Any, D: np.ndarray, u: np.ndarray, cov_u: np.ndarray, names: list[str],
            where: str, scale: float, gscale: float) -> Any:
    """``est`` with the stated inputs' ``D' cov_u D`` added to its covariance and every
    uncertainty derived from it (:func:`.uncertainty.widen`), and their record
    (:func:`record_inputs`), batch and online alike.

    ``D`` (q, 6): the change of ``theta`` per stated sigma of each input; ``u`` (q,), ``cov_u``
    (q, q): their posterior mean [stated sigmas] and covariance; ``names`` (q): the inputs;
    ``where``: the equations the profile ran on; ``scale``, ``gscale``: the stated torque and
    gyro scale sigmas.
    """
    outer = D.T @ cov_u @ D
    per = {nm: {'theta_change': D[j], 'profiled_sigmas': float(u[j]),
                'posterior_sigmas': float(np.sqrt(max(cov_u[j, j], 0.0)))}
           for j, nm in enumerate(names)}
    out = widen(est, outer)
    if out is est:
        out = replace(est, diagnostics=dict(est.diagnostics))
    record_inputs(out.diagnostics, per, outer, cov_u, where, scale, gscale, out.status)
    return out


def record_inputs(diag: dict[str, Any], per: dict[str, Any], outer: np.ndarray,
                  cov_u: np.ndarray, where: str, scale: float, gscale: float,
                  status: str) -> None:
    """Write the stated inputs' record into ``diag`` (batch and online alike).

    ``diagnostics['input_uncertainty']`` (alias ``wheel_inertia``): each input's record
    ``per``, the standard errors added (from ``outer`` (6, 6), ``D cov_u D'``), the posterior
    covariance ``cov_u`` (q, q) and the rule (``where`` the profile ran); the stated scales in
    ``diagnostics['calibration']``; a ``model_mismatch`` reason says the stated sigmas do not
    explain it.
    """
    diag['wheel_inertia'] = {
        'inputs': per, 'theta_std_added': np.sqrt(np.diag(outer)), 'posterior_cov': cov_u,
        'rule': f"stated inputs profiled under their N(0, stated sigma) prior on {where}, "
                "D cov D' added"}
    diag['input_uncertainty'] = diag['wheel_inertia']
    if scale or gscale:
        calib = dict(diag.get('calibration') or {})
        calib.update(torque_scale_std=scale, gyro_scale_std=gscale,
                     applies_to="stated inputs 'torque_scale' (the torque stream only, not the "
                     "momentum input) and 'gyro_scale' (the rate in both sides, w x h "
                     'included) of input_uncertainty')
        diag['calibration'] = calib
    if status == 'model_mismatch' and 'reason' in diag:
        diag['reason'] = (f"{diag['reason']}; beyond what the stated wheel inertias / rotor "
                          'coefficients / sensor scales explain')
