"""Maximum-likelihood refinement of an inertia estimate (method ``ml``).

The measurement model is the one of :mod:`inertia_ros.core.crlb`: Euler's equations driven by
the held torque, gyro white noise ``n_k ~ N(0, diag(sigma_g^2))`` and torque-sample noise
``nu_j ~ N(0, diag(sigma_t^2))`` acting as process noise held over each torque interval.
Maximum likelihood with the angular-velocity path integrated out is the Kalman
prediction-error criterion of :func:`~inertia_ros.core.crlb.prediction_error_step`; here the
same Gauss-Newton step is computed without a sequential filter:

* **multiple shooting**: every torque interval ``[s_j, s_{j+1})`` is integrated from its own
  reference state ``r_j`` (smoothed gyro at the first pass, the smoothed state afterwards),
  all intervals at once (vectorised RK4, :class:`~inertia_ros.core.crlb.Dynamics`), with the
  transition ``Phi``, the torque-noise input ``Psi`` and the parameter sensitivities ``S``;
* the deviations ``delta_j = w(s_j) - r_j`` are unknowns linked by the exact linearised
  continuity ``delta_{j+1} = Phi_j delta_j + g_j + S_j dp + Psi_j nu_j``; eliminating
  ``nu_j = Psi_j^-1 (...)`` leaves a least-squares problem whose rows each touch
  ``delta_j, delta_{j+1}`` and ``dp`` only: block-tridiagonal normal equations with a dense
  border, solved by a banded Cholesky factorisation and a Schur complement;
* for a linear Gaussian model the minimum over the path of the joint quadratic is the
  marginal likelihood (up to a log-determinant that the bound also neglects), so the Schur
  complement is the Fisher information of ``p = [theta, d]`` with ``w0 = r_0 + delta_0`` a
  free nuisance: its inverse is the estimate's covariance, the same as the bound's at the
  estimate.

Each pass costs a few vectorised operations per gyro sample; 2-4 passes converge from the
``integral`` estimate.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from ..crlb import Dynamics
from ..tensor import theta_to_matrix

__all__ = ['MLRefinement', 'refine']

_MAX_STEP_ANGLE = 0.02      # rad turned per RK4 substep, at most (as in crlb)
_MAX_SUBSTEPS = 256         # RK4 substeps per torque interval: beyond, ml is not worth its cost
_SIGMA_T_FLOOR = 1e-3       # torque-noise std floor, relative to the largest axis or torque rms


@dataclass(frozen=True, eq=False)
class MLRefinement:
    """Outcome of :func:`refine`.

    Attributes
    ----------
    converged : bool
        The last Gauss-Newton step was below ``tol`` standard errors in every parameter.
    beta : numpy.ndarray, shape (k,)
        Tensor coordinates in ``basis`` [kg m^2].
    bias : numpy.ndarray, shape (3,), or None
        Disturbance torque [N m] when it was estimated.
    cov : numpy.ndarray, shape (k (+3), k (+3))
        Covariance of ``[beta, bias]`` (inverse Fisher information, inflated by the residual
        excess when it is above 1).
    iterations : int
        Gauss-Newton passes made.
    excess : float
        Weighted residual sum of squares over its degrees of freedom (1 when the noise model
        holds).
    steps : list of float
        Largest step of each pass in standard errors.
    reason : str
        Why the refinement stopped (empty when it converged).
    """

    converged: bool
    beta: np.ndarray
    bias: np.ndarray | None
    cov: np.ndarray
    iterations: int
    excess: float
    steps: list[float]
    reason: str = ''


def _events(tg: np.ndarray, s: np.ndarray, t_end: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-interval event times (gyro times, then the interval end), padded with the end.

    Returns ``T (M, K)``, the interval of each gyro sample ``(N,)`` and its event column
    ``(N,)``.
    """
    M = len(s)
    j = np.searchsorted(s, tg, side='right') - 1
    first = np.searchsorted(j, np.arange(M), side='left')
    col = np.arange(len(tg)) - first[j]
    counts = np.bincount(j, minlength=M)
    K = int(counts.max()) + 1
    ends = np.append(s[1:], t_end)
    T = np.repeat(ends[:, None], K, axis=1)
    T[j, col] = tg
    return T, j, col


def _shoot(dyn: Dynamics, r0: np.ndarray, s: np.ndarray, T: np.ndarray, iiu: np.ndarray,
           jg: np.ndarray, cg: np.ndarray, q: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integrate every interval from its reference; states and ``Z`` at gyro times and ends."""
    M, K = T.shape
    w = r0.copy()
    Z = np.zeros((M, 3, q))
    Z[:, :, q - 6:q - 3] = np.eye(3)
    n = len(jg)
    wg = np.empty((n, 3))
    Zg = np.empty((n, 3, q))
    t_prev = s.copy()
    for k in range(K):
        h_tot = T[:, k] - t_prev
        t_prev = T[:, k]
        if np.any(h_tot > 0):
            vmax = float(np.max(np.linalg.norm(w, axis=1))) + float(
                np.max(np.linalg.norm(iiu, axis=1)) * np.max(h_tot))
            nsub = max(1, int(np.ceil(vmax * float(np.max(h_tot)) / _MAX_STEP_ANGLE)))
            if nsub > _MAX_SUBSTEPS:      # bounded cost: the integral estimate stands
                raise _PassError(f'the body turns {vmax * float(np.max(h_tot)):.3g} rad '
                                 f'between samples ({nsub} RK4 substeps needed, at most '
                                 f'{_MAX_SUBSTEPS})')
            w, Z = dyn.rk4(w, Z, iiu, h_tot / nsub, nsub)
        at = cg == k
        wg[at] = w[jg[at]]
        Zg[at] = Z[jg[at]]
    return wg, Zg, w, Z


def _banded(D: np.ndarray, O: np.ndarray) -> np.ndarray:
    """Upper banded storage (6, 3 B) of the symmetric block-tridiagonal matrix.

    ``D (B, 3, 3)`` diagonal blocks, ``O (B - 1, 3, 3)`` blocks coupling ``b`` to ``b + 1``.
    """
    B = D.shape[0]
    n = 3 * B
    ab = np.zeros((6, n))
    base = 3 * np.arange(B)
    for r in range(3):
        for c in range(r, 3):
            ab[5 + r - c, base + c] = D[:, r, c]
    base = 3 * np.arange(B - 1)
    for r in range(3):
        for c in range(3):
            ab[5 + r - (3 + c), base + 3 + c] = O[:, r, c]
    return ab


class _Normal:
    """Normal equations of row blocks ``a delta_j + b delta_{j+1} + c dp ~ z`` (weights ``wv``).

    ``D (M + 1, 3, 3)`` and ``O (M, 3, 3)``: block-tridiagonal part in the path deviations;
    ``Dp (M + 1, 3, p)``: border; ``bd (M + 1, 3)``: right-hand side of the path part.
    """

    def __init__(self, M: int, npar: int) -> None:
        self.D = np.zeros((M + 1, 3, 3))
        self.O = np.zeros((M, 3, 3))
        self.Dp = np.zeros((M + 1, 3, npar))
        self.bd = np.zeros((M + 1, 3))

    def add(self, a: np.ndarray, b: np.ndarray, c: np.ndarray, z: np.ndarray, wv: np.ndarray,
            groups: tuple[np.ndarray, np.ndarray] | None
            ) -> tuple[np.ndarray, np.ndarray, float]:
        """Add ``n`` row blocks (``a, b (n, 3, 3)``, ``c (n, 3, p)``, ``z (n, 3)``).

        ``groups=None``: block ``j`` belongs to interval ``j`` (``n = M``); else
        ``(intervals, first rows)``: rows sorted by interval, summed per interval.
        Returns the border's own blocks ``(c' W c (p, p), c' W z (p,), z' W z)``.
        """
        aw = a.transpose(0, 2, 1) * wv
        bw = b.transpose(0, 2, 1) * wv
        zc = z[:, :, None]
        blocks = (aw @ a, bw @ b, aw @ b, aw @ c, bw @ c, (aw @ zc)[..., 0], (bw @ zc)[..., 0])
        if groups is not None:
            blocks = tuple(np.add.reduceat(x, groups[1], axis=0) for x in blocks)
            j: np.ndarray | slice = groups[0]
            jn: np.ndarray | slice = groups[0] + 1
            jo: np.ndarray | slice = groups[0]
        else:
            j, jn, jo = slice(0, -1), slice(1, None), slice(None)
        self.D[j] += blocks[0]
        self.D[jn] += blocks[1]
        self.O[jo] += blocks[2]
        self.Dp[j] += blocks[3]
        self.Dp[jn] += blocks[4]
        self.bd[j] += blocks[5]
        self.bd[jn] += blocks[6]
        cw = c * wv[:, None]
        return (np.einsum('nri,nrj->ij', cw, c), np.einsum('nri,nr->i', cw, z),
                float(np.sum(z * z * wv)))


def refine(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
           theta0: np.ndarray, basis: np.ndarray, bias0: np.ndarray | None,
           gyro_std: np.ndarray, torque_std: np.ndarray, *, max_iter: int = 6,
           tol: float = 0.05) -> MLRefinement:
    """Gauss-Newton on the maximum-likelihood criterion, started from a consistent estimate.

    Parameters
    ----------
    tg : numpy.ndarray, shape (N,)
        Gyro times [s], increasing, all at or after ``ts[0]`` (inside the torque coverage).
    w : numpy.ndarray, shape (N, 3)
        Measured angular velocity [rad/s].
    ts : numpy.ndarray, shape (M,)
        Torque sample times [s], increasing; the torque is held from each sample to the next.
    tau : numpy.ndarray, shape (M, 3)
        Measured torque [N m].
    theta0 : numpy.ndarray, shape (6,)
        Starting tensor ``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2] (positive definite).
    basis : numpy.ndarray, shape (6, k)
        Parameter set: ``theta = basis @ beta`` (``theta0`` must lie in its span).
    bias0 : numpy.ndarray, shape (3,), or None
        Starting disturbance torque [N m], or ``None`` to leave it out of the model.
    gyro_std, torque_std : numpy.ndarray, shape (3,)
        Noise std per axis [rad/s], [N m].
    max_iter : int
        Gauss-Newton passes at most (>= 2).
    tol : float
        Convergence: every parameter's step below ``tol`` of its standard error.

    Returns
    -------
    MLRefinement
        ``converged`` False (with ``reason``) when the passes did not settle or a
        factorisation failed; the caller then keeps its starting estimate.

    Raises
    ------
    ValueError
        Inconsistent shapes, or gyro samples before the first torque sample.
    """
    tg = np.asarray(tg, dtype=float)
    w = np.asarray(w, dtype=float)
    if w.shape != (len(tg), 3):
        raise ValueError(f'w: expected shape ({len(tg)}, 3), got {w.shape}')
    if len(ts) < 2 or tau.shape != (len(ts), 3):
        raise ValueError('ts, tau: need >= 2 torque samples with shape (M,), (M, 3)')
    if tg[0] < ts[0]:
        raise ValueError('tg: gyro samples before the first torque sample')
    if max_iter < 2:
        raise ValueError(f'max_iter: must be >= 2, got {max_iter!r}')
    pb = _Problem.build(tg, w, ts, tau, np.asarray(basis, dtype=float), bias0 is not None,
                        gyro_std, torque_std)
    k, bias = pb.k, pb.bias
    beta = np.linalg.lstsq(pb.basis, np.asarray(theta0, dtype=float), rcond=None)[0]
    d = np.zeros(3) if bias0 is None else np.asarray(bias0, dtype=float).copy()
    r = _reference_states(tg, w, pb.s)
    steps: list[float] = []
    cov = np.full((pb.npar, pb.npar), np.nan)
    excess = float('nan')
    for it in range(1, max_iter + 1):
        try:
            dp, delta, cov, excess = _gauss_newton_pass(pb, beta, d, r)
        except _PassError as exc:
            return MLRefinement(False, beta, d if bias else None, cov, it, excess, steps,
                                str(exc))
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        step = float(np.max(np.abs(dp) / np.where(se > 0, se, np.inf)))
        steps.append(step)
        if not np.all(np.isfinite(dp)):
            return MLRefinement(False, beta, d if bias else None, cov, it, excess, steps,
                                'non-finite Gauss-Newton step')
        beta = beta + dp[:k]
        if bias:
            d = d + dp[k:]
        r = r + delta.reshape(pb.M + 1, 3)
        if it >= 2 and step < tol:
            cov = cov * max(excess, 1.0)
            return MLRefinement(True, beta, d if bias else None, cov, it, excess, steps)
    return MLRefinement(False, beta, d if bias else None, cov * max(excess, 1.0), max_iter,
                        excess, steps, f'no convergence in {max_iter} Gauss-Newton passes')


class _PassError(Exception):
    """A Gauss-Newton pass that cannot go on; the message is the reason."""


@dataclass(frozen=True, eq=False)
class _Problem:
    """The fixed parts of the refinement: data, interval events, weights, parameter map."""

    tg: np.ndarray             # (N,) gyro times [s]
    w: np.ndarray              # (N, 3) measured angular velocity [rad/s]
    s: np.ndarray              # (M,) torque samples before the last gyro sample [s]
    u: np.ndarray              # (M, 3) their torque [N m]
    T: np.ndarray              # event times (see _events)
    jg: np.ndarray             # interval of each gyro sample
    cg: np.ndarray             # event index of each gyro sample
    g_int: np.ndarray          # intervals holding gyro samples
    g_start: np.ndarray        # first gyro sample of each of those
    basis: np.ndarray          # (6, k)
    Tp: np.ndarray             # (n_par, npar): sensitivity columns -> dp
    wg: np.ndarray             # (3,) gyro weights [s^2/rad^2]
    wt: np.ndarray             # (3,) torque weights [1/(N^2 m^2)]
    bias: bool

    @property
    def k(self) -> int:
        """Tensor coordinates."""
        return self.basis.shape[1]

    @property
    def M(self) -> int:
        """Torque intervals."""
        return len(self.s)

    @property
    def n_par(self) -> int:
        """Sensitivity columns of the dynamics: theta, w0 (, d)."""
        return 12 if self.bias else 9

    @property
    def npar(self) -> int:
        """Estimated parameters: beta (, d)."""
        return self.k + (3 if self.bias else 0)

    @staticmethod
    def build(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
              basis: np.ndarray, bias: bool, gyro_std: np.ndarray,
              torque_std: np.ndarray) -> _Problem:
        """Events, weights (torque-noise std floored) and the parameter map."""
        keep = ts < tg[-1]
        s, u = ts[keep], tau[keep]
        T, jg, cg = _events(tg, s, float(tg[-1]))
        g_int, g_start = np.unique(jg, return_index=True)
        k = basis.shape[1]
        n_par, npar = (12 if bias else 9), k + (3 if bias else 0)
        Tp = np.zeros((n_par, npar))
        Tp[:6, :k] = basis
        if bias:
            Tp[9:12, k:] = np.eye(3)
        st = np.asarray(torque_std, dtype=float)
        floor = _SIGMA_T_FLOOR * max(float(np.max(st)),
                                     float(np.max(np.sqrt(np.mean(u ** 2, 0)))))
        return _Problem(tg, w, s, u, T, jg, cg, g_int, g_start, basis, Tp,
                        1.0 / np.asarray(gyro_std, dtype=float) ** 2,
                        1.0 / np.maximum(st, floor) ** 2, bias)


def _reference_states(tg: np.ndarray, w: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Reference states (M + 1, 3) at the interval starts and the end: the smoothed gyro."""
    wl = min(9, len(tg) - (1 - len(tg) % 2))
    if wl >= 5:
        from scipy import signal  # lazily: scipy.signal costs ~0.8 s to import
        ws = signal.savgol_filter(w, wl, 2, axis=0)
    else:
        ws = w
    bounds = np.append(s, tg[-1])
    return np.column_stack([np.interp(bounds, tg, ws[:, c]) for c in range(3)])


def _gauss_newton_pass(pb: _Problem, beta: np.ndarray, d: np.ndarray,
                       r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """One pass: the step ``dp``, the path correction ``delta``, the covariance and excess.

    Raises :class:`_PassError` when the tensor, the torque-noise input or the information
    matrix make the pass impossible.
    """
    n_par, npar, M = pb.n_par, pb.npar, pb.M
    Im = theta_to_matrix(pb.basis @ beta)
    if np.linalg.eigvalsh(Im)[0] <= 0 or not np.all(np.isfinite(Im)):
        raise _PassError('the tensor left the positive-definite set')
    dyn = Dynamics(Im, n_par, pb.bias)
    iiu = (pb.u + d) @ dyn.Ii.T
    wk, Zk, wend, Zend = _shoot(dyn, r[:-1], pb.s, pb.T, iiu, pb.jg, pb.cg, n_par + 6)
    Phb, Psb = Zend[:, :, n_par:n_par + 3], Zend[:, :, n_par + 3:]
    Sb = Zend[:, :, :n_par] @ pb.Tp
    gj = wend - r[1:]
    try:
        Pinv = np.linalg.inv(Psb)
    except np.linalg.LinAlgError:
        raise _PassError('singular torque-noise input matrix') from None
    # prior rows of nu_j: coefficients on delta_j, delta_{j+1}, dp and the target
    pa, pc, pz = -Pinv @ Phb, -Pinv @ Sb, (Pinv @ gj[:, :, None])[..., 0]
    # gyro rows
    jg = pb.jg
    G = Zk[:, :, n_par + 3:] @ Pinv[jg]
    ga = Zk[:, :, n_par:n_par + 3] - G @ Phb[jg]
    gc = Zk[:, :, :n_par] @ pb.Tp - G @ Sb[jg]
    gz = pb.w - wk + (G @ gj[jg][:, :, None])[..., 0]
    nrm = _Normal(M, npar)
    Fp1, bp1, zz1 = nrm.add(pa, Pinv, pc, pz, pb.wt, None)
    Fp2, bp2, zz2 = nrm.add(ga, G, gc, gz, pb.wg, (pb.g_int, pb.g_start))
    try:
        cb = linalg.cholesky_banded(_banded(nrm.D, nrm.O), lower=False)
    except linalg.LinAlgError:
        raise _PassError('the path normal equations are not positive definite') from None
    Dpf = nrm.Dp.reshape(3 * (M + 1), npar)
    X = linalg.cho_solve_banded((cb, False), np.column_stack([nrm.bd.ravel(), Dpf]))
    F = Fp1 + Fp2 - Dpf.T @ X[:, 1:]
    F = 0.5 * (F + F.T)
    bp = bp1 + bp2
    rhs = bp - Dpf.T @ X[:, 0]
    cov = _inverse_information(F)
    dp = cov @ rhs
    delta = X[:, 0] - X[:, 1:] @ dp
    rss = zz1 + zz2 - float(nrm.bd.ravel() @ delta) - float(bp @ dp)
    excess = rss / max(3 * len(pb.tg) - 3 - npar, 1)
    return dp, delta, cov, excess


def _inverse_information(F: np.ndarray) -> np.ndarray:
    """``F^-1`` by column scaling; :class:`_PassError` when ``F`` is singular."""
    sc = np.sqrt(np.abs(np.diag(F)))
    if np.any(sc == 0) or not np.all(np.isfinite(F)):
        raise _PassError('the Fisher information is singular')
    Fs = F / sc[:, None] / sc[None, :]
    try:
        return np.linalg.inv(Fs) / sc[:, None] / sc[None, :]
    except np.linalg.LinAlgError:
        raise _PassError('the Fisher information is singular') from None
