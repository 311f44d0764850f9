"""Sensor nuisance terms of the batch estimator, each kept only when the data support it.

Four terms that real gyros, torque streams and bodies add to Euler's equations
(:data:`.options.NUISANCE_TERMS`):

``gyro_bias`` (3 values, rad/s)
    A constant gyro offset ``b``: the body turns at ``w = w_meas - b``.
``torque_delay`` (1 value, s, within +-:data:`.options.NUISANCE_MAX_DELAY_S`)
    The torque stream's stamps lag the true instants by ``delta`` (``stamp = true + delta``,
    the scene key ``imperfections.torque_delay``); negative: they lead.
``damping`` (3 values, N m s/rad)
    Aerodynamic damping ``tau_d = -D w`` with ``D`` diagonal in the body frame, acting on the
    body but absent from the known torque.
``gyro_lowpass`` (1 value, s, up to :data:`.options.NUISANCE_MAX_TIME_CONSTANT_S`)
    A first-order sensor filter ``w_meas' = (w - w_meas) / T_g``.

The fit.  Non-overlapping intervals (one gyro sample skipped between them, so no sample
is shared; the shortest of :data:`.options.NUISANCE_INTERVALS_S` whose gyro-noise share is
small, see :func:`_prepare`) give independent momentum equations

    I (w_b - w_a) + int_a^b w x I w dt + D int_a^b w dt - d (t_b - t_a)
        = F_T[J](t_b + delta) - F_T[J](t_a + delta)

with ``J`` the integral of the held torque, ``F_T`` the first-order filter of the gyro
applied to the torque side (exact for the linear terms, first order in ``T_g`` for the
gyroscopic one) and ``d`` the constant disturbance torque (always in this fit).  The tensor,
``d`` and ``D`` enter linearly; the gyro bias through the gyroscopic term, linearised at the
current tensor and iterated (Gauss-Newton, exact Jacobian at convergence); ``delta`` and
``T_g`` by a profile (grid, then golden section).  The equations are weighted by the inverse
of their 3 x 3 residual covariance, estimated from the general model (every candidate term):
no noise model is assumed, so the statistics stay honest whatever the noise levels.  The
rate changes ``w_b - w_a`` carry the gyro noise of two samples, whose own (known) information
is taken out of the normal equations (corrected least squares, :class:`_Solver`): on short
records the shortest intervals' rate changes are largely noise, and the uncorrected fit
shrank the tensor by that share and left residuals any candidate term could absorb.  When the
general model's tensor is not determined (the batch identifiability rule, :func:`_undetermined`)
no term is tested: ``record['skipped']`` says why and the ordinary estimate runs.

The rule (one for all four, as :mod:`.selection`'s Wald tests): forward selection; a term is
added when the drop of the weighted residual sum it brings (a likelihood ratio, chi-square
with the term's number of values) has a p-value below ``alpha`` (:data:`.options.ALPHA`).

The estimate.  The chosen terms correct the data (``w - b``; torque stamps ``- delta``; the
torque replaced by the interval means of ``F_T[J] - D int w``) and the ordinary estimator runs
on them; the covariance the tensor inherits from the nuisance values (the joint covariance of
this fit minus the one with the nuisance held) is added to its covariance, so sigma includes
the nuisance uncertainty.  ``diagnostics['nuisance']`` records the choice.
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._numeric import psd_part
from .._validate import as_samples, as_times
from ..tensor import theta_to_matrix
from .align import cross_matrices, cumtrapz, gap_starts
from .homogeneous import is_torque_free
from .noise import noise_std_from_differences, regressor_noise_information
from .options import (
    ALPHA,
    IDENTIFIABILITY_TOL,
    NUISANCE_EIV_SHARE,
    NUISANCE_INTERVALS_S,
    NUISANCE_MAX_DELAY_S,
    NUISANCE_MAX_TIME_CONSTANT_S,
    NUISANCE_TERMS,
)
from .regressors import cumulative_torque
from .result import InertiaEstimate
from .uncertainty import widen

__all__ = ['NuisanceFit', 'apply_nuisance', 'fit_nuisance', 'nuisance_hook', 'with_nuisance']

_SIZES = {'gyro_bias': 3, 'torque_delay': 1, 'damping': 3, 'gyro_lowpass': 1}
_GRID = 11                      # profile grid points over a nonlinear term's range
_GOLDEN_STEPS = 20              # golden-section iterations after the grid
_BIAS_ITERATIONS = 3            # Gauss-Newton passes of the gyro-bias linearisation
_MIN_INTERVALS = 30             # fewer independent equations: no nuisance fit
_FD_STEP_S = 1e-3               # finite-difference step of delta and T_g [s]


@dataclass
class _Data:
    """Origin-shifted streams and the interval endpoints of the nuisance equations."""

    tg: np.ndarray
    w: np.ndarray
    ts: np.ndarray
    tau: np.ndarray
    a: np.ndarray               # interval start (gyro index)
    b: np.ndarray               # interval end (gyro index)
    dt: float                   # median gyro interval [s]
    noise_var: np.ndarray = field(default_factory=lambda: np.zeros(3))  # gyro [rad^2/s^2]


@dataclass
class NuisanceFit:
    """The nuisance fit of one term set.

    Attributes
    ----------
    terms : tuple of str
        Terms in the model.
    beta : ndarray, shape (p,)
        Linear parameters ``[theta (6), d (3), gyro_bias increment (3)?, damping (3)?]``.
    gyro_bias : ndarray, shape (3,)
        Gyro bias [rad/s] (zeros when not in ``terms``).
    delay, time_constant : float
        ``delta`` and ``T_g`` [s] (0 when not in ``terms``).
    rss : float
        Weighted residual sum of squares (with the weight of the general model).
    cov : ndarray, shape (q, q)
        Joint covariance of ``beta`` and the nonlinear terms (in ``names`` order).
    names : list of str
        Names of ``cov``'s rows.
    resid : ndarray, shape (n, 3)
        Interval residuals [N m s].
    identified : bool
        Whether the noise-corrected normal matrix was positive definite (see :class:`_Solver`).
    """

    terms: tuple[str, ...]
    beta: np.ndarray
    gyro_bias: np.ndarray
    delay: float = 0.0
    time_constant: float = 0.0
    rss: float = np.inf
    cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    info: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    names: list[str] = field(default_factory=list)
    resid: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    identified: bool = True

    def value(self, term: str) -> Any:
        """The fitted value of ``term`` (list for vectors, float for scalars)."""
        if term == 'gyro_bias':
            return self.gyro_bias.tolist()
        if term == 'damping':
            i = self.names.index('damping_x')
            return self.beta[i:i + 3].tolist()
        return self.delay if term == 'torque_delay' else self.time_constant

    def sigma(self, term: str) -> Any:
        """One-sigma uncertainty of ``term`` from the joint covariance."""
        sd = np.sqrt(np.maximum(np.diag(self.cov), 0.0))
        if _SIZES[term] == 3:
            i = self.names.index(f'{term}_x')
            return sd[i:i + 3].tolist()
        return float(sd[self.names.index(term)])


# --------------------------------------------------------------------------------------------
# equations
# --------------------------------------------------------------------------------------------

def _prepare(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray
             ) -> tuple[_Data | None, dict[str, Any]]:
    """Origin-shifted data and the independent intervals (None when too few), and a record.

    The interval is the shortest of :data:`.options.NUISANCE_INTERVALS_S` whose gyro-noise
    share in the rate change ``w_b - w_a`` is below :data:`.options.NUISANCE_EIV_SHARE` on
    every axis (the noise in the regressor would shrink the fit towards zero by about as
    much), the longest one when none is.
    """
    t0 = float(min(tg[0], ts[0]))
    tg, ts = tg - t0, ts - t0
    dt = float(np.median(np.diff(tg)))
    noise_var = noise_std_from_differences(w) ** 2
    margin = NUISANCE_MAX_DELAY_S + NUISANCE_MAX_TIME_CONSTANT_S
    gaps = gap_starts(ts)
    best: tuple[np.ndarray, np.ndarray, float, float] | None = None
    for length in NUISANCE_INTERVALS_S:
        m = max(2, int(round(length / dt)))
        a = np.arange(0, len(tg) - m, m + 1)
        b = a + m
        ok = (tg[a] >= ts[0] + margin) & (tg[b] <= ts[-1] - margin)
        ok &= (tg[b] - tg[a]) <= (m + 1) * dt          # no gyro gap inside
        for g in gaps:                                  # no torque gap inside
            ok &= ~((tg[b] > ts[g]) & (tg[a] < ts[g + 1]))
        if int(np.sum(ok)) < _MIN_INTERVALS:
            break
        a, b = a[ok], b[ok]
        share = float(np.max(2.0 * noise_var / np.maximum(
            np.mean((w[b] - w[a]) ** 2, axis=0), 1e-300)))
        best = (a, b, m * dt, share)
        if share <= NUISANCE_EIV_SHARE:
            break
    if best is None:
        return None, {'skipped': f'fewer than {_MIN_INTERVALS} independent '
                                 f'{NUISANCE_INTERVALS_S[0]:g} s intervals inside the torque '
                                 'coverage'}
    a, b, length, share = best
    return _Data(tg, w, ts, tau, a, b, dt, noise_var), {'interval_s': length,
                                                        'equations': int(len(a)),
                                             'regressor_noise_share': share}


def _design(d: _Data, terms: tuple[str, ...], theta: np.ndarray,
            bias: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Interval design (n, 3, p) of the linear parameters and their names.

    The gyro is read as ``w_meas - bias``; the gyro-bias columns are the increment's
    linearisation at ``theta``.
    """
    # imported here: stated (and momentum, ~8 ms) stay off the default estimate's start-up
    from .stated import lhs_columns

    w = d.w - bias
    cols = [lhs_columns(d.tg, w)]                               # the tensor's, (N, 3, 6)
    cols.append(-d.tg[:, None, None] * np.eye(3))              # constant disturbance d
    names = ['ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz', 'torque_bias_x', 'torque_bias_y',
             'torque_bias_z']
    if 'gyro_bias' in terms:
        I = theta_to_matrix(theta, check_finite=False)
        cols.append(cumtrapz(d.tg, cross_matrices(w @ I) - cross_matrices(w) @ I))
        names += ['gyro_bias_x', 'gyro_bias_y', 'gyro_bias_z']
    if 'damping' in terms:
        cols.append(cumtrapz(d.tg, w)[:, :, None] * np.eye(3))
        names += ['damping_x', 'damping_y', 'damping_z']
    X = np.concatenate(cols, axis=2)
    return X[d.b] - X[d.a], names


def _first_order(u: np.ndarray, y: np.ndarray, h: float, T: float) -> np.ndarray:
    """``y`` (K, 3) on a regular grid of step ``h`` through ``x' = (y - x) / T`` (exact for
    ``y`` linear between samples; starts at rest on ``y[0]``)."""
    if T <= 0.0:
        return y
    from scipy.signal import lfilter  # lazily: scipy.signal costs start-up time

    a = np.exp(-h / T)
    c = T / h * (1.0 - a)
    out = lfilter([1.0 - c, c - a], [1.0, -a], y - y[0], axis=0)
    return out + y[0]


def _torque_side(d: _Data, t: np.ndarray, delay: float, T: float) -> np.ndarray:
    """``F_T[J](t + delay)`` (K, 3) at increasing times ``t`` [s]."""
    if T <= 0.0:
        return cumulative_torque(d.ts, d.tau, t + delay)
    u = np.arange(t[0] - 10.0 * T - d.dt, t[-1] + 2.0 * d.dt, d.dt)
    y = _first_order(u, cumulative_torque(d.ts, d.tau, u + delay), d.dt, T)
    return np.stack([np.interp(t, u, y[:, i]) for i in range(3)], 1)


def _rhs(d: _Data, delay: float, T: float) -> np.ndarray:
    """Interval right-hand sides (n, 3)."""
    t = np.stack([d.tg[d.a], d.tg[d.b]], 1).ravel()         # increasing: a0 b0 a1 b1 ...
    J = _torque_side(d, t, delay, T).reshape(-1, 2, 3)
    return J[:, 1] - J[:, 0]


# --------------------------------------------------------------------------------------------
# weighted least squares and profiles
# --------------------------------------------------------------------------------------------

def _noise_gram(d: _Data, Wh: np.ndarray, p: int) -> np.ndarray:
    """Expected weighted Gram (p, p) of the gyro noise in the design's tensor columns.

    The tensor's columns of an interval hold ``L(w_b - w_a)`` (``I v = L(v) theta``), whose
    gyro noise ``L(n_b - n_a)`` has the known covariance ``2 sigma_k^2`` per axis: summed
    over the intervals, ``n`` times :func:`.noise.regressor_noise_information`.  The noise in
    the integrated (gyroscopic) part is smaller by ``|w| dt``: left out.
    """
    G = np.zeros((p, p))
    G[:6, :6] = len(d.a) * regressor_noise_information(2.0 * d.noise_var, Wh)
    return G


class _Solver:
    """Weighted least squares corrected for the gyro noise in the regressors, with a fixed
    design for many right-hand sides.

    Minimises ``|y - X beta|_W^2 - beta' G beta`` (``G`` from :func:`_noise_gram`): the
    errors-in-variables (corrected least squares) estimate, which the noise in the rate
    changes does not shrink towards zero; ``rss`` is that minimum, ``y'Wy - b' M^-1 b``
    with ``M = X'WX - G``, ``b = X'Wy``.  ``positive`` is False when ``M`` is not positive
    definite: the noise in the rate changes is as large as their signal along some
    direction, and the parameters cannot be told from it.
    """

    def __init__(self, X: np.ndarray, Wh: np.ndarray, G: np.ndarray | None = None) -> None:
        self.Wh = Wh                                   # (3, 3): Sigma^-1/2
        self.Xw = np.einsum('ij,njp->nip', Wh, X).reshape(-1, X.shape[2])
        self.scale = np.linalg.norm(self.Xw, axis=0)
        self.scale[self.scale == 0] = 1.0
        A = self.Xw.T @ self.Xw
        if G is not None:
            A = A - G
        self.M = A / np.outer(self.scale, self.scale)
        try:
            self.L = np.linalg.cholesky(self.M)
            self.positive = True
        except np.linalg.LinAlgError:
            self.L = None
            self.positive = False

    def _solve(self, bs: np.ndarray) -> np.ndarray:
        if self.L is None:
            return np.linalg.lstsq(self.M, bs, rcond=None)[0]
        from scipy.linalg import cho_solve  # lazily: scipy.linalg costs start-up time
        return cho_solve((self.L, True), bs)

    def _b(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        yw = (y @ self.Wh.T).ravel()
        return yw, (self.Xw.T @ yw) / self.scale

    def rss(self, y: np.ndarray) -> float:
        """Corrected weighted residual sum of squares of ``y`` (n, 3)."""
        yw, bs = self._b(y)
        return float(yw @ yw - bs @ self._solve(bs))

    def beta(self, y: np.ndarray) -> np.ndarray:
        """The corrected weighted least-squares parameters for ``y`` (n, 3)."""
        return self._solve(self._b(y)[1]) / self.scale


def _golden(f: Callable[[float], float], lo: float, hi: float) -> float:
    """Minimiser of ``f`` on ``[lo, hi]`` by golden section."""
    g = 0.5 * (np.sqrt(5.0) - 1.0)
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(_GOLDEN_STEPS):
        if f1 <= f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - g * (hi - lo)
            f1 = f(x1)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + g * (hi - lo)
            f2 = f(x2)
    return x1 if f1 <= f2 else x2


def _profile_1d(f: Callable[[float], float], lo: float, hi: float) -> float:
    """Grid over ``[lo, hi]``, then golden section around the best grid point."""
    grid = np.linspace(lo, hi, _GRID)
    vals = [f(float(x)) for x in grid]
    k = int(np.argmin(vals))
    return _golden(f, float(grid[max(k - 1, 0)]), float(grid[min(k + 1, _GRID - 1)]))


def _profile(d: _Data, solver: _Solver, terms: tuple[str, ...],
             start: tuple[float, float]) -> tuple[float, float]:
    """``(delta, T_g)`` minimising the weighted residual sum (0 for terms not in ``terms``)."""
    delay = start[0] if 'torque_delay' in terms else 0.0
    T = start[1] if 'gyro_lowpass' in terms else 0.0
    rounds = 2 if {'torque_delay', 'gyro_lowpass'} <= set(terms) else 1
    for _ in range(rounds):
        if 'torque_delay' in terms:
            delay = _profile_1d(lambda x, T=T: solver.rss(_rhs(d, x, T)),
                                -NUISANCE_MAX_DELAY_S, NUISANCE_MAX_DELAY_S)
        if 'gyro_lowpass' in terms:
            T = _profile_1d(lambda x, delay=delay: solver.rss(_rhs(d, delay, x)), 0.0,
                            NUISANCE_MAX_TIME_CONSTANT_S)
    return delay, T


def _fit(d: _Data, terms: tuple[str, ...], Wh: np.ndarray, theta0: np.ndarray,
         start: tuple[float, float] = (0.0, 0.0)) -> NuisanceFit:
    """Fit one term set (gyro bias by Gauss-Newton passes, delta and T_g profiled)."""
    bias = np.zeros(3)
    theta = theta0
    delay, T = start
    passes = _BIAS_ITERATIONS if 'gyro_bias' in terms else 1
    for _ in range(passes):
        X, names = _design(d, terms, theta, bias)
        solver = _Solver(X, Wh, _noise_gram(d, Wh, X.shape[2]))
        delay, T = _profile(d, solver, terms, (delay, T))
        beta = solver.beta(_rhs(d, delay, T))
        theta = beta[:6]
        if 'gyro_bias' in terms:
            bias = bias + beta[9:12]
    y = _rhs(d, delay, T)
    fit = NuisanceFit(terms, beta, bias, delay, T, solver.rss(y))
    fit.resid = y - np.einsum('njp,p->nj', X, beta)
    fit.identified = solver.positive
    fit.cov, fit.info, fit.names = _joint_cov(d, X, names, Wh, fit)
    return fit


def _joint_cov(d: _Data, X: np.ndarray, names: list[str], Wh: np.ndarray,
               fit: NuisanceFit) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Covariance of the linear and the profiled parameters from the linearised model."""
    cols = [X]
    names = list(names)
    for term, x in (('torque_delay', fit.delay), ('gyro_lowpass', fit.time_constant)):
        if term not in fit.terms:
            continue
        lo = max(x - _FD_STEP_S, 0.0) if term == 'gyro_lowpass' else x - _FD_STEP_S
        hi = x + _FD_STEP_S

        def at(v: float, term: str = term) -> np.ndarray:
            return (_rhs(d, v, fit.time_constant) if term == 'torque_delay'
                    else _rhs(d, fit.delay, v))
        cols.append(-((at(hi) - at(lo)) / (hi - lo))[:, :, None])
        names.append(term)
    J = np.concatenate(cols, axis=2)
    Jw = np.einsum('ij,njp->nip', Wh, J).reshape(-1, J.shape[2])
    s = np.linalg.norm(Jw, axis=0)
    s[s == 0] = 1.0
    info = (Jw / s).T @ (Jw / s) - _noise_gram(d, Wh, J.shape[2]) / np.outer(s, s)
    cov = np.linalg.pinv(info) / np.outer(s, s)
    return 0.5 * (cov + cov.T), info * np.outer(s, s), names


# --------------------------------------------------------------------------------------------
# selection
# --------------------------------------------------------------------------------------------

def _whitener(resid: np.ndarray, p: int) -> np.ndarray:
    """``Sigma^-1/2`` (3, 3) from interval residuals (n, 3) of a fit with ``p`` parameters."""
    n = len(resid)
    S = resid.T @ resid / max(n - p / 3.0, 1.0)
    L = np.linalg.cholesky(S + 1e-12 * np.trace(S) * np.eye(3))
    return np.linalg.inv(L)


def _undetermined(fit: NuisanceFit) -> str:
    """Why the model with every candidate term leaves the tensor undetermined ('' if not).

    The batch rule (:data:`.options.IDENTIFIABILITY_TOL`): every principal moment positive
    with a standard error (the noise-corrected joint covariance) at most that share of the
    largest; and the noise-corrected normal matrix positive definite.  Otherwise the terms
    are confounded with the tensor or with the gyro noise in the rate changes, and a test of
    them says nothing: on a few seconds of slow rotation the 0.1 s intervals' rate changes
    are mostly noise, and gyro biases of 0.3-2 rad/s were chosen at p < 1e-10 on
    model-conforming records.
    """
    if not fit.identified:
        return ('the gyro noise in the interval rate changes is as large as their signal '
                'along some direction (the noise-corrected normal matrix is not positive '
                'definite): no nuisance term can be tested')
    moments = fit.beta[:3]
    se = np.sqrt(np.maximum(np.diag(fit.cov)[:3], 0.0))
    scale = float(np.max(moments))
    if scale > 0 and np.all(moments > 0) and np.all(se <= IDENTIFIABILITY_TOL * scale):
        return ''
    return (f'the interval equations with every candidate term do not determine the tensor '
            f'(principal moments {np.array2string(moments, precision=3)} +- '
            f'{np.array2string(se, precision=3)} kg m^2; the batch rule asks for a standard '
            f'error at most {IDENTIFIABILITY_TOL:g} of the scale): no nuisance term can be '
            f'tested')


def _test(drop: float, dof: int, dof_resid: int) -> dict[str, Any]:
    """Test record of a weighted-residual drop: ``drop / dof`` against F(dof, dof_resid).

    The weight comes from the general model's residuals, so the drop is a likelihood ratio
    whose scale is estimated: the F distribution (chi-square / dof for long records) keeps
    the level exact on short ones.
    """
    from scipy.special import fdtrc  # lazily: scipy.special costs start-up time

    stat = max(float(drop), 0.0)
    return {'statistic': stat, 'dof': dof,
            'p_value': float(fdtrc(dof, max(dof_resid, 1), stat / dof))}


#: ``rank(fit) -> residual excess`` of the whole-record estimate on the data ``fit`` corrects.
RankFunction = Callable[[NuisanceFit], float]


def fit_nuisance(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                 request: str | tuple[str, ...], alpha: float,
                 rank: RankFunction | None = None
                 ) -> tuple[NuisanceFit | None, dict[str, Any]]:
    """Choose the nuisance terms the data support and fit them.

    Parameters
    ----------
    tg, w : ndarray, shapes (N,), (N, 3)
        Gyro stamps [s] and angular velocity [rad/s].
    ts, tau : ndarray, shapes (M,), (M, 3)
        Torque stamps [s] and torque [N m], M >= 2.
    request : 'auto' or tuple of str
        ``auto``: forward selection among :data:`NUISANCE_TERMS`; a tuple: exactly these.
    alpha : float
        Level of the likelihood-ratio tests.
    rank : callable, optional
        The residual excess of the whole-record estimate on the data a fit corrects: when
        several terms pass the test at one step, the one with the smallest excess is added
        (:func:`_step`); without it, the smallest p-value.

    Returns
    -------
    fit : NuisanceFit or None
        The fit of the chosen terms (None when the record is too short for the fit).
    record : dict
        ``requested``, ``chosen``, ``evidence`` (per tested term: ``statistic``, ``dof``,
        ``p_value``, ``chosen``), ``rule``, ``interval_s``, ``equations``; or ``skipped``.
    """
    record: dict[str, Any] = {
        'requested': request if request == 'auto' else list(request), 'chosen': [],
        'rule': (f'forward selection: a term is added when the F test of the drop in '
                 f'weighted residuals it brings (a likelihood ratio, weight from the model '
                 f'with every candidate) has p < alpha={alpha:g}')}
    d, info = _prepare(tg, w, ts, tau)
    record.update(info)
    if d is None:
        return None, record
    cands = NUISANCE_TERMS if request == 'auto' else tuple(request)
    Wh = np.eye(3)
    base = _fit(d, (), Wh, np.zeros(6))
    general = _fit(d, cands, Wh, base.beta[:6])
    for _ in range(2):              # the weight from the general model's residuals
        Wh = _whitener(general.resid, len(general.beta))
        general = _fit(d, cands, Wh, base.beta[:6], (general.delay, general.time_constant))
    why = _undetermined(general)
    if why:
        record['skipped'] = why
        return None, record
    theta0 = general.beta[:6]
    dof_resid = 3 * len(d.a) - len(general.beta) - (len(general.names) - len(general.beta))
    chosen: list[str] = [] if request == 'auto' else list(cands)
    cur = _fit(d, tuple(chosen), Wh, theta0)
    evidence: dict[str, dict[str, Any]] = {}
    while request == 'auto' and len(chosen) < len(cands):
        trials = {t: _fit(d, _ordered(chosen + [t]), Wh, theta0,
                          (general.delay, general.time_constant))
                  for t in cands if t not in chosen}
        tests = {t: {**_test(cur.rss - f.rss, _SIZES[t], dof_resid), 'chosen': False}
                 for t, f in trials.items()}
        evidence.update(tests)
        best = _step(tests, trials, alpha, rank)
        ranked = {t: v['residual_excess'] for t, v in tests.items() if 'residual_excess' in v}
        if ranked:                  # the whole-record comparison of this step's rivals
            record.setdefault('ranked_by_residual_excess', []).append(ranked)
        if best is None:
            break
        tests[best]['chosen'] = True
        chosen.append(best)
        cur = trials[best]
    record['chosen'] = list(_ordered(chosen))
    record['evidence'] = evidence
    if rank is not None:
        record['rule'] += ('; when several terms pass at one step, the one whose correction '
                           'leaves the smallest residual excess of the whole-record estimate')
    return cur, record


def _step(tests: dict[str, dict[str, Any]], trials: dict[str, NuisanceFit], alpha: float,
          rank: RankFunction | None) -> str | None:
    """The term to add at one forward step (``None``: none passes the test at ``alpha``).

    Terms that act alike (a torque delay and a gyro low-pass both shift the torque against
    the rate by about ``T_g``) all pass, and on the independent intervals (tens of
    equations) the wrong one can fit slightly better: a 15 ms gyro low-pass was taken for a
    torque delay in 4 of 8 seeds.  The whole-record estimate on each candidate's corrected
    data (every gyro sample, the same noise model, as ``hold='auto'`` compares the holds)
    tells them apart: its residual excess was smaller with the true term in 16 of 16 seeds
    (low-pass present: 0.2-0.6 % smaller; delay present: 1.01 against 1.8).  So the
    interval test admits the terms, and among those it admits the whole record chooses
    (``record['ranked_by_residual_excess']``, one entry per such step).
    """
    passed = [t for t in tests if tests[t]['p_value'] < alpha and trials[t].identified]
    if not passed:
        return None
    if rank is None or len(passed) == 1:
        return min(passed, key=lambda t: tests[t]['p_value'])
    for t in passed:
        tests[t]['residual_excess'] = float(rank(trials[t]))
    return min(passed, key=lambda t: (tests[t]['residual_excess'], tests[t]['p_value']))


def _ordered(terms: list[str]) -> tuple[str, ...]:
    """``terms`` in :data:`NUISANCE_TERMS` order."""
    return tuple(t for t in NUISANCE_TERMS if t in terms)


# --------------------------------------------------------------------------------------------
# correction and the estimate
# --------------------------------------------------------------------------------------------

def apply_nuisance(tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                   fit: NuisanceFit) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The streams with the fitted nuisance removed: ``(tg, w, ts, tau)``.

    ``w - b``; torque stamps ``ts - delta``; with damping or a gyro low-pass, each torque
    sample replaced by the mean over its hold interval of ``F_T[J] - D int w`` (so the
    integral of the corrected torque is exact at the torque stamps).
    """
    w2 = w - fit.gyro_bias
    t0 = float(min(tg[0], ts[0]))
    t_true = ts - t0 - fit.delay
    if not {'damping', 'gyro_lowpass'} & set(fit.terms):
        return tg, w2, t_true + t0, tau
    tgs = tg - t0
    d = _Data(tgs, w2, ts - t0, tau, np.zeros(0, int), np.zeros(0, int),
              float(np.median(np.diff(tgs))))
    Jc = _torque_side(d, t_true, fit.delay, fit.time_constant)
    if 'damping' in fit.terms:
        W = cumtrapz(tgs, w2)
        D = np.asarray(fit.value('damping'))
        Jc = Jc - D * np.stack([np.interp(t_true, tgs, W[:, i]) for i in range(3)], 1)
    tau2 = np.empty_like(tau)
    tau2[:-1] = np.diff(Jc, axis=0) / np.diff(t_true)[:, None]
    tau2[-1] = tau2[-2]
    return tg, w2, t_true + t0, tau2


def _added_cov(fit: NuisanceFit) -> np.ndarray:
    """Covariance (6, 6) the tensor inherits from the nuisance values.

    The joint covariance of the tensor minus the one with the nuisance values held (the
    tensor and the disturbance torque free).
    """
    keep = list(range(9))
    try:
        cond = np.linalg.inv(fit.info[np.ix_(keep, keep)])[:6, :6]
    except np.linalg.LinAlgError:
        return np.zeros((6, 6))
    return psd_part(fit.cov[:6, :6] - cond)


def nuisance_hook(fn: Callable[..., InertiaEstimate]) -> Callable[..., InertiaEstimate]:
    """Give :func:`.batch.estimate` its ``nuisance`` option (the decorated function itself
    always runs with the option off, on the corrected streams when terms are chosen)."""
    @functools.wraps(fn)
    def wrapper(t_gyro: Any, omega: Any, t_torque: Any, torque: Any,
                **kw: Any) -> InertiaEstimate:
        from .config import require
        request = require('batch', 'torque' if _count(t_torque) else 'torque_free',
                          kw).nuisance                     # validated (normalised) once
        if request == 'off':
            return fn(t_gyro, omega, t_torque, torque, **kw)
        return with_nuisance(fn, (t_gyro, omega, t_torque, torque), dict(kw, nuisance=request))
    return wrapper


def _count(t: Any) -> int:
    """Number of samples in a stamp array (1 for what is not a sequence: validated later)."""
    try:
        return len(t)
    except TypeError:
        return 1


def with_nuisance(estimate_fn: Callable[..., InertiaEstimate], streams: tuple[Any, ...],
                  kw: dict[str, Any]) -> InertiaEstimate:
    """:func:`.batch.estimate` with the nuisance terms ``kw['nuisance']`` asks for.

    Parameters
    ----------
    estimate_fn : callable
        The undecorated :func:`.batch.estimate` (called with ``nuisance='off'``).
    streams : tuple
        ``(t_gyro, omega, t_torque, torque)`` as given to it.
    kw : dict
        Its keyword options; ``nuisance`` is ``'auto'`` or a tuple of terms.

    Returns
    -------
    InertiaEstimate
        With ``diagnostics['nuisance']`` (see DESIGN.md) and the nuisance uncertainty in
        its covariance.
    """
    tg = as_times(streams[0], 't_gyro')
    w = as_samples(streams[1], len(tg), 'omega', 't_gyro')
    ts = as_times(streams[2], 't_torque')
    tau = as_samples(streams[3], len(ts), 'torque', 't_torque')
    request = kw['nuisance']
    kw = dict(kw, nuisance='off')
    kw_fit = dict(kw)
    if kw_fit.get('torque_noise') is None and len(ts) >= 2:   # the raw stream's, not filtered
        kw_fit['torque_noise'] = noise_std_from_differences(tau)
    # torque-free (no stream, or zeros or noise only: the estimate's rule): nothing to fit
    if len(ts) < 2 or len(tg) < 2 or is_torque_free(np.sqrt(np.mean(tau ** 2, axis=0)),
                                                    np.asarray(kw_fit['torque_noise'])):
        est = estimate_fn(tg, w, ts, tau, **kw)
        est.diagnostics['nuisance'] = {'requested': request if isinstance(request, str)
                                       else list(request), 'chosen': [],
                                       'skipped': 'torque-free data: no nuisance fit'}
        return est
    done: dict[tuple[str, ...], InertiaEstimate] = {}

    def corrected(f: NuisanceFit, options: dict[str, Any]) -> InertiaEstimate:
        return estimate_fn(*apply_nuisance(tg, w, ts, tau, f), **options)

    def rank(f: NuisanceFit) -> float:
        """Residual excess of the whole-record (integral) estimate on ``f``'s corrected data."""
        ml = kw_fit.get('method', 'auto') in ('auto', 'ml')     # ml's excess: its integral
        est = corrected(f, dict(kw_fit, method='integral') if ml else kw_fit)
        if not ml:
            done[f.terms] = est                                  # the final one when chosen
        return float(est.diagnostics.get('residual_excess', np.inf))

    fit, record = fit_nuisance(tg, w, ts, tau, request, kw.get('alpha', ALPHA), rank)
    if fit is None or not fit.terms:
        est = estimate_fn(tg, w, ts, tau, **kw)
        est.diagnostics['nuisance'] = record
        return est
    added = _added_cov(fit)
    est = done.get(fit.terms)
    est = widen(est if est is not None else corrected(fit, kw_fit), added)
    record['values'] = {t: fit.value(t) for t in fit.terms}
    record['sigma'] = {t: fit.sigma(t) for t in fit.terms}
    record['units'] = {t: _UNITS[t] for t in fit.terms}
    record['theta_std_added'] = np.sqrt(np.diag(added)).tolist()
    est.diagnostics['nuisance'] = record
    return est


_UNITS = {'gyro_bias': 'rad/s', 'torque_delay': 's', 'damping': 'N m s/rad',
          'gyro_lowpass': 's'}
