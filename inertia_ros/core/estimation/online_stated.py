"""Stated input uncertainties online, profiled under their prior on the accumulated statistics.

The online form of :mod:`.stated` for :class:`.recursive_momentum.MomentumRecursiveEstimator`.
Each stated input (a wheel inertia, a rotor ``k_f``/``k_m``/``J``, the torque scale of the
other torque, the gyro scale) is an error ``u_j`` of one stated sigma per unit, ``u ~ N(0, 1)``.
Its change of the known angular impulse is carried as extra columns of the same equations:
the cumulative integral ``S_j`` (3 columns) of the equivalent torque of the input's one-sigma
change (held over the grid intervals like the equivalent torque itself), and for the gyro
scale the integral ``Wc = -int w x h`` of the momentum's gyroscopic part.  They enter the
accumulator (:class:`.accumulator.OnlineStats`, ``dim = 13 + 3 q'``) as columns after the
13 variables ``[w, m, t, T]``, so their cross products with the regressor and the measured
impulse accumulate incrementally, segment-centred, with the same forgetting.

At each estimate :func:`profile` fits ``X theta (+ d t) + C (u - u0) = Y(u0)`` on these
statistics (the column ``C_j = -S_j``; the gyro scale's ``-g a (L(w) theta + 2 Q(m) theta -
a Wc)`` with ``a = 1 / (1 + g u)``, re-linearised in Gauss-Newton steps), weighted by the
absolute white-noise model of the fit (:func:`.fit.fit_weighted`), with the tensor and bias
profiled out and the prior added: the data's information
is the sandwich one, its meat the anchored noise model's (white gyro noise plus the
torque-noise walk, scaled by the residual excess of the fit at the stated inputs: the
noise scale is that fit's; never below the information), only directions the data
inform at least :data:`.stated._MIN_INFORMATION` times the prior move, and the inputs'
common scale (:meth:`StatedInputs.scale_dir`) keeps its prior.  An input far beyond its
sigma is thus not absorbed: the fit at the stated inputs informs it little, it keeps the
prior and the adequacy test sees the misfit.  The accumulator then reads the statistics with the
inputs corrected by the posterior mean (:func:`correction_map`, exact: every column is linear
in the variables), so the estimator's fit, model selection and adequacy test see no residual
the stated uncertainty explains; ``D cov_u D'`` (``D`` from refits at ``u_hat + e_j``) is
added to the covariance.  The batch one reruns the estimator on corrected data; here the
statistics are the corrected data's (equal within 0.04 sigma on the same corrected inputs).
The batch (:func:`.stated.propagate`) runs this profile on the same statistics accumulated
over the whole record, so the two posteriors agree by construction.  With ``hold='auto'``
the torque scale's column is the held reduction of the other torque on both sides.
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from ..tensor import theta_to_matrix
from .accumulator import noise_map
from .fit import _anchored_meat, equation_weight, fit_two_pass
from .model import model_basis, model_parts
from .options import MIN_EQUATIONS, MIN_GYRO_SAMPLES
from .regressors import MOMENTUM_BASIS, VARIABLE_MAP
from .schedule import STALE_FRACTION
from .stated import _MIN_INFORMATION, _larger, widened

__all__ = ['StatedInputs', 'correction_map', 'profile', 'sensitivities']

_STEPS = 4                      # Gauss-Newton steps at most (the gyro scale's column moves)
_TOL = 0.01                     # converged: every step below this many posterior sigmas


def correction_map(u: np.ndarray, q_y: int, gscale: float) -> np.ndarray:
    """Map (dim, 13) from the accumulated variables to the 13 ``[w, m, t, T]`` of the data
    with the stated inputs ``u`` (q,) [stated sigmas] off: ``T + sum_j u_j S_j`` for the
    ``q_y`` inputs of the impulse; with a gyro scale sigma ``gscale`` (the last ``u``) the
    true rates ``a w`` (``a = 1 / (1 + gscale u_g)``), ``a^2 m`` and ``T + (a - 1) Wc``."""
    dim = 13 + 3 * q_y + (3 if gscale else 0)
    P = np.eye(dim, 13)
    for j in range(q_y):
        P[13 + 3 * j:16 + 3 * j, 10:13] = u[j] * np.eye(3)
    if gscale:
        a = 1.0 / (1.0 + gscale * u[-1])
        P[:, :3] *= a
        P[:, 3:9] *= a * a
        P[dim - 3:, 10:13] = (a - 1.0) * np.eye(3)
    return P


def _blocks(u0: np.ndarray, q_y: int, gscale: float, nv: np.ndarray, theta0: np.ndarray,
            bias: bool) -> np.ndarray:
    """The equation blocks' map E (dim, 3, m + 1) of ``[theta, (d), u, y]`` at ``u0``."""
    q = len(u0)
    P = correction_map(u0, q_y, gscale) @ noise_map(nv)          # (dim, 13)
    dim = P.shape[0]
    cols = [np.arange(6)] + ([np.arange(6, 9)] if bias else [])
    nb = 6 + 3 * bias
    E = np.zeros((dim, 3, nb + q + 1))
    for r in range(3):
        E[:, r, :nb] = P @ VARIABLE_MAP[:, r, np.concatenate(cols)]
        E[:, r, -1] = P @ VARIABLE_MAP[:, r, 9]
        for j in range(q_y):
            E[13 + 3 * j + r, r, nb + j] = -1.0
        if gscale:
            a = 1.0 / (1.0 + gscale * u0[-1])
            f = VARIABLE_MAP[:, r, :6] @ theta0                    # (13,)
            f = f * np.r_[np.ones(3), 2.0 * np.ones(6), np.zeros(4)]
            E[:, r, nb + q - 1] = -gscale * a * (P @ f)
            E[dim - 3 + r, r, nb + q - 1] += gscale * a * a
    return E


def _cross(E: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Cross Grams (3, 3, m + 1, m + 1) of the blocks ``E`` (dim, 3, m + 1) from ``G``."""
    dim, _, k = E.shape
    E2 = E.reshape(dim, 3 * k)
    return np.ascontiguousarray((E2.T @ G @ E2).reshape(3, k, 3, k).transpose(0, 2, 1, 3))


def profile(acc: Any, u0: np.ndarray, q_y: int, gscale: float, theta0: np.ndarray,
            bias: bool, nv: np.ndarray, tv: np.ndarray, ctx: dict[str, Any],
            n_eff: float, scale_dir: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Posterior mean (q,) and covariance (q, q) of the stated inputs [stated sigmas].

    Parameters
    ----------
    acc : OnlineStats
        The accumulator with the extra columns (``acc.totals()``).
    u0 : ndarray, shape (q,)
        The first linearisation point (the last estimate's posterior mean).
    q_y : int
        Inputs of the impulse (the first ``q_y`` of ``u``); a gyro scale is the last.
    gscale : float
        The stated relative gyro scale sigma (0: none).
    theta0 : ndarray, shape (6,)
        A tensor from an earlier fit (the weights and the gyro column).
    bias : bool
        Fit a constant torque bias too.
    nv, tv : ndarray, shape (3,)
        Gyro [rad^2/s^2] and torque [N^2 m^2] white-noise variances.
    ctx : dict
        The noise model's stream figures (``torque_dt``, ``gyro_dt``, ``white_y_cov``).
    n_eff : float
        Equations after the segment intercepts.
    scale_dir : ndarray, shape (q,), optional
        The inputs' common scale, kept at its prior (:meth:`StatedInputs.scale_dir`).

    Returns
    -------
    u_hat, cov_u : ndarray, shape (q,), (q, q)
    theta : ndarray, shape (6,)
        The tensor of the joint fit at ``u_hat``.
    """
    G, GP, walk = acc.totals()
    q = len(u0)
    u = np.asarray(u0, dtype=float).copy()
    cov = np.eye(q)
    theta = np.asarray(theta0, dtype=float)
    for _ in range(_STEPS if gscale else 2):     # linear: the 2nd rescales the noise
        E = _blocks(u, q_y, gscale, nv, theta, bias)
        st = SimpleNamespace(C=_cross(E, G), CP=_cross(E, GP), n_eff=n_eff, walk_time=walk,
                             omega_m2=acc.omega_m2(), **ctx)
        new, cov, theta = _posterior(st, q, u, theta, bias, nv, tv, scale_dir)
        done = np.all(np.abs(new - u) <= _TOL * np.sqrt(np.maximum(np.diag(cov), 1e-30)))
        u = new
        if done:
            break
    return u, 0.5 * (cov + cov.T), theta


def _posterior(st: Any, q: int, u0: np.ndarray, theta0: np.ndarray, bias: bool,
               nv: np.ndarray, tv: np.ndarray, scale_dir: np.ndarray | None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One Gauss-Newton step of the posterior from ``u0``, the information in absolute
    units (the white-noise model's weight), the anchored noise model's meat."""
    Im_S = equation_weight(theta0, nv, st.white_y_cov)            # shape of the weight
    S = _white(theta0, nv, st.white_y_cov)
    W = Im_S / float(np.trace(Im_S @ S) / 3.0)                    # absolute: tr(W S) = 3
    k = st.C.shape[2]
    m = k - 1
    Gm = np.einsum('rs,rsij->ij', W, st.C)
    H = Gm[:m, :m].copy()
    H[:6, :6] -= st.n_eff * np.einsum('c,crk,rs,csl->kl', nv, MOMENTUM_BASIS, W,
                                      MOMENTUM_BASIS)
    g = Gm[:m, m]
    nb = m - q
    n_i, u_i = np.arange(nb), np.arange(nb, m)
    K = np.linalg.pinv(H[np.ix_(n_i, n_i)], rcond=1e-12, hermitian=True) @ H[np.ix_(n_i, u_i)]
    Hu = H[np.ix_(u_i, u_i)] - H[np.ix_(u_i, n_i)] @ K
    gu = g[u_i] - K.T @ g[n_i]
    R = np.concatenate([-K.T, np.eye(q)], axis=1)                # scores of u, profiled
    if scale_dir is not None:
        Pj = np.eye(q) - np.outer(scale_dir, scale_dir) / float(scale_dir @ scale_dir)
        Hu, gu, R = Pj @ Hu @ Pj, Pj @ gu, Pj @ R
    lam, V = np.linalg.eigh(0.5 * (Hu + Hu.T))
    keep = lam > 1e-9 * max(float(lam.max(initial=0.0)), 1e-300)
    V, lam = V[:, keep], lam[keep]
    if not len(lam):
        return np.zeros(q), np.eye(q), np.asarray(theta0, dtype=float)
    # the data-only step (the inputs free) and its sandwich covariance in the directions
    # the data touch; the residual excess of the fit with the inputs at u0 scales the meat
    # (the noise scale is that fit's; never below the information): data the stated inputs
    # cannot explain near u0 (an input far beyond its sigma) inform them little, so they
    # keep the prior and the adequacy test sees the misfit
    d = (V.T @ gu) / lam
    step = V @ d
    pinv_n = np.linalg.pinv(H[np.ix_(n_i, n_i)], rcond=1e-12, hermitian=True)
    beta_0 = pinv_n @ g[n_i]
    c = np.concatenate([-beta_0, np.zeros(q), [1.0]])
    meat, excess = _anchored_meat(st, np.eye(k), m, W, Gm, c, beta_0[:6], nv, tv)
    Mv = _larger(V.T @ R @ meat @ R.T @ V * excess, np.diag(lam))
    J = np.diag(lam) @ np.linalg.pinv(Mv, hermitian=True) @ np.diag(lam)   # data information
    # only directions the data inform at least _MIN_INFORMATION times the prior move
    mu, Z = np.linalg.eigh(0.5 * (J + J.T))
    Vk, mu = V @ Z[:, mu >= _MIN_INFORMATION], mu[mu >= _MIN_INFORMATION]
    z = Vk.T @ (u0 + step)                                   # the data's measure of Vk' u
    u = Vk @ (mu / (mu + 1.0) * z)
    cov = Vk @ np.diag(1.0 / (mu + 1.0)) @ Vk.T + (np.eye(q) - Vk @ Vk.T)
    beta_n = pinv_n @ (g[n_i] - H[np.ix_(n_i, u_i)] @ (u - u0))
    return u, cov, beta_n[:6]


def _white(theta: np.ndarray, nv: np.ndarray, white_y_cov: np.ndarray | None) -> np.ndarray:
    """The equations' white-noise covariance (3, 3) per row: ``I S_g I`` (+ ``white_y_cov``)."""
    Im = theta_to_matrix(theta, check_finite=False)
    S = Im @ np.diag(nv) @ Im
    return S if white_y_cov is None else S + white_y_cov


class StatedInputs:
    """The stated inputs of one online estimator: their posterior (kept from estimate to
    estimate: the next profile starts there), the last tensor and the sensitivities.

    Parameters
    ----------
    names : sequence of str
        The momentum input's stated inputs (wheel inertias, rotor coefficients).
    torque_scale_std, gyro_scale_std : float
        Stated relative scale sigmas of the other torque and of the gyro (0: none).
    """

    def __init__(self, names: Any, torque_scale_std: float, gyro_scale_std: float) -> None:
        self.names = (list(names) + ['torque_scale'] * bool(torque_scale_std)
                      + ['gyro_scale'] * bool(gyro_scale_std))
        self.q_y = len(self.names) - bool(gyro_scale_std)
        self.torque_scale_std = float(torque_scale_std)
        self.gscale = float(gyro_scale_std)
        self.u = np.zeros(len(self.names))               # the last posterior mean
        self.cov_u = np.eye(len(self.names))
        self.theta: np.ndarray | None = None              # the last estimate's tensor
        self.profiled_at = 0                               # samples the profile saw
        #: (model and hold, D (q, 6), data span [s]) of the last sensitivities
        self.cache: tuple[str, np.ndarray, float] | None = None
        p = len(names)
        self._AA = np.zeros((p, p))        # the momentum input's changes against itself:
        self._Ay = np.zeros(p)             # for the inputs' common scale (scale_dir)
        self._yy = 0.0

    def observe(self, h: np.ndarray, tq: np.ndarray, dh: np.ndarray, dtq: np.ndarray) -> None:
        """Accumulate a momentum block's ``h``, torque (k, 3) and their one-sigma changes
        (p, k, 3) for :meth:`scale_dir`."""
        if not len(dh):
            return
        A = np.concatenate([dh.reshape(len(dh), -1), dtq.reshape(len(dtq), -1)], axis=1)
        y = np.concatenate([h.reshape(-1), tq.reshape(-1)])
        self._AA += A @ A.T
        self._Ay += A @ y
        self._yy += float(y @ y)

    def scale_dir(self, other_torque: bool) -> np.ndarray | None:
        """The ``u`` (q,) that scales the whole known input (momentum, its torque and the
        other torque) by one, every part of it stated (else None): least squares on the
        accumulated blocks."""
        p = len(self._Ay)
        if not p or (other_torque and not self.torque_scale_std) or self._yy <= 0:
            return None
        s = np.linalg.lstsq(self._AA, self._Ay, rcond=None)[0]
        resid = self._yy - 2.0 * float(s @ self._Ay) + float(s @ self._AA @ s)
        if resid > 1e-12 * self._yy:
            return None
        out = np.zeros(len(self.names))
        out[:p] = s
        if self.torque_scale_std:
            out[p] = 1.0 / self.torque_scale_std
        return out

    def read(self, est: Any, u: np.ndarray) -> Any:
        """``est``'s statistics (its noise model) read with the inputs ``u`` (q,) off."""
        acc = est._acc
        keep, acc.correction = acc.correction, correction_map(u, self.q_y, self.gscale)
        try:
            return est._stats(est._gyro_var(), acc.n_eff())
        finally:
            acc.correction = keep

    def update(self, est: Any) -> None:
        """Profile the inputs on ``est``'s statistics (:func:`profile`, from the last
        posterior mean and tensor) and read every accumulator with them corrected.  With
        ``reselect_every`` > 1 the profile runs with the model selection (on every
        ``reselect_every``-th estimate, the first included) and its posterior is reused in
        between, as the selection's verdicts are (and, as they are, not when stale:
        :data:`.schedule.STALE_FRACTION`)."""
        n = est.samples_used
        if est._schedule.estimates % est.reselect_every and self.theta is not None \
                and n - self.profiled_at <= STALE_FRACTION * n:
            return
        est._process()
        self.profiled_at = est.samples_used
        tv = est._torque_variance()
        tv = tv if tv is not None else np.zeros(3)
        nv = est._gyro_var()
        acc = est._acc
        if est.samples_used >= MIN_GYRO_SAMPLES and acc.n_eff() >= MIN_EQUATIONS \
                and np.all(nv > 0):
            bias = est.torque_bias != 'off'
            theta0 = self.theta
            if theta0 is None:           # the first: a fit at the last posterior mean
                f = fit_two_pass(self.read(est, self.u), np.eye(6), bias, nv, tv)
                theta0 = f.basis @ f.beta[:6]
            if np.all(np.isfinite(theta0)):
                self.u, self.cov_u, _ = profile(acc, self.u, self.q_y, self.gscale, theta0,
                                                bias, nv, tv, est._context(), acc.n_eff(),
                                                self.scale_dir(est.other_torque))
        for a in est._accs.values():
            a.correction = correction_map(self.u, self.q_y, self.gscale)

    def widen(self, est: Any, res: Any) -> Any:
        """``res`` with ``D cov_u D'`` added (``D`` reused while the parameter set and the
        hold stay and the data grew by under 5 %, and a tenth of the ``window``)."""
        if res.status not in ('ok', 'model_mismatch') or res.theta is None \
                or not np.all(np.isfinite(res.theta)):
            return res
        self.theta = np.asarray(res.theta, dtype=float)
        if model_parts(res.model)[0] not in ('full', 'diagonal', 'axisymmetric'):
            return res
        span = (est._acc.t_last or 0.0) - (est._align.t0 or 0.0)
        key = f'{res.model} {est._active}'        # the parameter set and the hold estimated
        c = self.cache
        if c is not None and c[0] == key and span - c[2] < 0.05 * max(c[2], 1e-9) and (
                not est.window or span - c[2] < 0.1 * est.window):
            D = c[1]
        else:
            tv = est._tau_var if est._tau_var is not None else np.zeros(3)
            D = sensitivities(lambda u: self.read(est, u), self.u, res, est.axis,
                              est._gyro_var(), tv)
            self.cache = (key, D, span)
        return widened(res, D, self.u, self.cov_u, self.names, 'the accumulated equations, '
                       'the statistics read with the inputs corrected by the posterior mean',
                       self.torque_scale_std, self.gscale)


def sensitivities(stats: Any, u_hat: np.ndarray, est: Any, axis: Any, nv: np.ndarray,
                  tv: np.ndarray) -> np.ndarray:
    """``d theta`` (q, 6) of each input at one sigma from ``u_hat`` (q,): ``stats(u)`` the
    statistics read with the inputs ``u`` off, fitted with ``est``'s parameter set and its
    weights (the batch's refits at ``u_hat + e_j``; exact for the impulse's inputs, which
    enter linearly; the gyro scale's a one-sigma difference, as the batch's)."""
    name, bias, _ = model_parts(est.model)
    basis = model_basis(name, axis)
    k = basis.shape[1]

    def theta(u: np.ndarray) -> np.ndarray:
        f = fit_two_pass(stats(u), basis, bias, nv, tv, None, est.theta)
        return basis @ f.beta[:k]
    ref = theta(u_hat)
    return np.array([np.nan_to_num(theta(u_hat + e) - ref) for e in np.eye(len(u_hat))])
