"""Maximum-likelihood refinement of an inertia estimate (method ``ml``).

The measurement model is the one of :mod:`inertia_ros.core.crlb`: Euler's equations driven by
the held torque, gyro white noise ``n_k ~ N(0, diag(sigma_g^2))`` and torque-sample noise
``nu_j ~ N(0, diag(sigma_t^2))`` acting as process noise held over each torque interval.
Maximum likelihood with the angular-velocity path integrated out is the Kalman
prediction-error criterion of :func:`~inertia_ros.core.crlb.prediction_error_step`; here the
same Gauss-Newton step is computed without a sequential filter:

* **multiple shooting**: every torque interval ``[s_j, s_{j+1})`` is integrated from its own
  reference state ``r_j`` (smoothed gyro at the first pass, the smoothed state afterwards),
  all intervals at once (vectorised RK4 over the whole interval,
  :class:`~inertia_ros.core.crlb.Dynamics`), with the transition ``Phi``, the torque-noise
  input ``Psi`` and the parameter sensitivities ``S``; the states and sensitivities at the
  gyro times inside an interval are cubic Hermite interpolants of the interval's ends (values
  and derivatives; error ``h^4 x/384``, orders of magnitude below the gyro noise);
* the deviations ``delta_j = w(s_j) - r_j`` are unknowns linked by the exact linearised
  continuity ``delta_{j+1} = Phi_j delta_j + g_j + S_j dp + Psi_j nu_j``; eliminating
  ``nu_j = Psi_j^-1 (...)`` leaves a least-squares problem whose rows each touch
  ``delta_j, delta_{j+1}`` and ``dp`` only: block-tridiagonal normal equations with a dense
  border, solved by a banded Cholesky factorisation and a Schur complement;
* the rows are laid out per interval (the prior rows of ``nu_j``, then the interval's gyro
  samples, padded), so the normal-equation blocks are one batched product;
* for a linear Gaussian model the minimum over the path of the joint quadratic is the
  marginal likelihood (up to a log-determinant that the bound also neglects), so the Schur
  complement is the Fisher information of ``p = [theta, d]`` with ``w0 = r_0 + delta_0`` a
  free nuisance: its inverse is the estimate's covariance, the same as the bound's at the
  estimate.

The first pass from the ``integral`` estimate moves by about one standard error; the next
passes keep its sensitivities and factorisation (chord steps: only the states are
re-integrated, a sixth of the cost), which changes the step by a fraction
``step x sigma / theta`` of itself.  A pass whose step exceeds ``_CHORD_MAX_STEP`` standard
errors or grows is a full one.  Two passes usually converge (second step ~1e-3 sigma).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..crlb import Dynamics
from ..tensor import theta_to_matrix
from .align import hermite_weights

__all__ = ['MLRefinement', 'refine']

_MAX_STEP_ANGLE = 0.02      # rad turned per RK4 substep, at most (as in crlb)
_MAX_SUBSTEPS = 256         # RK4 substeps per torque interval: beyond, ml is not worth its cost
_SIGMA_T_FLOOR = 1e-3       # torque-noise std floor, relative to the largest axis or torque rms
_CHORD_MAX_STEP = 3.0       # std errors: after a smaller step, the next pass keeps the Jacobian
#: Quadratic 9-point Savitzky-Golay smoothing weights (reference states only).
#: Largest one-call products of :func:`_thin_dot` (rows x columns, vector length): the BLAS
#: keeps to one thread below them; larger products (a momentum input's union grid) go in
#: blocks, as the BLAS threads' spinning costs more CPU than the work on a loaded machine
_ONE_THREAD_GEMV = 400_000
_ONE_THREAD_DOT = 10_000
_SMOOTH = np.array([-21.0, 14.0, 39.0, 54.0, 59.0, 54.0, 39.0, 14.0, -21.0]) / 231.0


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
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gyro samples laid out per torque interval: ``(M, K)`` slots, padded.

    Returns the interval lengths ``h (M,)`` [s], the Hermite weights ``H (M, K, 4)`` of every
    slot (:func:`.align.hermite_weights`), the slot mask ``(M, K)`` and the slot of every gyro
    sample as a flat index ``(N,)`` into ``(M, K)``.
    """
    M = len(s)
    j = np.searchsorted(s, tg, side='right') - 1          # sorted, >= 0
    counts = np.bincount(j, minlength=M)
    first = np.zeros(M, dtype=np.intp)
    np.cumsum(counts[:-1], out=first[1:])                  # each interval's first sample
    col = np.arange(len(tg)) - first[j]
    K = int(counts.max())
    h = np.append(s[1:], t_end) - s
    slot = j * K + col
    U = np.ones((M, K))
    hj = h[j]
    U.reshape(-1)[slot] = (tg - s[j]) / np.where(hj > 0, hj, 1.0)
    valid = np.zeros((M, K), dtype=bool)
    valid.reshape(-1)[slot] = True
    return h, np.stack(hermite_weights(U, h[:, None]), axis=-1), valid, slot


def _interp(H: np.ndarray, x0: np.ndarray, d0: np.ndarray, x1: np.ndarray,
            d1: np.ndarray) -> np.ndarray:
    """Hermite interpolation ``(M, K, ...)`` of per-interval end values ``x (M, ...)``."""
    M = len(x0)
    ends = np.stack([x0.reshape(M, -1), d0.reshape(M, -1), x1.reshape(M, -1),
                     d1.reshape(M, -1)], axis=1)
    return (H @ ends).reshape(H.shape[:2] + x0.shape[1:])


def _substeps(w: np.ndarray, iiu: np.ndarray, h: np.ndarray) -> int:
    """RK4 substeps per torque interval (at most ``_MAX_STEP_ANGLE`` turned per substep)."""
    hmax = float(np.max(h))
    vmax = float(np.max(np.linalg.norm(w, axis=1))) + float(
        np.max(np.linalg.norm(iiu, axis=1))) * hmax
    nsub = max(1, int(np.ceil(vmax * hmax / _MAX_STEP_ANGLE)))
    if nsub > _MAX_SUBSTEPS:          # bounded cost: the integral estimate stands
        raise _PassError(f'the body turns {vmax * hmax:.3g} rad per torque interval '
                         f'({nsub} RK4 substeps needed, at most {_MAX_SUBSTEPS})')
    return nsub


def _shoot(dyn: Dynamics, r0: np.ndarray, h: np.ndarray, H: np.ndarray, iiu: np.ndarray,
           basis: np.ndarray, n_par: int
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integrate every interval from its reference (RK4 over the whole interval at once).

    ``dyn`` integrates ``Z = [Phi | Psi | S_theta (| S_d)]`` in that order (the columns of
    ``delta_j``, ``nu_j`` and ``dp``; see :func:`_dynamics`), so the interval ends are written
    once into one ``(4, M, 3, q)`` array and interpolated from it.  Returns the states and
    sensitivities ``[Phi | Psi | S_theta basis (| S_d)]`` at the slots, ``(M, K, 3)`` and
    ``(M, K, 3, c)`` (cubic Hermite interpolation between the interval ends, whose error
    ``h^4 x''''/384`` is many orders below the gyro noise), and at the interval ends,
    ``(M, 3)`` and ``(M, 3, c)``.
    """
    M, q = len(h), n_par + 6
    ends = np.zeros((4, M, 3, q))       # Z and Z' at both ends of every interval (contiguous)
    ends[0, :, :, :3] = np.eye(3)
    nsub = _substeps(r0, iiu, h)
    d0w, ends[1] = dyn(r0, ends[0], iiu)
    w1, ends[2] = dyn.rk4(r0, ends[0], iiu, h / nsub, nsub, first=(d0w, ends[1]))
    d1w, ends[3] = dyn(w1, ends[2], iiu)
    if basis.shape[1] < 6 or not np.array_equal(basis, np.eye(6)):
        ends = np.concatenate([ends[..., :6], ends[..., 6:12] @ basis, ends[..., 12:]], axis=-1)
    Zk = (H @ ends.reshape(4, M, -1).transpose(1, 0, 2)).reshape(M, H.shape[1], 3, -1)
    return _interp(H, r0, d0w, w1, d1w), Zk, w1, ends[2]


def _shoot_states(dyn: Dynamics, r0: np.ndarray, h: np.ndarray, H: np.ndarray,
                  iiu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_shoot` without sensitivities: slot states ``(M, K, 3)``, end states ``(M, 3)``."""
    nsub = _substeps(r0, iiu, h)
    hs = (h / nsub)[:, None]
    w = r0
    d0 = dyn.rate(r0, iiu)
    for i in range(nsub):
        k1 = d0 if i == 0 else dyn.rate(w, iiu)
        k2 = dyn.rate(w + 0.5 * hs * k1, iiu)
        k3 = dyn.rate(w + 0.5 * hs * k2, iiu)
        k4 = dyn.rate(w + hs * k3, iiu)
        w = w + hs / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
    return _interp(H, r0, d0, w, dyn.rate(w, iiu)), w


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
    tg, w = _checked(tg, w, ts, tau, max_iter)
    pb = _Problem.build(tg, w, ts, tau, np.asarray(basis, dtype=float), bias0 is not None,
                        gyro_std, torque_std)
    k, bias = pb.k, pb.bias
    beta = np.linalg.lstsq(pb.basis, np.asarray(theta0, dtype=float), rcond=None)[0]
    d = np.zeros(3) if bias0 is None else np.asarray(bias0, dtype=float).copy()
    r = _reference_states(tg, w, pb.s)
    steps: list[float] = []
    cov = np.full((pb.npar, pb.npar), np.nan)
    excess = float('nan')
    lin: _Linear | None = None
    for it in range(1, max_iter + 1):
        try:
            # close to the optimum (a small, shrinking step) the sensitivities stand
            if lin is None or steps[-1] > min(_CHORD_MAX_STEP, steps[max(len(steps) - 2, 0)]):
                dp, delta, excess, lin = _full_pass(pb, beta, d, r)
            else:
                dp, delta, excess = _chord_pass(pb, lin, beta, d, r)
        except _PassError as exc:
            return MLRefinement(False, beta, d if bias else None, cov, it, excess, steps,
                                str(exc))
        cov = lin.cov
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


def _checked(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
             max_iter: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`refine`'s input checks; the gyro times and rates as float arrays."""
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
    return tg, w


class _PassError(Exception):
    """A Gauss-Newton pass that cannot go on; the message is the reason."""


@dataclass(frozen=True, eq=False)
class _Problem:
    """The fixed parts of the refinement: data, interval events, weights, parameter map."""

    n_gyro: int                # gyro samples
    s: np.ndarray              # (M,) torque samples before the last gyro sample [s]
    u: np.ndarray              # (M, 3) their torque [N m]
    h: np.ndarray              # (M,) interval lengths [s]
    H: np.ndarray              # (M, K, 4) Hermite weights of the gyro slots (see _events)
    Y: np.ndarray              # (M, K, 3) measured angular velocity per slot [rad/s] (0: none)
    swg: np.ndarray            # (M, K, 3) square-root gyro weights per slot [s/rad] (0: none)
    swt: np.ndarray            # (3,) square-root torque weights [1/(N m)]
    basis: np.ndarray          # (6, k)
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
        """Sensitivity columns of the dynamics: theta (, d)."""
        return 9 if self.bias else 6

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
        h, H, valid, slot = _events(tg, s, float(tg[-1]))
        Y = np.zeros(valid.shape + (3,))
        Y.reshape(-1, 3)[slot] = w
        st = np.asarray(torque_std, dtype=float)
        floor = _SIGMA_T_FLOOR * max(float(np.max(st)),
                                     float(np.max(np.sqrt(np.mean(u ** 2, 0)))))
        swg = valid[..., None] / np.asarray(gyro_std, dtype=float)
        return _Problem(len(tg), s, u, h, H, Y, swg, 1.0 / np.maximum(st, floor), basis,
                        bias)


def _reference_states(tg: np.ndarray, w: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Reference states (M + 1, 3) at the interval starts and the end: the smoothed gyro.

    A 9-point quadratic Savitzky-Golay smoother (the raw gyro at the four samples of either
    end): only the linearisation point, which the passes correct.
    """
    ws = w
    if len(tg) >= 2 * _SMOOTH.size:
        ws = w.copy()
        for c in range(3):
            ws[4:-4, c] = np.convolve(w[:, c], _SMOOTH, mode='valid')
    bounds = np.append(s, tg[-1])
    return np.column_stack([np.interp(bounds, tg, ws[:, c]) for c in range(3)])


@dataclass(frozen=True, eq=False)
class _Linear:
    """The linearisation of one full pass, reused by the chord passes that follow it.

    ``Xc (M, 3 + 3 K, 6 + npar)``: the weighted row coefficients of every interval (the
    prior rows of ``nu_j``, then the gyro slots) on ``[delta_j, delta_{j+1}, dp]``.
    """

    Xc: np.ndarray
    X6: np.ndarray             # (M, 3 + 3 K, 6) Xc's path columns (a view)
    Xf: np.ndarray             # (M (3 + 3 K), npar) Xc's parameter columns (a view)
    Pinv: np.ndarray           # (M, 3, 3) inverse torque-noise input matrices
    Zpsi: np.ndarray           # (M, K, 3, 3) torque-noise input at the gyro slots
    cb: np.ndarray             # banded Cholesky factor of the path block
    Dpf: np.ndarray            # (3 (M + 1), npar) border
    X1: np.ndarray             # (3 (M + 1), npar) path block^-1 border
    cov: np.ndarray            # (npar, npar) inverse Fisher information


def _dynamics(pb: _Problem, beta: np.ndarray, d: np.ndarray) -> tuple[Dynamics, np.ndarray]:
    """The dynamics at ``beta`` and ``I^-1 (u + d)`` per interval; :class:`_PassError` when the
    tensor is not positive definite."""
    Im = theta_to_matrix(pb.basis @ beta)
    if not np.all(np.isfinite(Im)) or np.linalg.eigvalsh(Im)[0] <= 0:
        raise _PassError('the tensor left the positive-definite set')
    # columns [Phi | Psi | S_theta (| S_d)]: delta_j, nu_j, dp (no copies to rearrange)
    dyn = Dynamics(Im, pb.n_par, pb.bias, bias_at=12, theta_at=6, psi_at=3)
    return dyn, (pb.u + d) @ dyn.Ii.T


def _full_pass(pb: _Problem, beta: np.ndarray, d: np.ndarray, r: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, float, _Linear]:
    """One Gauss-Newton pass with new sensitivities: step, path correction, excess, model.

    Raises :class:`_PassError` when the tensor, the torque-noise input or the information
    matrix make the pass impossible.
    """
    from scipy import linalg  # lazily: 0.14 s of start-up the integral path never needs
    M, npar = pb.M, pb.npar
    dyn, iiu = _dynamics(pb, beta, d)
    # sensitivities as [Phi | Psi | S_p]: on delta_j, nu_j and dp
    wk, Zk, w1, Z1 = _shoot(dyn, r[:-1], pb.h, pb.H, iiu, pb.basis, pb.n_par)
    Pinv = _inverse3(Z1[..., 3:6])
    # prior rows of nu_j = Pinv (delta_{j+1} - Phi delta_j - S dp - g_j): on delta_j,
    # delta_{j+1}, dp
    B = -Z1
    B[..., 3:6] = np.eye(3)
    R = Pinv @ B
    # gyro rows: the slot's own sensitivities, with nu_j eliminated through the prior row
    K = pb.H.shape[1]
    Zk2 = Zk.reshape(M, 3 * K, -1)
    Zpsi = np.ascontiguousarray(Zk2[..., 3:6])               # (M, 3 K, 3)
    Zk2[..., 3:6] = 0.0          # the slot's nu_j columns are all in Zpsi R (eliminated nu_j)
    Xc = np.empty((M, 3 + 3 * K, 6 + npar))                 # written in place, no copies
    # (einsum: np.multiply broadcasting into these strided views takes 2-4x as long)
    np.einsum('mrc,r->mrc', R, pb.swt, out=Xc[:, :3])
    rows = Zpsi @ R                        # contiguous, then one strided write into Xc
    rows += Zk2
    np.einsum('mr,mrc->mrc', pb.swg.reshape(M, 3 * K), rows, out=Xc[:, 3:])
    Zpsi = Zpsi.reshape(M, K, 3, 3)
    X6 = Xc[..., :6]                     # (a view: the products are as fast as on a copy)
    Gm = X6.transpose(0, 2, 1) @ Xc                             # (M, 6, 6 + npar)
    Xf = Xc[..., 6:].reshape(-1, npar)                          # (a view)
    D = np.zeros((M + 1, 3, 3))
    D[:-1] += Gm[:, :3, :3]
    D[1:] += Gm[:, 3:6, 3:6]
    Dp = np.zeros((M + 1, 3, npar))
    Dp[:-1] += Gm[:, :3, 6:]
    Dp[1:] += Gm[:, 3:6, 6:]
    try:
        cb = linalg.cholesky_banded(_banded(D, Gm[:, :3, 3:6]), lower=False,
                                    check_finite=False)
        if not np.all(np.isfinite(cb)):
            raise linalg.LinAlgError
    except linalg.LinAlgError:
        raise _PassError('the path normal equations are not positive definite') from None
    Dpf = Dp.reshape(3 * (M + 1), npar)
    X1 = linalg.cho_solve_banded((cb, False), Dpf, check_finite=False)
    F = Xf.T @ Xf - Dpf.T @ X1
    lin = _Linear(Xc, X6, Xf, Pinv, Zpsi, cb, Dpf, X1,
                  _inverse_information(0.5 * (F + F.T)))
    dp, delta, excess = _step(pb, lin, wk, w1, r)
    return dp, delta, excess, lin


def _chord_pass(pb: _Problem, lin: _Linear, beta: np.ndarray, d: np.ndarray, r: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """A pass with the previous pass's sensitivities: new residuals, same linear model.

    Near the optimum the sensitivities change by a fraction ``step x sigma / theta`` of
    themselves, so the step agrees with a full pass to that fraction at a sixth of the cost
    (states only, no factorisation).
    """
    dyn, iiu = _dynamics(pb, beta, d)
    wk, w1 = _shoot_states(dyn, r[:-1], pb.h, pb.H, iiu)
    return _step(pb, lin, wk, w1, r)


def _step(pb: _Problem, lin: _Linear, wk: np.ndarray, w1: np.ndarray, r: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, float]:
    """Gauss-Newton step of the linear model ``lin`` for the residuals of states ``wk, w1``."""
    from scipy import linalg  # lazily: 0.14 s of start-up the integral path never needs
    M = pb.M
    pz = (lin.Pinv @ (w1 - r[1:])[..., None])[..., 0]           # prior targets (M, 3)
    K = lin.Zpsi.shape[1]
    gz = (lin.Zpsi.reshape(M, 3 * K, 3) @ pz[..., None]).reshape(M, K, 3)   # gyro targets
    gz += pb.Y
    gz -= wk
    Xz = np.concatenate([pz * pb.swt, (gz * pb.swg).reshape(M, -1)], axis=1)
    Gz = (Xz[:, None] @ lin.X6)[:, 0]                             # (M, 6)
    bd = np.zeros((M + 1, 3))
    bd[:-1] += Gz[:, :3]
    bd[1:] += Gz[:, 3:6]
    bd = bd.ravel()
    bp = _thin_dot(Xz.ravel(), lin.Xf)
    X0 = linalg.cho_solve_banded((lin.cb, False), bd, check_finite=False)
    dp = lin.cov @ (bp - lin.Dpf.T @ X0)
    delta = X0 - lin.X1 @ dp
    rss = float(np.sum(Xz * Xz)) - float(_thin_dot(bd, delta)) - float(bp @ dp)
    return dp, delta, rss / max(3 * pb.n_gyro - 3 - pb.npar, 1)


def _thin_dot(x: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``x @ A`` for ``x`` (n,) and ``A`` (n,) or (n, k), in blocks of rows above the sizes the
    BLAS computes on one thread (below them the single call, bit for bit)."""
    k = A.shape[1] if A.ndim == 2 else 1
    rows = _ONE_THREAD_GEMV // k if A.ndim == 2 else _ONE_THREAD_DOT
    if len(x) <= rows:
        return x @ A
    out = x[:rows] @ A[:rows]
    for a in range(rows, len(x), rows):
        out = out + x[a:a + rows] @ A[a:a + rows]
    return out


def _inverse3(A: np.ndarray) -> np.ndarray:
    """Inverses of a stack of 3 x 3 matrices ``(M, 3, 3)`` by their adjugates (a tenth of
    ``np.linalg.inv``'s time on small matrices); :class:`_PassError` when one is singular."""
    a, b, c = A[..., 0, 0], A[..., 0, 1], A[..., 0, 2]
    d, e, f = A[..., 1, 0], A[..., 1, 1], A[..., 1, 2]
    g, h, i = A[..., 2, 0], A[..., 2, 1], A[..., 2, 2]
    adj = np.empty(A.shape)
    adj[..., 0, 0] = e * i - f * h
    adj[..., 1, 0] = f * g - d * i
    adj[..., 2, 0] = d * h - e * g
    adj[..., 0, 1] = c * h - b * i
    adj[..., 1, 1] = a * i - c * g
    adj[..., 2, 1] = b * g - a * h
    adj[..., 0, 2] = b * f - c * e
    adj[..., 1, 2] = c * d - a * f
    adj[..., 2, 2] = a * e - b * d
    det = a * adj[..., 0, 0] + b * adj[..., 1, 0] + c * adj[..., 2, 0]
    scale = np.max(np.abs(A), axis=(-2, -1)) ** 3
    if not np.all(np.abs(det) > 1e-13 * scale):
        raise _PassError('singular torque-noise input matrix')
    return adj / det[..., None, None]


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
