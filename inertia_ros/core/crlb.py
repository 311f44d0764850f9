"""Cramer-Rao lower bound for the inertia tensor from gyro + known-torque streams.

The physical limit of any unbiased estimator on a scene: the inverse of the Fisher information
of the measurement model with the scene's true noise.

Model
-----
The body obeys Euler's equations about its centre of mass, in body axes,

    I w_dot + w x (I w) = u(t) + d,        w(t0) = w0,

with ``u`` the torque actually applied, held constant (zero-order hold) on every torque
interval ``[s_j, s_{j+1})``.  The data are

* gyro samples ``y_k = w(t_k) + n_k``, ``n_k ~ N(0, diag(sigma_g^2))`` white;
* torque samples ``tau_j = u_j + nu_j``, ``nu_j ~ N(0, diag(sigma_t^2))`` white.

Conditioning on the measured torques, the applied torque is ``u_j = tau_j - nu_j``: the torque
noise enters as *process noise* on the dynamics, constant over each torque interval.  The
unknowns are ``p = [theta (6), w0 (3)]`` and, when requested, the constant unmeasured
disturbance ``d (3)`` (``theta = [ixx, iyy, izz, ixy, ixz, iyz]``).

Linearising the dynamics about the noise-free trajectory ``m_k(p)`` (driven by the true held
torque) gives a linear Gaussian state-space model for the deviation ``x_k = [dw_k, nu]``:

    dw_{k+1} = Phi_k dw_k + Psi_k nu,   nu redrawn at every torque sample,
    y_k - m_k(p) = dw_k + n_k.

``y`` is then Gaussian with mean ``m(p)`` and a covariance ``R`` that does not depend on ``p``
to first order, so the Fisher information is ``F = J' R^-1 J`` with ``J = dm/dp``.  ``R^-1/2``
is applied by a Kalman filter (Gupta & Mehra, 1974): run on the sensitivities ``-dm_k/dp``
its innovations are ``de_k/dp`` and

    F = sum_k (de_k/dp)' S_k^-1 (de_k/dp),     S_k the innovation covariance.

With no torque noise the filter gain is zero and ``F = sum_k J_k' J_k / sigma_g^2``.

Equivalently, treat the true held commands ``u_j`` as nuisance parameters, each measured once
by ``tau_j`` with information ``sigma_t^-2``: by the Woodbury identity the Schur complement of
the joint information of ``(p, u)`` is ``J' (S_g + J_u S_t J_u')^-1 J``, the same ``F``.

The trajectory, its parameter sensitivities (variational equations) and the per-interval
transition matrices ``Phi_k`` and input matrices ``Psi_k`` are integrated together with the
classical Runge-Kutta scheme on the merged grid of gyro and torque times.

Assumptions (what the bound does not cover): sensors sample at their stamps (no jitter, delay
or dropped samples), no gyro bias, a constant tensor (no inertia change), Gaussian white
noise with known variances, and the derivative of the noise covariance with respect to ``p``
neglected (the term ``1/2 tr(S^-1 dS S^-1 dS)``: its relative size is of the order of the
torque-noise-to-signal ratio squared).  The bound is local: for an unbiased estimator at the
true parameters.  Nuisance parameters the estimators also estimate (``w0`` always, ``d`` when
a torque bias is fitted) are part of ``p`` and so inflate the bound on ``theta`` exactly as
they should.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validate import as_noise_std, as_times
from .estimation.model import BIAS_NAMES
from .estimation.regressors import GYROSCOPIC_MAP, MOMENTUM_MAP, MONOMIAL_I, MONOMIAL_J
from .tensor import THETA_COLS, THETA_NAMES, THETA_ROWS

__all__ = ['FisherResult', 'PredictionErrorStep', 'cumulative_information',
           'fisher_information', 'frobenius_weights', 'prediction_error_step', 'scene_fisher']

#: Rows per product of :meth:`Dynamics.__call__`'s ``(n, 9) x (9, 18)`` map: above about 6 000
#: rows OpenBLAS wakes its threads, whose spinning cost 10x the product's CPU (``ml`` on a
#: 300 s record: 2.1 against 0.2 ms a call)
_ONE_THREAD_ROWS = 4096
_MAX_STEP_ANGLE = 0.02                          # rad turned per RK4 substep, at most
_TIME_TOL = 1e-9                                # s: times closer than this are merged


@dataclass(frozen=True, eq=False)
class FisherResult:
    """Fisher information of one record and the bound it implies.

    Attributes
    ----------
    information : numpy.ndarray, shape (p, p)
        Fisher information of ``p = [theta (6), w0 (3)(, d (3))]`` in SI units
        (theta [kg m^2], w0 [rad/s], d [N m]).
    names : tuple of str
        Parameter names, ``THETA_NAMES`` then ``wx0 wy0 wz0`` (then ``dx dy dz``).
    omega : numpy.ndarray, shape (N, 3)
        Noise-free model trajectory at the gyro times [rad/s].
    sensitivity : numpy.ndarray, shape (N, 3, p)
        ``d omega_k / d p`` at the gyro times.
    """

    information: np.ndarray
    names: tuple[str, ...]
    omega: np.ndarray
    sensitivity: np.ndarray

    def covariance(self) -> np.ndarray:
        """Cramer-Rao bound on the covariance of all parameters, shape (p, p).

        Returns
        -------
        numpy.ndarray, shape (p, p)
            ``F^-1`` (column-scaled inverse); ``inf`` on the diagonal when ``F`` is singular.
        """
        F = self.information
        d = np.sqrt(np.diag(F))
        if np.any(d <= 0) or not np.all(np.isfinite(F)):
            return np.full(F.shape, np.inf)
        Fs = F / d[:, None] / d[None, :]
        if np.linalg.cond(Fs) > 1e14:
            return np.full(F.shape, np.inf)
        return np.linalg.inv(Fs) / d[:, None] / d[None, :]

    def theta_covariance(self) -> np.ndarray:
        """Bound on the covariance of ``theta`` [kg^2 m^4], shape (6, 6), nuisances included."""
        return self.covariance()[:6, :6]

    def theta_std(self) -> np.ndarray:
        """Bound on the standard deviation of each tensor element [kg m^2], shape (6,)."""
        return np.sqrt(np.diag(self.theta_covariance()))

    def frobenius_mse(self) -> float:
        """Bound on ``E ||I_hat - I||_F^2`` [kg^2 m^4] (off-diagonal elements count twice)."""
        return float(frobenius_weights() @ np.diag(self.theta_covariance()))


def frobenius_weights() -> np.ndarray:
    """Weights ``w`` with ``||theta_to_matrix(e)||_F^2 = sum_i w_i e_i^2``, shape (6,)."""
    return np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0])


# The bilinear terms of Euler's equation as products with constant matrices (the regressor
# maps of the estimators): for any ``v`` and ``w``, ``([v, mono(w)] @ _Y_MAP).reshape(3, 6)``
# has columns ``E_k v + w x (E_k w)``, and ``w x (I w) = mono(w) @ (_GYRO_MAP @ theta)``.
_Y_MAP = np.vstack([MOMENTUM_MAP, GYROSCOPIC_MAP])          # (9, 18)
_GYRO_MAP = GYROSCOPIC_MAP.reshape(6, 3, 6)


class Dynamics:
    """Right-hand side of the state, sensitivity, transition and input equations.

    ``w x (I w) = G(mono(w)) theta`` and its Jacobian in ``w`` are linear in ``w`` (or in the
    monomials), so each evaluation is a handful of small matrix products.
    """

    def __init__(self, inertia: np.ndarray, n_par: int, bias: bool, bias_at: int = 9,
                 theta_at: int = 0, psi_at: int | None = None) -> None:
        """``n_par`` sensitivity columns ``[theta (6), w0 (3), d (3)]`` (``d`` when ``bias``,
        its columns from ``bias_at``: 6 for a layout without ``w0``).

        ``theta_at`` and ``psi_at`` place the six ``theta`` and the three ``Psi`` columns
        elsewhere in ``Z`` (default: ``theta`` first, ``Psi`` last, ``Phi`` before it); a
        caller that wants ``[Phi | Psi | S]`` integrates it in that order and copies nothing.
        """
        self.I = inertia
        self.Ii = np.linalg.inv(inertia)
        theta = inertia[THETA_ROWS, THETA_COLS]
        # w x (I w) = mono(w) @ gyro_w  (6, 3)
        self.gyro_w = _GYRO_MAP @ theta
        # Jacobian of w x (I w) in w: d/dw_c of mono(w) @ gyro_w, linear in w:
        # dmono_m/dw_c = w_i [c == j] + w_j [c == i]  ->  jac(w)[r, c] = sum_a w_a Jm[a, r, c]
        Jm = np.zeros((3, 3, 3))
        for m, (i, j) in enumerate(zip(MONOMIAL_I, MONOMIAL_J, strict=True)):
            Jm[i, :, j] += self.gyro_w[m]
            Jm[j, :, i] += self.gyro_w[m]
        self.jac_w = -np.einsum('rs,asc->arc', self.Ii, Jm).reshape(3, 9)   # Jw = -Ii jac
        self.gyro_wd = -(self.gyro_w @ self.Ii.T)     # mono @ gyro_wd = -Ii (w x I w)
        self.n_par = n_par
        psi = n_par + 3 if psi_at is None else psi_at
        # constant columns of the linear part: Psi' = Jw Psi + I^-1 (and d(w_dot)/dd = I^-1),
        # added as one contiguous (3, q) row (zeros elsewhere) rather than strided slices
        self.forcing = np.zeros((3, n_par + 6))
        for c in [psi] + ([bias_at] if bias else []):
            self.forcing[:, c:c + 3] = self.Ii
        self.theta = slice(theta_at, theta_at + 6)
        # -I^-1 Y(wd, mono) as one product with the (9, 18) map: no batched 3 x 3 products
        self.y_map = np.einsum('Rr,irk->iRk', -self.Ii, _Y_MAP.reshape(9, 3, 6)).reshape(9, 18)

    def __call__(self, w: np.ndarray, Z: np.ndarray, Iiu: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """``(w_dot, Z_dot)`` with ``Z = [S (3, p) | Phi (3, 3) | Psi (3, 3)]`` (or the
        constructor's layout).

        ``Iiu`` is ``I^-1 (u + d)`` for the interval.  Leading batch dimensions are allowed:
        ``w (..., 3)``, ``Z (..., 3, p + 6)``, ``Iiu (..., 3)`` (many intervals at once, as
        :mod:`inertia_ros.core.estimation.ml` integrates them).
        """
        mono = w[..., MONOMIAL_I] * w[..., MONOMIAL_J]
        wd = Iiu + mono @ self.gyro_wd
        Jw = (w @ self.jac_w).reshape(w.shape[:-1] + (3, 3))
        # Y[:, k] = E_k wd + w x (E_k w): regressor of Euler's equation in theta; -I^-1 Y
        x = np.concatenate((wd, mono), axis=-1).reshape(-1, 9)
        mIiY = np.empty((len(x), 18))
        for a in range(0, len(x), _ONE_THREAD_ROWS):      # (the BLAS on one thread, below)
            np.matmul(x[a:a + _ONE_THREAD_ROWS], self.y_map, out=mIiY[a:a + _ONE_THREAD_ROWS])
        mIiY = mIiY.reshape(w.shape[:-1] + (3, 6))
        Zd = Jw @ Z
        Zd += self.forcing
        Zd[..., self.theta] += mIiY
        return wd, Zd

    def rate(self, w: np.ndarray, Iiu: np.ndarray) -> np.ndarray:
        """``w_dot`` alone (no sensitivities), shape of ``w``."""
        mono = w[..., MONOMIAL_I] * w[..., MONOMIAL_J]
        return Iiu + mono @ self.gyro_wd

    def rk4(self, w: np.ndarray, Z: np.ndarray, Iiu: np.ndarray, h: float | np.ndarray,
            n: int, first: tuple[np.ndarray, np.ndarray] | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
        """``n`` classical RK4 steps of length ``h`` [s] from ``(w, Z)`` under constant ``Iiu``.

        ``h`` is a scalar, or one step length per leading batch index of ``w`` (shape
        ``w.shape[:-1]``: every interval of a batch integrated at once).  ``first``: the
        derivatives ``self(w, Z, Iiu)`` at the start, when the caller already has them.
        """
        if isinstance(h, float):
            hw = hz = h
        else:
            hw = np.asarray(h, dtype=float)[..., None]  # broadcasts over w's last axis
            hz = hw[..., None]                          # and over Z's last two
        for i in range(n):
            k1w, k1 = first if i == 0 and first is not None else self(w, Z, Iiu)
            k2w, k2 = self(w + 0.5 * hw * k1w, Z + 0.5 * hz * k1, Iiu)
            k3w, k3 = self(w + 0.5 * hw * k2w, Z + 0.5 * hz * k2, Iiu)
            k4w, k4 = self(w + hw * k3w, Z + hz * k3, Iiu)
            w = w + hw / 6.0 * (k1w + 2.0 * (k2w + k3w) + k4w)
            Z = Z + hz / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
        return w, Z


def _validated(t_gyro: Any, t_torque: Any, torque: Any, inertia: Any, omega0: Any,
               gyro_std: Any, torque_std: Any, disturbance: Any) -> tuple[Any, ...]:
    """Validate the common arguments; return ``(tg, ts, tau, I, w0, sg, st, d)``."""
    tg = as_times(t_gyro, 't_gyro', min_samples=2, detail=False)
    ts = np.asarray(t_torque, dtype=float)
    if ts.ndim != 1 or not np.all(np.isfinite(ts)) or np.any(np.diff(ts) <= 0):
        raise ValueError('t_torque: expected strictly increasing finite times, shape (M,)')
    tau = np.asarray(torque, dtype=float)
    if tau.shape != (ts.size, 3) or not np.all(np.isfinite(tau)):
        raise ValueError(f'torque: expected finite shape ({ts.size}, 3), got {tau.shape}')
    I = np.asarray(inertia, dtype=float)
    if I.shape != (3, 3) or not np.allclose(I, I.T, rtol=1e-9, atol=1e-15) \
            or np.linalg.eigvalsh(0.5 * (I + I.T))[0] <= 0:
        raise ValueError('inertia: must be a symmetric positive definite (3, 3) matrix')
    I = 0.5 * (I + I.T)
    w0 = np.asarray(omega0, dtype=float)
    if w0.shape != (3,) or not np.all(np.isfinite(w0)):
        raise ValueError(f'omega0: expected a finite 3-vector, got shape {w0.shape}')
    sg = as_noise_std(gyro_std, 'gyro_std', what=' (scalar or 3 values)')
    if np.any(sg <= 0):
        raise ValueError(f'gyro_std: must be > 0, got {gyro_std!r}')
    st = as_noise_std(torque_std, 'torque_std', what=' (scalar or 3 values)')
    d = np.zeros(3) if disturbance is None else np.asarray(disturbance, dtype=float)
    if d.shape != (3,) or not np.all(np.isfinite(d)):
        raise ValueError(f'disturbance: expected a finite 3-vector, got {disturbance!r}')

    return tg, ts, tau, I, w0, sg, st, d


@dataclass(frozen=True, eq=False)
class _Pass:
    """Output of one filter pass."""

    information: np.ndarray
    names: tuple[str, ...]
    omega: np.ndarray
    sensitivity: np.ndarray
    gradient: np.ndarray | None
    cost: float
    partial: tuple[np.ndarray, ...] = ()


def _merged_grid(tg: np.ndarray, ts: np.ndarray, tau: np.ndarray, d: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The filter's time grid: gyro times and the torque samples inside the record.

    Returns
    -------
    grid : ndarray, shape (G,)
        Merged times [s] (closer than ``_TIME_TOL`` merged).
    is_gyro, new_tau : ndarray of bool, shape (G,)
        A gyro sample at ``grid[i]``; a new torque sample takes effect at ``grid[i]``.
    u_grid : ndarray, shape (G, 3)
        Torque (plus ``d``) in effect on ``[grid_i, grid_{i+1})`` [N m].
    """
    inside = ts[(ts > tg[0] + _TIME_TOL) & (ts < tg[-1] - _TIME_TOL)]
    grid = np.union1d(tg, inside)
    grid = grid[np.concatenate([[True], np.diff(grid) > _TIME_TOL])]
    is_gyro = np.zeros(grid.size, dtype=bool)
    is_gyro[np.clip(np.searchsorted(grid, tg - _TIME_TOL), 0, grid.size - 1)] = True
    # torque sample index in effect on [grid_i, grid_{i+1}) and where a new one starts
    j_of = np.searchsorted(ts, grid + _TIME_TOL, side='right') - 1
    new_tau = np.zeros(grid.size, dtype=bool)
    new_tau[0] = j_of[0] >= 0
    new_tau[1:] = (j_of[1:] != j_of[:-1]) & (j_of[1:] >= 0)
    u_grid = np.where((j_of >= 0)[:, None], tau[np.clip(j_of, 0, None)], 0.0) + d
    return grid, is_gyro, new_tau, u_grid


def _step(dyn: Dynamics, w: np.ndarray, S: np.ndarray, Z: np.ndarray, u: np.ndarray,
          h_total: float, Ii_norm: float) -> tuple[np.ndarray, np.ndarray]:
    """State and ``Z = [S, Phi, Psi]`` over one grid interval, in RK4 substeps of at most
    ``_MAX_STEP_ANGLE`` of rotation (``Z`` (3, n_par + 6) is reused as the work array)."""
    n_par = dyn.n_par
    wmax = float(np.linalg.norm(w)) + Ii_norm * float(np.linalg.norm(u)) * h_total
    n = max(1, math.ceil(wmax * h_total / _MAX_STEP_ANGLE))
    Z[:, :n_par] = S
    Z[:, n_par:n_par + 3] = np.eye(3)
    Z[:, n_par + 3:] = 0.0
    return dyn.rk4(w, Z, dyn.Ii @ u, h_total / n, n)


def _kalman_pass(tg: np.ndarray, ts: np.ndarray, tau: np.ndarray, I: np.ndarray,
                 w0: np.ndarray, sg: np.ndarray, st: np.ndarray, d: np.ndarray, *, bias: bool,
                 y: np.ndarray | None, counts: tuple[int, ...] = ()) -> _Pass:
    """Trajectory, sensitivities and the Kalman filter; with data ``y`` also the innovations.

    ``F = sum de' S^-1 de``; with ``y`` the gradient ``sum de' S^-1 e`` and the cost
    ``1/2 sum e' S^-1 e`` of the prediction-error criterion at these parameters; ``partial``:
    ``F`` of the first ``counts[k]`` (ascending) gyro samples (causal: the record cut there).
    """
    n_par = 12 if bias else 9
    names = tuple(THETA_NAMES) + ('wx0', 'wy0', 'wz0') + (BIAS_NAMES if bias else ())

    grid, is_gyro, new_tau, u_grid = _merged_grid(tg, ts, tau, d)
    dyn = Dynamics(I, n_par, bias)
    Ii_norm = float(np.linalg.norm(dyn.Ii, 2))
    R = np.diag(sg ** 2)
    Qnu = np.diag(st ** 2)
    noisy = bool(np.any(st > 0))

    w = w0.copy()
    S = np.zeros((3, n_par))
    S[:, 6:9] = np.eye(3)
    P = np.zeros((6, 6))            # covariance of [dw, nu] (prior)
    D = np.zeros((6, n_par))        # sensitivity of the predicted deviation state
    F = np.zeros((n_par, n_par))
    grad = np.zeros(n_par)
    cost = 0.0
    xhat = np.zeros(6)              # predicted deviation state (data pass only)
    omega_out = np.empty((tg.size, 3))
    sens_out = np.empty((tg.size, 3, n_par))
    g = 0
    Z, partial = np.zeros((3, n_par + 6)), []
    for i in range(grid.size):
        if is_gyro[i]:
            omega_out[g] = w
            sens_out[g] = S
            g += 1
            # innovation sensitivities: de = -(S + H D), H = [I 0]
            de = -(S + D[:3])
            Sk = P[:3, :3] + R
            Sinv = np.linalg.inv(Sk)
            F += de.T @ Sinv @ de
            while len(partial) < len(counts) and counts[len(partial)] <= g:
                partial.append(0.5 * (F + F.T))
            if y is not None:
                e = y[g - 1] - w - xhat[:3]
                Se = Sinv @ e
                grad += de.T @ Se
                cost += 0.5 * float(e @ Se)
            if noisy:
                K = P[:, :3] @ Sinv                   # (6, 3)
                D = D + K @ de
                if y is not None:
                    xhat = xhat + K @ e
                P = P - K @ P[:3, :]
                P = 0.5 * (P + P.T)
        if noisy and new_tau[i]:
            # a new torque sample: its noise is independent of everything before
            P[3:, :] = 0.0
            P[:, 3:] = 0.0
            P[3:, 3:] = Qnu
            D[3:] = 0.0
            xhat[3:] = 0.0
        if i == grid.size - 1:
            break
        w, Z = _step(dyn, w, S, Z, u_grid[i], grid[i + 1] - grid[i], Ii_norm)
        S = Z[:, :n_par].copy()
        if noisy:
            Phi = Z[:, n_par:n_par + 3]
            Psi = Z[:, n_par + 3:]
            A = np.eye(6)
            A[:3, :3] = Phi
            A[:3, 3:] = Psi
            P = A @ P @ A.T
            D = A @ D
            xhat = A @ xhat
    F = 0.5 * (F + F.T)
    return _Pass(F, names, omega_out, sens_out, grad if y is not None else None, cost,
                 tuple(partial))


def fisher_information(t_gyro: Any, t_torque: Any, torque: Any, inertia: Any, omega0: Any, *,
                       gyro_std: Any, torque_std: Any = 0.0, disturbance: Any = None,
                       estimate_bias: bool = False) -> FisherResult:
    """Fisher information of the tensor (and nuisances) for one gyro + torque record.

    Parameters
    ----------
    t_gyro : array_like, shape (N,)
        Gyro sample times [s], strictly increasing; ``omega0`` is the rate at ``t_gyro[0]``.
    t_torque : array_like, shape (M,)
        Torque sample times [s], strictly increasing; the torque is held from each sample
        to the next (and after the last one); zero before the first.
    torque : array_like, shape (M, 3)
        True applied (held) torque [N m], body axes (the measured values minus their noise).
    inertia : array_like, shape (3, 3)
        True tensor about the centre of mass [kg m^2].
    omega0 : array_like, shape (3,)
        True angular velocity at ``t_gyro[0]`` [rad/s].
    gyro_std : float or array_like (3,)
        Gyro white-noise std per axis [rad/s], > 0.
    torque_std : float or array_like (3,)
        Std of the noise on each torque sample, per axis [N m] (process noise held over the
        torque interval).
    disturbance : array_like (3,), optional
        Constant unmeasured torque acting on the body [N m] (default zero).
    estimate_bias : bool
        Treat the disturbance as three unknown nuisance parameters.

    Returns
    -------
    FisherResult
        Information matrix, names, trajectory and sensitivities.

    Raises
    ------
    ValueError
        Malformed shapes, non-finite values, non-increasing times, ``gyro_std`` not positive,
        or a tensor that is not symmetric positive definite.
    """
    args = _validated(t_gyro, t_torque, torque, inertia, omega0, gyro_std, torque_std,
                      disturbance)
    p = _kalman_pass(*args, bias=bool(estimate_bias), y=None)
    return FisherResult(information=p.information, names=p.names, omega=p.omega,
                        sensitivity=p.sensitivity)


def cumulative_information(t_gyro: Any, t_torque: Any, torque: Any, inertia: Any,
                           omega0: Any, times: Any, *, gyro_std: Any, torque_std: Any = 0.0
                           ) -> np.ndarray:
    """Fisher information of the record cut at each of ``times``, in one filter pass.

    Arguments as :func:`fisher_information` (no disturbance, no bias); ``times`` (K,) [s],
    ascending.  Returns shape (K, 9, 9): entry ``k`` is the information of the gyro samples
    at or before ``times[k]`` (the filter is causal: the same as :func:`fisher_information`
    of the record cut at ``times[k]``); zero where fewer than 2 samples are.
    """
    args = _validated(t_gyro, t_torque, torque, inertia, omega0, gyro_std, torque_std, None)
    tk = np.asarray(times, dtype=float).reshape(-1)
    if np.any(np.diff(tk) < 0):
        raise ValueError('times: expected ascending times')
    counts = np.searchsorted(args[0], tk + 1e-9, side='right')
    use = tuple(int(c) for c in counts if c >= 2)
    p = _kalman_pass(*args, bias=False, y=None, counts=use)
    out = np.zeros((tk.size, 9, 9))
    out[counts >= 2] = np.array(p.partial).reshape(-1, 9, 9)
    return out


def scene_fisher(sim: Any, *, estimate_bias: bool | None = None) -> FisherResult:
    """Fisher information of a simulated scene record (``simulation.simulate`` output).

    Uses the true held commands at the torque sample times, the scene's true noise
    (``gyro.noise_std``; torque noise ``noise_std + noise_rel * rms(command)`` per axis) and
    its disturbance.  Stamps are taken as exact (the bound ignores jitter, delay and drops).

    Parameters
    ----------
    sim : SimResult
        A simulated record; its scene must have gyro noise and no inertia change.
    estimate_bias : bool, optional
        Include the disturbance torque as nuisance parameters; default: when the scene has a
        non-zero disturbance.

    Returns
    -------
    FisherResult

    Raises
    ------
    ValueError
        The record has an inertia change, no gyro noise, or too few samples.
    """
    if getattr(sim, 'inertia_changes', ()):
        raise ValueError('sim: the bound assumes a constant tensor; this record has an inertia '
                         'change')
    scene = sim.scene
    if scene.gyro.noise_std <= 0:
        raise ValueError('sim: the scene has no gyro noise (the bound would be zero)')
    cmd = np.asarray(sim.torque_command, dtype=float)
    rms = np.sqrt(np.mean(cmd ** 2, axis=0)) if cmd.size else np.zeros(3)
    tstd = scene.torque_sensor.noise_std + scene.torque_sensor.noise_rel * rms
    dist = np.asarray(sim.torque_bias_true, dtype=float)
    if estimate_bias is None:
        estimate_bias = bool(np.any(dist != 0))
    return fisher_information(sim.t_gyro, sim.t_torque, cmd, sim.inertia,
                              np.asarray(sim.omega_true[0], dtype=float),
                              gyro_std=scene.gyro.noise_std, torque_std=tstd,
                              disturbance=dist, estimate_bias=estimate_bias)


@dataclass(frozen=True, eq=False)
class PredictionErrorStep:
    """One Gauss-Newton step of the prediction-error (maximum-likelihood) criterion.

    Attributes
    ----------
    step : numpy.ndarray, shape (p,)
        ``-F^-1 g``: the parameter update, same order as ``names``.
    information : numpy.ndarray, shape (p, p)
        ``F`` at the current parameters (Gauss-Newton Hessian = Fisher information).
    gradient : numpy.ndarray, shape (p,)
        ``g = sum_k (de_k/dp)' S_k^-1 e_k``.
    cost : float
        ``1/2 sum_k e_k' S_k^-1 e_k`` (dimensionless).
    names : tuple of str
        Parameter names.
    """

    step: np.ndarray
    information: np.ndarray
    gradient: np.ndarray
    cost: float
    names: tuple[str, ...]


def prediction_error_step(t_gyro: Any, omega: Any, t_torque: Any, torque: Any, inertia: Any,
                          omega0: Any, *, gyro_std: Any, torque_std: Any = 0.0,
                          disturbance: Any = None, estimate_bias: bool = False
                          ) -> PredictionErrorStep:
    """Gauss-Newton step of the maximum-likelihood criterion of the same model as the bound.

    The innovations ``e_k`` of the Kalman filter of :func:`fisher_information`, run on the
    measured gyro ``omega`` with the trajectory driven by the *measured* torque, are white
    with covariance ``S_k`` when the parameters are right; minimising
    ``1/2 sum e_k' S_k^-1 e_k`` is maximum likelihood, asymptotically efficient (it attains
    the bound).  A prototype refinement used by the benchmark (``pem_refine``), started from
    a consistent estimate; not a full estimator (no status, no model selection).

    Parameters
    ----------
    t_gyro, omega : array_like, shapes (N,), (N, 3)
        Gyro times [s] and measured angular velocity [rad/s].
    t_torque, torque : array_like, shapes (M,), (M, 3)
        Torque times [s] and measured torque [N m] (held).
    inertia : array_like, shape (3, 3)
        Current tensor [kg m^2].
    omega0 : array_like, shape (3,)
        Current initial angular velocity [rad/s] at ``t_gyro[0]``.
    gyro_std, torque_std : float or array_like (3,)
        Noise std per axis [rad/s], [N m].
    disturbance : array_like (3,), optional
        Current disturbance torque [N m].
    estimate_bias : bool
        Include the disturbance in the parameters.

    Returns
    -------
    PredictionErrorStep

    Raises
    ------
    ValueError
        As :func:`fisher_information`, and ``omega`` not of shape (N, 3) finite.
    """
    args = _validated(t_gyro, t_torque, torque, inertia, omega0, gyro_std, torque_std,
                      disturbance)
    y = np.asarray(omega, dtype=float)
    if y.shape != (args[0].size, 3) or not np.all(np.isfinite(y)):
        raise ValueError(f'omega: expected finite shape ({args[0].size}, 3), got {y.shape}')
    p = _kalman_pass(*args, bias=bool(estimate_bias), y=y)
    assert p.gradient is not None
    F = p.information
    dsc = np.sqrt(np.diag(F))
    dsc[dsc == 0] = 1.0
    step = -np.linalg.lstsq(F / dsc[:, None] / dsc[None, :], p.gradient / dsc,
                            rcond=1e-12)[0] / dsc
    return PredictionErrorStep(step=step, information=F, gradient=p.gradient, cost=p.cost,
                               names=p.names)
