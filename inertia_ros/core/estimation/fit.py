"""Weighted least squares on the sufficient statistics, with its covariance.

``y = X6 (T psi + offset) + Xd d + e`` is solved from the cross Grams of
:class:`~.statistics.SufficientStats`:

* weights ``W = (I S_g I)^-1`` (``S_g`` the gyro-noise covariance, ``I`` from a first pass:
  :func:`fit_two_pass`), the equation error's white part being ``I n_b``;
* errors in variables: the gyro noise in the regressor biases ``X6' W X6`` by ``n B``, which is
  subtracted (``H = Phi' W Phi - n B``);
* the covariance is the sandwich ``H^-1 M H^-T`` with the exact noise model of the anchored
  equations (white gyro noise plus the integrated torque noise of each torque interval),
  inflated (never deflated) by the excess of the residuals over that model; the ``hac``
  equations use the Newey-West meat of their scores, corrected on short records
  (:func:`hac_small_sample`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..tensor import check_physical, nearest_physical, theta_to_matrix
from .model import selector
from .noise import gyroscopic_walk_cov, walk_maps
from .regressors import MOMENTUM_BASIS, metric
from .statistics import WALK_BASIS, SufficientStats

__all__ = ['Fit', 'equation_weight', 'fit_two_pass', 'fit_weighted', 'hac_small_sample',
           'solve_symmetric']


@dataclass
class Fit:
    """One weighted least-squares fit of a parameter set ``[psi (k), d (3, optional)]``.

    ``beta``/``cov`` are the estimate and its covariance (p = k (+ 3)), ``H`` the
    bias-compensated information and ``H0`` the raw one (conditioning), ``basis`` the
    parameter set (6, k), ``resid_rms`` the residual RMS per axis, ``n_eq`` the equations,
    ``excess`` the residual variance over the noise model's, ``offset`` a held part of theta
    and ``H_full`` the information of all six elements (fits with an offset); ``inertial``: a
    torque fixed in inertial axes ``d_i`` (3) follows the bias in ``beta`` (wide statistics,
    :mod:`.regressors`; :attr:`bias_at`, :attr:`inertial_at` locate both).
    """

    beta: np.ndarray               # (p,)
    cov: np.ndarray                # (p, p)
    H: np.ndarray                  # (p, p) (bias-compensated) information
    H0: np.ndarray                 # (p, p) uncompensated, for conditioning
    basis: np.ndarray              # (6, k)
    bias: bool
    resid_rms: np.ndarray          # (3,)
    n_eq: int
    excess: float = 1.0            # residual variance / noise-model prediction
    offset: np.ndarray | None = None  # (6,) fixed part of theta
    H_full: np.ndarray | None = None  # information of the full model (fits with an offset)
    inertial: bool = False         # d_i (3) after the bias
    #: the equations carry a momentum input's noise (wheels, rotors): its noise model is an
    #: upper bound (a residual excess well below 1 is expected there)
    momentum_noise: bool = False

    @property
    def bias_at(self) -> slice:
        """Where the torque bias sits in ``beta`` (empty without it)."""
        k = self.basis.shape[1]
        return slice(k, k + (3 if self.bias else 0))

    @property
    def inertial_at(self) -> slice:
        """Where the torque fixed in inertial axes sits in ``beta`` (empty without it)."""
        b = self.bias_at.stop
        return slice(b, b + (3 if self.inertial else 0))


def solve_symmetric(H: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve ``H x = rhs`` with column scaling; least squares if singular."""
    d = np.sqrt(np.abs(np.diag(H)))
    d[d == 0] = 1.0
    Hs = H / d[:, None] / d[None, :]
    rs = rhs / (d[:, None] if rhs.ndim == 2 else d)
    try:
        x = np.linalg.solve(Hs, rs)
        if not np.all(np.isfinite(x)):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        x = np.linalg.lstsq(Hs, rs, rcond=1e-12)[0]
    return x / (d[:, None] if rhs.ndim == 2 else d)


def _anchored_meat(st: SufficientStats, T: np.ndarray, p: int, W: np.ndarray, G: np.ndarray,
                   c: np.ndarray, theta: np.ndarray, gyro_var: np.ndarray,
                   torque_var: np.ndarray) -> tuple[np.ndarray, float]:
    """Middle of the sandwich and the residual excess under the anchored noise model."""
    Im = theta_to_matrix(theta)
    S = Im @ np.diag(gyro_var) @ Im                           # white part of e_b
    if st.white_y_cov is not None:                            # + a momentum input's noise
        S = S + st.white_y_cov
    meat = (T.T @ metric(st.C, W @ S @ W) @ T)[:p, :p]
    # the integrated torque noise and the gyro noise the gyroscopic term integrates: both
    # random walks held over the torque intervals (see noise.gyroscopic_walk_cov)
    S_tau = np.diag(torque_var) + gyroscopic_walk_cov(Im, gyro_var, st.omega_m2, st.gyro_dt,
                                                      st.torque_dt)
    if st.CP is not None:
        meat += (T.T @ metric(st.CP, W @ S_tau @ W) @ T)[:p, :p]
    walk = getattr(st, 'walk_grams', None)       # a time-varying walk (a momentum input's)
    if walk is not None:
        B = walk_bases(len(walk), Im, gyro_var, st.gyro_dt, st.torque_dt)
        meat += (T.T @ np.einsum('qrs,qrsij->ij', W @ B @ W, walk) @ T)[:p, :p]
        S_tau = S_tau + np.einsum('q,qab->ab', st.walk_mean, B)
    # residuals larger than the noise model predicts (misfit, unmodelled effects):
    # inflate the covariance by the excess, never deflate it
    rss_w = float(c @ G @ c)
    expected = st.n_eff * float(np.trace(W @ S)) + st.walk_time * st.torque_dt * float(
        np.trace(W @ S_tau))
    excess = rss_w / expected if expected > 0 else 1.0
    return meat, excess


def eiv_swap(eiv_var: np.ndarray, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The errors-in-variables term the measured Gram leaves out of the sandwich middle (6, 6).

    The gyro noise ``n`` (variances ``eiv_var`` (3,)) is in the regressor ``N = sum_c n_c
    M_c`` (:data:`.regressors.MOMENTUM_BASIS`) and, through it, in the equation error ``N
    theta = I n``.  Their product ``N' W N theta``, whose mean the compensation removes,
    varies as two Gaussian pairings: the one the measured Gram's ``N' W S W N`` part
    carries, and the swapped one, ``sum_cd s_c s_d a_cd a_dc'`` with ``a_cd = M_c' W M_d
    theta`` (Isserlis), per equation.  Negligible against the signal on a whole record, it
    dominates where the excitation barely separates two parameters (a short piece's torque
    bias from its tensor: the score's variance there was 2.6x the middle's).
    """
    a = np.einsum('crk,rs,dsl,l->cdk', MOMENTUM_BASIS, W, MOMENTUM_BASIS, theta)
    v = np.asarray(eiv_var, dtype=float)
    out = np.einsum('c,d,cdk,dcl->kl', v, v, a, a)
    return 0.5 * (out + out.T)


def walk_bases(q: int, I: np.ndarray, gyro_var: np.ndarray, gyro_dt: float,
               torque_dt: float) -> np.ndarray:
    """The matrices (q, 3, 3) a time-varying walk's weights multiply
    (:attr:`.statistics.SufficientStats.walk_grams`): the six of a covariance
    (:data:`.statistics.WALK_BASIS`), then (q = 15) for each product ``w_i h_c`` (index
    ``3 i + c``) the cross term of the gyro noise's two walks, the gyroscopic ``J(w) n``
    (``J(w) = sum_i w_i A_i``, :func:`.noise.walk_maps`) and a momentum input's ``n x h``:
    ``-(A_i S_g [e_c]x' + [e_c]x S_g A_i')``, scaled as the gyroscopic walk by
    ``sqrt(gyro_dt / torque_dt)`` (``I`` (3, 3) the tensor, ``gyro_var`` (3,) [rad^2/s^2])."""
    if q == len(WALK_BASIS) or not (gyro_dt > 0 and torque_dt > 0):
        return np.concatenate([WALK_BASIS, np.zeros((q - len(WALK_BASIS), 3, 3))])
    from .align import cross_matrices

    AS = walk_maps(I) * np.asarray(gyro_var, dtype=float)[None, None, :]   # A_i S_g
    X = np.einsum('iab,cdb->icad', AS, cross_matrices(np.eye(3)))         # A_i S_g [e_c]x'
    cross = -(X + X.transpose(0, 1, 3, 2)).reshape(9, 3, 3) * np.sqrt(gyro_dt / torque_dt)
    return np.concatenate([WALK_BASIS, cross])


def _hac_meat(st: SufficientStats, T: np.ndarray, p: int, W: np.ndarray,
              c: np.ndarray) -> np.ndarray:
    """Newey-West (Bartlett) middle of the sandwich from the scores of the blocks."""
    assert st.A is not None
    X = st.A @ T                                               # (n, 3, p + 1)
    e = X @ c                                                  # (n, 3) residuals
    scores = np.einsum('nrp,rs,ns->np', X[..., :p], W, e)
    meat = scores.T @ scores
    for lag in range(1, st.hac_lag + 1):
        wgt = 1.0 - lag / (st.hac_lag + 1.0)
        Gl = scores[lag:].T @ scores[:-lag]
        meat += wgt * (Gl + Gl.T)
    if st.hac_shapes is not None:
        g = np.sqrt(hac_small_sample(X[..., :p], W, e, st.hac_lag, st.hac_shapes))
        meat = meat * g[:, None] * g[None, :]
    return meat


def hac_small_sample(X: np.ndarray, W: np.ndarray, e: np.ndarray, lag: int,
                     shapes: np.ndarray) -> np.ndarray:
    """Per-parameter factor (>= 1) by which the Newey-West variance is too small on a short record.

    With few equations per correlation time the Bartlett estimate is biased low: the kernel
    down-weights the correlated lags and the residuals, fitted to the same equations, are
    smaller than the errors.  Under a working model of the error -- stationary, the pooled
    axis covariance ``E = e'e / n`` (3, 3) times an autocorrelation ``rho`` fitted to the
    residuals' own autocovariance at lags ``0..2 lag`` as a non-negative mix of ``shapes`` --
    the true variance ``diag(H^-1 Z' S Z H^-1)`` and the expected Newey-West one (the same with
    ``S`` replaced by the kernel-weighted covariance of the residuals ``M S M'``) are exact;
    their ratio is the factor (Bell-McCaffrey style bias reduction).  Dense ``3n x 3n``:
    called only for short records (:data:`.filtered.HAC_SMALL_SAMPLE_MAX` equations).

    Parameters
    ----------
    X : ndarray, shape (n, 3, p)
        Regressor blocks.
    W : ndarray, shape (3, 3)
        Equation weight.
    e : ndarray, shape (n, 3)
        Residuals.
    lag : int
        Bartlett lag [equations].
    shapes : ndarray, shape (k, m)
        Candidate autocorrelations of the error at lags ``0..m-1`` (``shapes[:, 0] = 1``).

    Returns
    -------
    ndarray, shape (p,)
        Variance factors, each >= 1.
    """
    from scipy.optimize import nnls

    n, _, p = X.shape
    m = min(2 * lag, n - 1)
    acov = np.array([np.sum(e[k:] * e[:n - k]) / n for k in range(m + 1)])
    basis = np.zeros((m + 1, len(shapes)))
    basis[:min(m + 1, shapes.shape[1])] = shapes.T[:m + 1]
    mix = nnls(basis, acov)[0]
    rho = mix @ shapes
    if not rho[0] > 0:
        return np.ones(p)
    rho = rho / rho[0]
    d = np.abs(np.subtract.outer(np.arange(n), np.arange(n)))
    R = np.where(d < len(rho), rho[np.minimum(d, len(rho) - 1)], 0.0)
    K = np.kron(np.where(d <= lag, 1.0 - d / (lag + 1.0), 0.0), np.ones((3, 3)))
    S = np.kron(R, e.T @ e / n)                               # working error covariance
    Xf = X.reshape(3 * n, p)
    Z = np.einsum('rs,nsp->nrp', W, X).reshape(3 * n, p)
    Hi = solve_symmetric(Z.T @ Xf, np.eye(p))
    AS = (Hi @ Z.T) @ S                                       # (p, 3n)
    XAS = Xf @ AS
    Eres = S - XAS - XAS.T + Xf @ (AS @ (Z @ Hi.T)) @ Xf.T    # E[residuals'] = M S M'
    true = np.diag(Hi @ (Z.T @ S @ Z) @ Hi.T)
    est = np.diag(Hi @ (Z.T @ (K * Eres) @ Z) @ Hi.T)
    with np.errstate(divide='ignore', invalid='ignore'):
        f = np.where(est > 0, true / est, 1.0)
    return np.maximum(np.nan_to_num(f, nan=1.0, posinf=1.0), 1.0)


def fit_weighted(st: SufficientStats, basis: np.ndarray, bias: bool, W: np.ndarray,
                 gyro_var: np.ndarray, torque_var: np.ndarray, bias_comp: bool,
                 offset: np.ndarray | None = None, noise_theta: np.ndarray | None = None,
                 inertial: bool = False, held: np.ndarray | None = None) -> Fit:
    """Weighted LS of ``y = X6 (T psi + offset) (+ Xd d)`` with its covariance.

    Parameters
    ----------
    st : SufficientStats
        Statistics of the equations.
    basis : ndarray, shape (6, k)
        Parameter set.
    bias : bool
        Fit the constant torque bias.
    W : ndarray, shape (3, 3)
        Equation weight.
    gyro_var, torque_var : ndarray, shape (3,)
        Noise variances [rad^2/s^2], [N^2 m^2].
    bias_comp : bool
        Subtract the gyro-noise bias of the information (errors in variables).
    offset : ndarray, shape (6,), optional
        Fixed part of ``theta``.
    noise_theta : ndarray, shape (6,), optional
        Tensor the anchored noise model (sandwich middle, residual excess) is evaluated at;
        the fit's own by default.  A short piece of a record (the bias split's) gives
        a nearly singular fit whose own tensor swings with the noise, and its noise model
        with it; the whole record's tensor is the model's under the null.
    inertial : bool
        Fit the torque fixed in inertial axes too (wide statistics only).
    held : ndarray, shape (3,), optional
        The torque fixed in inertial axes, not fitted, held at these values [N m]
        (:func:`.model.selector`).

    Returns
    -------
    Fit
    """
    k = basis.shape[1]
    T, p, G, H0, H, beta, B6 = _normal_solution(st, basis, bias, W, bias_comp, offset,
                                                inertial, held)
    compensate = B6 is not None
    Hinv = solve_symmetric(H, np.eye(p))
    c = np.append(-beta, 1.0)
    rss = np.array([c @ (T.T @ st.C[r, r] @ T) @ c for r in range(3)])
    if st.kind == 'anchored':
        theta = basis @ beta[:k] + (0.0 if offset is None else offset) \
            if noise_theta is None else noise_theta
        meat, excess = _anchored_meat(st, T, p, W, G, c, theta, gyro_var, torque_var)
        if compensate:
            meat[:k, :k] += st.n_eff * (basis.T @ eiv_swap(st.eiv_var, W, theta) @ basis)
    else:
        meat, excess = _hac_meat(st, T, p, W, c), 1.0
    cov = Hinv @ meat @ Hinv.T
    cov = 0.5 * (cov + cov.T) * max(excess, 1.0)
    dof = max(st.n_eff - p, 1)
    H_full = None
    if offset is not None:
        # information of all six elements under the same weights: how the held elements
        # leak into the estimated ones (see selection.held_leak)
        Tf = selector(np.eye(6), bias, None, inertial, st.C.shape[-1])
        pf = Tf.shape[1] - 1
        H_full = (Tf.T @ metric(st.C, W) @ Tf)[:pf, :pf]
        if compensate:
            H_full[:6, :6] -= st.n_eff * B6
    return Fit(beta=beta, cov=cov, H=H, H0=H0, basis=basis, bias=bias, offset=offset,
               resid_rms=np.sqrt(np.maximum(rss, 0.0) / dof), n_eq=st.n, excess=excess,
               H_full=H_full, inertial=inertial,
               momentum_noise=st.white_y_cov is not None
               or getattr(st, 'walk_grams', None) is not None)


def _normal_solution(st: SufficientStats, basis: np.ndarray, bias: bool, W: np.ndarray,
                     bias_comp: bool, offset: np.ndarray | None, inertial: bool = False,
                     held: np.ndarray | None = None
                     ) -> tuple[np.ndarray, int, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                np.ndarray | None]:
    """The (bias-compensated) normal equations of :func:`fit_weighted` and their solution.

    Returns ``(T, p, G, H0, H, beta, B6)``: the selector, parameter count, the weighted Gram
    ``T' C_W T``, the information before and after compensation, the estimate and the
    gyro-noise term ``B6`` (6, 6) (``None`` without compensation).
    """
    k = basis.shape[1]
    T = selector(basis, bias, offset, inertial, st.C.shape[-1], held)
    p = T.shape[1] - 1
    G = T.T @ metric(st.C, W) @ T
    H0 = G[:p, :p]
    g = G[:p, p]
    H = H0.copy()
    B6 = None
    if bias_comp and st.eiv_var is not None:
        B6 = np.einsum('c,crk,rs,csl->kl', st.eiv_var, MOMENTUM_BASIS, W, MOMENTUM_BASIS)
        H[:k, :k] -= st.n_eff * (basis.T @ B6 @ basis)
        if offset is not None:
            # the held part's regressor carries the same gyro noise: g = -B' X6'X6 offset
            # is compensated like H (B' (X6'X6 - n B6) offset)
            g = g.copy()
            g[:k] += st.n_eff * (basis.T @ B6 @ offset)
    return T, p, G, H0, H, solve_symmetric(H, g), B6


def equation_weight(theta: np.ndarray, gyro_var: np.ndarray,
                    white_y_cov: np.ndarray | None = None) -> np.ndarray:
    """Equation weight ``(I S_g I)^-1`` (3, 3), scaled to max 1, from a first-pass ``theta``
    (``(I S_g I + white_y_cov)^-1`` with other white noise in ``y``); a tensor that is not
    physical or nearly singular (its weight would be) is projected first."""
    Im = theta_to_matrix(theta)
    lam = np.linalg.eigvalsh(Im)     # a smallest moment under 1e-6 of the largest: projected
    if not (lam[0] > 1e-6 * lam[2] and (lam[0] + lam[1] >= lam[2] or check_physical(Im).valid)):
        Im = nearest_physical(Im, min_moment=1e-3 * max(float(np.sum(np.abs(Im))), 1e-30))
    S = Im @ np.diag(gyro_var) @ Im
    if white_y_cov is not None:
        S = S + white_y_cov
    W = np.linalg.inv(S)
    return 0.5 * (W + W.T) / np.max(np.abs(W))


def fit_two_pass(st: SufficientStats, basis: np.ndarray, bias: bool, gyro_var: np.ndarray,
                 torque_var: np.ndarray, offset: np.ndarray | None = None,
                 theta0: np.ndarray | None = None, noise_theta: np.ndarray | None = None,
                 inertial: bool = False, held: np.ndarray | None = None) -> Fit:
    """Two-pass fit: unweighted, then weighted by the first pass's tensor (weighted methods).

    ``theta0`` (6,), a tensor from an earlier fit of the same data, gives the weights at once
    (one weighted pass; model selection refits the same equations several times).  Other
    parameters as :func:`fit_weighted` (``inertial``: the torque fixed in inertial axes too;
    ``held``: the inertial torque not fitted, at fixed values, :func:`.model.selector`).
    """
    if theta0 is not None and st.weighted and np.all(gyro_var > 0) \
            and np.all(np.isfinite(theta0)) and np.any(theta0[:3] != 0):
        return fit_weighted(st, basis, bias,
                            equation_weight(theta0, gyro_var, st.white_y_cov), gyro_var,
                            torque_var, st.weighted, offset, noise_theta, inertial, held)
    if st.weighted and np.all(gyro_var > 0):
        # the unweighted pass gives the weights only: its estimate, not its covariance
        beta = _normal_solution(st, basis, bias, np.eye(3), st.weighted, offset, inertial,
                                held)[5]
        theta = basis @ beta[:basis.shape[1]] + (0.0 if offset is None else offset)
        if np.all(np.isfinite(theta)) and np.any(theta[:3] != 0):
            return fit_weighted(st, basis, bias,
                                equation_weight(theta, gyro_var, st.white_y_cov), gyro_var,
                                torque_var, st.weighted, offset, noise_theta, inertial, held)
    return fit_weighted(st, basis, bias, np.eye(3), gyro_var, torque_var, st.weighted, offset,
                        noise_theta, inertial, held)
