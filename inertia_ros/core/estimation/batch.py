"""Batch inertia estimation from gyro and torque streams: :func:`estimate`.

Methods (:data:`METHODS`), all built from :mod:`.regressors`:

``auto`` (default)
    ``ml`` for records of up to :data:`ML_AUTO_MAX_SAMPLES` gyro samples, ``integral`` for
    longer ones (``ml`` costs about 6x ``integral`` on a 60 s, 200 Hz record and more on
    long ones, where ``integral``'s error is already small).  The result's ``method`` names
    the one used and ``diagnostics['method_selection']`` says why.
``integral``
    Momentum form anchored per segment.  For every gyro sample ``b`` of a segment,
    ``I w_b + int_{t0}^{t_b} w x (I w) dt - d t_b - h0 = int_{t0}^{t_b} tau dt``, with the
    segment's initial momentum ``h0`` as three nuisance parameters (eliminated exactly by
    removing the segment mean of every column).  Each equation then carries only the white
    gyro noise of ``w_b`` (``I n_b``) plus the random walk of the integrated torque noise, so
    nothing is differentiated and no window overlaps.  Weighted by ``(I S_g I)^-1`` (``S_g`` the
    gyro noise covariance, ``I`` from a first pass) and bias-compensated for the gyro noise in
    the regressor (errors in variables: ``H = Phi' W Phi - n B``).  The covariance is the
    sandwich with the exact model of both noises: white gyro noise and piecewise-constant torque
    noise integrated over each torque interval, inflated when the residuals exceed that model.
    The segment length trades the information in slow motion against the random walk of the
    integrated torque noise; it is chosen by minimising the predicted variance among 5, 10, 20,
    40 s and the whole record (unless ``segment`` is given).  All statistics are quadratic
    forms in 13 per-sample variables ``[w, m, t, T]``, so the data are reduced once to a
    13 x 13 Gram matrix (plus the torque-noise sums) and every model, weight and segmentation
    is evaluated on those.
``ml``
    Maximum likelihood: the ``integral`` estimate (status, model and bias decision included)
    refined by Gauss-Newton on the likelihood of the exact model (gyro white noise, torque
    noise as process noise held over each torque interval; :mod:`.ml`), with the covariance
    from the Fisher information.  Attains the Cramer-Rao bound of :mod:`inertia_ros.core.crlb`.
    Only an ``ok`` zero-order-hold estimate without torque gaps is refined; otherwise, or when
    the refinement does not converge, the ``integral`` result is returned unchanged and
    ``diagnostics['ml']`` says why.
``integral_ls``
    The same anchored equations, unweighted and without bias compensation.
``integral_sliding``
    Overlapping windows ``I (w_b - w_a) + int_a^b w x I w = int_a^b tau`` of fixed length,
    ordinary least squares, Newey-West (HAC) covariance for the overlap.
``differential_fd``
    ``tau(t_b) = I w_dot_b + w_b x I w_b`` with central finite differences: the baseline.
``differential_sg``
    The same with a Savitzky-Golay smoothing differentiator, the same filter on the torque.

    Both differentiate the gyro, so its noise enters the regressor (errors in variables) and
    shrinks the fit by about the noise share of the differentiated gyro.  That share (from the
    estimated gyro noise and the differentiator's noise gain, per axis, in
    ``diagnostics['regressor_noise_share']``) above 2 % gives ``insufficient_excitation``
    instead of a biased tensor with status ``ok``.

Model selection (``model='auto'`` / ``torque_bias='auto'``): Wald tests on the general model
(full tensor plus bias) with its calibrated covariance; the smallest parameter set the data does
not reject at level ``alpha`` is used (an F-test analogue that stays valid with the correlated
residuals of the momentum equations; BIC would need white residuals).

Identifiability: the gyro-noise-corrected information matrix, scaled by the total column
energy, shows which directions carry signal; elements in directions that are mostly gyro noise
are undetermined (reported NaN/null, held at a plausible value while the rest is estimated),
and so are elements whose standard error exceeds ``identifiability_tol`` of the tensor scale.
Torque-free data gives the scale-free (homogeneous) solution from the null vector.  A
physically impossible tensor (not positive definite, triangle inequality violated) is replaced
by the nearest valid one and the violation is reported in ``diagnostics['physical']``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import signal, sparse, stats

from ..inertia import (
    THETA_NAMES,
    check_physical,
    nearest_physical,
    principal_axes,
    theta_to_matrix,
)
from .ml import refine
from .options import HOLDS, METHODS, ML_AUTO_MAX_SAMPLES, MODELS, TORQUE_BIAS
from .regressors import (
    cumulative_monomials,
    cumulative_torque,
    gyroscopic_matrix,
    momentum_matrix,
    monomials,
    noise_std_from_differences,
)
from .result import InertiaEstimate

__all__ = ['HOLDS', 'METHODS', 'ML_AUTO_MAX_SAMPLES', 'MODELS', 'TORQUE_BIAS', 'estimate',
           'model_basis']

_AXES = {'x': np.array([1.0, 0.0, 0.0]), 'y': np.array([0.0, 1.0, 0.0]),
         'z': np.array([0.0, 0.0, 1.0])}
_L_BASIS = momentum_matrix(np.eye(3))          # (3 axes c, 3, 6): L(e_c)
_SIGNAL_SHARE = 0.5                            # conditional signal share of a determined element
_NULL_FRACTION = 0.01                          # signal fraction of an empty direction
_NOISE_SHARE = 0.01                            # gyro-noise share that makes a column suspect
_NREG = 10                                     # regressor variables [w, m, t] of the 13
_SELECT_MAX_ROWS = 100_000                     # equations used by the segment-length search
_BLAS_MIN_ROWS = 400_000                       # rows from which a Gram goes to BLAS
_SEGMENT_CANDIDATES = (5.0, 10.0, 20.0, 40.0)   # s, anchored-segment lengths tried
_EIV_MAX_SHARE = 0.02                          # differentiated-gyro noise share tolerated


# ---------------------------------------------------------------------------------------------
# validation
# ---------------------------------------------------------------------------------------------
def _times(t: Any, name: str) -> np.ndarray:
    """Validated 1-D strictly increasing finite float times."""
    arr = np.asarray(t, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f'{name}: expected shape (N,), got {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name}: contains NaN or inf')
    if len(arr) > 1 and np.any(np.diff(arr) <= 0):
        k = int(np.argmax(np.diff(arr) <= 0))
        raise ValueError(f'{name}: times must be strictly increasing (t[{k + 1}] = '
                         f'{arr[k + 1]!r} <= t[{k}] = {arr[k]!r})')
    return arr


def _vectors(x: Any, n: int, name: str, tname: str) -> np.ndarray:
    """Validated (n, 3) finite float array."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f'{name}: expected shape (N, 3), got {arr.shape}')
    if arr.shape[0] != n:
        raise ValueError(f'{name}: has {arr.shape[0]} rows but {tname} has {n} samples')
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name}: contains NaN or inf')
    return arr


def _axis(symmetry_axis: Any) -> np.ndarray | None:
    """Unit symmetry axis from 'x'/'y'/'z' or a 3-vector, or None."""
    if symmetry_axis is None:
        return None
    if isinstance(symmetry_axis, str):
        if symmetry_axis.lower() not in _AXES:
            raise ValueError(f"symmetry_axis: must be 'x', 'y', 'z' or a 3-vector, got "
                             f'{symmetry_axis!r}')
        return _AXES[symmetry_axis.lower()]
    v = np.asarray(symmetry_axis, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise ValueError(f'symmetry_axis: must be a finite non-zero 3-vector, got '
                         f'{symmetry_axis!r}')
    return v / np.linalg.norm(v)


def model_basis(model: str, symmetry_axis: np.ndarray | None = None) -> np.ndarray:
    """Basis ``T`` (6, k) of a parameter set: ``theta = T @ psi``.

    Parameters
    ----------
    model : {'full', 'diagonal', 'axisymmetric'}
        ``full``: the six elements; ``diagonal``: ixx, iyy, izz; ``axisymmetric``:
        ``I = a (1 - n n') + b n n'`` with ``psi = [a, b]`` (transverse, axial) [kg m^2].
    symmetry_axis : ndarray, shape (3,), optional
        Unit axis ``n``, required for ``axisymmetric``.

    Returns
    -------
    ndarray, shape (6, k)
    """
    if model == 'full':
        return np.eye(6)
    if model == 'diagonal':
        return np.eye(6)[:, :3]
    if model == 'axisymmetric':
        if symmetry_axis is None:
            raise ValueError("symmetry_axis: required for model='axisymmetric'")
        nn = np.outer(symmetry_axis, symmetry_axis)
        def th(m: np.ndarray) -> np.ndarray:
            return np.array([m[0, 0], m[1, 1], m[2, 2], m[0, 1], m[0, 2], m[1, 2]])
        return np.column_stack([th(np.eye(3) - nn), th(nn)])
    raise ValueError(f'model: must be one of {MODELS}, got {model!r}')


# ---------------------------------------------------------------------------------------------
# equations
# ---------------------------------------------------------------------------------------------
def _variable_map() -> np.ndarray:
    """``E`` (13, 3, 10): equation block ``A_b = [X6 | Xd | y]`` from 13 per-sample variables.

    ``v_b = [w (3), m (6), s (1), y (3)]``: ``X6 = L(w) + Q(m)``, ``Xd = -s * 1``, ``y``.  Every
    statistic of the equations is a quadratic form in ``v``, so the batch estimator only ever
    reduces the 13 columns of ``V``.
    """
    E = np.zeros((13, 3, 10))
    E[:3, :, :6] = momentum_matrix(np.eye(3))
    E[3:9, :, :6] = gyroscopic_matrix(np.eye(6))
    for r in range(3):
        E[9, r, 6 + r] = -1.0
        E[10 + r, r, 9] = 1.0
    return E


_VMAP = _variable_map()


def _gram(V: np.ndarray) -> np.ndarray:
    """``V' V`` (thin matrices: numpy's loop below ``_BLAS_MIN_ROWS`` rows, else BLAS)."""
    if len(V) >= _BLAS_MIN_ROWS:
        return V.T @ V
    # multithreaded BLAS on a thin matrix costs more in thread start-up than it saves,
    # badly so on a loaded machine
    return np.einsum('ni,nj->ij', V, V)


_VMAP2 = np.ascontiguousarray(_VMAP.reshape(13, 30))


def _lift(G13: np.ndarray) -> np.ndarray:
    """Cross Grams (3, 3, 10, 10) of the equation blocks from a 13 x 13 Gram of ``V``.

    ``C[r, s, q, p] = sum_ij VMAP[i, r, q] G13[i, j] VMAP[j, s, p]``, as two small matrix
    products (a tenth of the time of the three-operand ``einsum``; the recursive estimator
    runs it twice per ``estimate()``).
    """
    C = _VMAP2.T @ G13 @ _VMAP2                       # (30, 30): [r q] x [s p]
    return np.ascontiguousarray(C.reshape(3, 10, 3, 10).transpose(0, 2, 1, 3))


@dataclass
class _Equations:
    """Stacked 3-row equation blocks ``y_b = X6_b theta + Xd_b d + e_b``.

    Stored as the per-sample variables ``V`` (n, 13); ``A = V @ E`` (n, 3, 10) on demand.
    """

    V: np.ndarray                  # (n, 13)
    t: np.ndarray                  # (n,) time of each equation [s]
    breaks: np.ndarray             # (n-1,) bool: a segment must start after this equation
    kind: str                      # 'anchored' (segment intercepts, model covariance) or 'hac'
    hac_lag: int = 0
    eiv_var: np.ndarray | None = None   # gyro noise variance in the regressor, per axis
    weighted: bool = False
    info: dict[str, Any] = field(default_factory=dict)
    raw: dict[str, Any] | None = None    # shared statistics, see _raw

    def head(self, n: int) -> _Equations:
        """The first ``n`` equations."""
        return _Equations(self.V[:n].copy(), self.t[:n], self.breaks[:max(n - 1, 0)], self.kind,
                          self.hac_lag, self.eiv_var, self.weighted, dict(self.info))

    @property
    def A(self) -> np.ndarray:
        """Equation blocks (n, 3, 10)."""
        return (self.V @ _VMAP2).reshape(-1, 3, 10)


def _cross(A: np.ndarray) -> np.ndarray:
    """Cross Gram matrices ``C[r, s] = sum_b A_b[r]' A_b[s]``, shape (3, 3, q, q)."""
    n, _, q = A.shape
    A2 = A.reshape(n, 3 * q)
    if n >= _BLAS_MIN_ROWS:
        G = A2.T @ A2
    else:
        # small problems: numpy's own loop; multithreaded BLAS on a thin matrix costs more in
        # thread start-up than it saves, badly so on a loaded machine
        G = np.einsum('ni,nj->ij', A2, A2)
    return G.reshape(3, q, 3, q).transpose(0, 2, 1, 3)


def _metric(C: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``sum_b A_b' M A_b`` from the cross Grams."""
    return np.einsum('rs,rsij->ij', M, C)


def _range_sums(V: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Sums of the row ranges ``V[bounds[k]:bounds[k+1]]``, shape (len(bounds) - 1, q).

    A sparse indicator product: a compiled loop over contiguous rows, several times faster
    than ``np.add.reduceat`` on a thin matrix.
    """
    n = V.shape[0]
    ind = sparse.csr_matrix((np.ones(n), np.arange(n), bounds), shape=(len(bounds) - 1, n))
    return ind @ V


def _torque_stats(V: np.ndarray, t: np.ndarray, t_tau: np.ndarray,
                  tau_end: float) -> np.ndarray:
    """``P_j = sum_b o_j(b) V_b`` for every torque interval ``j``, shape (M, q).

    Torque sample ``j`` carries white noise ``nu_j`` held over ``[s_j, s_{j+1})``; anchored
    equation ``b`` contains ``-sum_j o_j(b) nu_j`` with ``o_j(b) = clip(t_b - s_j, 0, h_j)``.
    With segment-demeaned variables the constant part of every segment cancels, so one global
    sum serves all segments.
    """
    n, q = V.shape
    m = len(t_tau)
    ends = np.append(t_tau[1:], max(tau_end, t_tau[-1]))
    h = ends - t_tau
    # samples of interval j (s_j <= t_b < s_{j+1}) form the contiguous range from first[j]
    first = np.searchsorted(t, t_tau, side='left')
    first[0] = 0                                      # (no sample precedes t_tau[0])
    indptr = np.append(first, n)
    counts = np.diff(indptr)
    u = t - np.repeat(t_tau, counts)                  # time since the interval's sample
    # per-interval sums of V and of u V as one sparse (2M, n) product: a compiled loop over
    # contiguous row ranges, several times faster than ufunc.reduceat on a thin matrix
    both = sparse.csr_matrix((np.concatenate([np.ones(n), u]),
                              np.concatenate([np.arange(n), np.arange(n)]),
                              np.concatenate([indptr, n + indptr[1:]])), shape=(2 * m, n))
    SS = both @ V
    S, St = SS[:m], SS[m:]
    after = np.zeros((m, q))
    after[:-1] = np.cumsum(S[::-1], axis=0)[::-1][1:]
    return h[:, None] * after + St


@dataclass
class _Stats:
    """Sufficient statistics of one segmentation of the equations."""

    C: np.ndarray                  # (3, 3, 10, 10) cross Grams of (demeaned) A
    CP: np.ndarray | None          # (3, 3, 10, 10) cross Grams of the torque-noise sums
    n: int
    n_eff: int                     # equations minus segment intercepts
    n_seg: int
    eq: _Equations
    A: np.ndarray | None           # demeaned A, kept for the HAC covariance
    walk_time: float = 0.0         # sum over segments of n_s * duration_s / 6 [s]
    torque_dt: float = 0.0         # median torque sample interval [s]


def _raw(eq: _Equations, t_tau: np.ndarray, tau_end: float,
         torque_var: np.ndarray) -> dict[str, Any]:
    """Statistics of the (globally centred) variables that every segmentation shares."""
    if eq.raw is not None:
        return eq.raw
    eq.V -= eq.V.mean(axis=0)[None]           # a constant shift cancels in segment demeaning
    walk = np.any(torque_var > 0) and len(t_tau) > 1
    # (two threads overlapping the Gram and the torque sums no longer pay: with the sparse
    # interval sums a 1M-sample record is faster on one thread, measured 0.51 s against 0.65 s)
    G = _gram(eq.V)
    P = _torque_stats(eq.V[:, :_NREG], eq.t, t_tau, tau_end) if walk else None
    raw: dict[str, Any] = {'G': G, 'CT': np.concatenate([[0.0], np.cumsum(eq.t)])}
    if P is not None:
        ends = np.append(t_tau[1:], max(tau_end, t_tau[-1]))
        raw.update(P=P, s=t_tau, h=ends - t_tau, k0=np.searchsorted(eq.t, t_tau, side='right'),
                   k1=np.searchsorted(eq.t, ends, side='left'))
    eq.raw = raw
    return raw


def _stats(eq: _Equations, segment: float | None, t_tau: np.ndarray, tau_end: float,
           torque_var: np.ndarray) -> _Stats:
    """Reduce the equations of one segmentation to cross Gram matrices.

    Anchored methods: the per-segment demeaning is applied to shared raw statistics
    (``C - sum_s n_s m_s' m_s``; the torque-noise sums corrected with prefix sums of the
    segment means), so trying several segment lengths costs O(segments + torque samples).
    """
    n = len(eq.t)
    if eq.kind != 'anchored':
        return _Stats(_lift(_gram(eq.V)), None, n, n, 0, eq, eq.A)
    raw = _raw(eq, t_tau, tau_end, torque_var)
    starts = _segments(eq.t, eq.breaks, segment)
    bounds = np.append(starts, n)
    ns = np.diff(bounds).astype(float)
    S = _range_sums(eq.V, bounds)                             # (nseg, 13) segment sums
    m = S / ns[:, None]
    C = _lift(raw['G'] - np.einsum('s,si,sj->ij', ns, m, m))
    CP = None
    if 'P' in raw:
        CT = raw['CT']
        S, m = S[:, :_NREG], m[:, :_NREG]                     # regressor variables only
        Sp = np.vstack([np.zeros(_NREG), np.cumsum(S, axis=0)])
        TS = CT[bounds[1:]] - CT[starts]
        MTp = np.vstack([np.zeros(_NREG), np.cumsum(m * TS[:, None], axis=0)])

        def ZQ(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """``sum_{b<k} m_seg(b)`` and ``sum_{b<k} t_b m_seg(b)`` (one segment search)."""
            sk = np.searchsorted(starts, k, side='right') - 1
            mk = m[sk]
            return (Sp[sk] + (k - starts[sk])[:, None] * mk,
                    MTp[sk] + (CT[k] - CT[starts[sk]])[:, None] * mk)

        z0, q0 = ZQ(raw['k0'])
        z1, q1 = ZQ(raw['k1'])
        adj = raw['h'][:, None] * (Sp[-1][None] - z1) + (q1 - q0) \
            - raw['s'][:, None] * (z1 - z0)
        GP = np.zeros((13, 13))
        GP[:_NREG, :_NREG] = _gram(raw['P'] - adj)
        CP = _lift(GP)
    dur = eq.t[bounds[1:] - 1] - eq.t[starts]
    if 'torque_dt' not in raw:              # the same for every segmentation: once
        raw['torque_dt'] = float(np.median(np.diff(t_tau))) if len(t_tau) > 1 else 0.0
    tdt = raw['torque_dt']
    return _Stats(C, CP, n, n - len(starts), len(starts), eq, None,
                  walk_time=float(np.sum(ns * dur)) / 6.0, torque_dt=tdt)


@dataclass
class _Fit:
    """One weighted least-squares fit of a parameter set."""

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
    g: np.ndarray | None = None    # (p,) right-hand side of H beta = g
    meat: np.ndarray | None = None  # (p, p) middle of the sandwich (inflation included)
    H_full: np.ndarray | None = None  # information of the full model (fits with an offset)


def _solve_sym(H: np.ndarray, rhs: np.ndarray) -> np.ndarray:
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


def _selector(basis: np.ndarray, bias: bool, offset: np.ndarray | None = None) -> np.ndarray:
    """Map (10, p + 1) from [psi, d, 1] to the columns [X6 | Xd | y] of ``A``.

    ``offset`` (6,) is a fixed part of theta moved to the right-hand side.
    """
    k = basis.shape[1]
    p = k + (3 if bias else 0)
    T = np.zeros((10, p + 1))
    T[:6, :k] = basis
    if bias:
        T[6:9, k:k + 3] = np.eye(3)
    T[9, p] = 1.0
    if offset is not None:
        T[:6, p] = -offset
    return T


def _fit(st: _Stats, basis: np.ndarray, bias: bool, W: np.ndarray, gyro_var: np.ndarray,
         torque_var: np.ndarray, bias_comp: bool, offset: np.ndarray | None = None) -> _Fit:
    """Weighted LS of ``y = X6 (T psi + offset) (+ Xd d)`` with its covariance."""
    k = basis.shape[1]
    T = _selector(basis, bias, offset)
    p = T.shape[1] - 1
    G = T.T @ _metric(st.C, W) @ T
    H0 = G[:p, :p]
    g = G[:p, p]
    H = H0.copy()
    if bias_comp and st.eq.eiv_var is not None:
        B6 = np.einsum('c,crk,rs,csl->kl', st.eq.eiv_var, _L_BASIS, W, _L_BASIS)
        H[:k, :k] -= st.n_eff * (basis.T @ B6 @ basis)
        if offset is not None:
            # the held part's regressor carries the same gyro noise: g = -B' X6'X6 offset
            # is compensated like H (B' (X6'X6 - n B6) offset)
            g = g.copy()
            g[:k] += st.n_eff * (basis.T @ B6 @ offset)
    beta = _solve_sym(H, g)
    Hinv = _solve_sym(H, np.eye(p))
    c = np.append(-beta, 1.0)
    rss = np.array([c @ (T.T @ st.C[r, r] @ T) @ c for r in range(3)])
    if st.eq.kind == 'anchored':
        theta = basis @ beta[:k] + (0.0 if offset is None else offset)
        Im = theta_to_matrix(theta)
        S = Im @ np.diag(gyro_var) @ Im                           # white part of e_b
        meat = (T.T @ _metric(st.C, W @ S @ W) @ T)[:p, :p]
        if st.CP is not None:
            meat += (T.T @ _metric(st.CP, W @ np.diag(torque_var) @ W) @ T)[:p, :p]
        # residuals larger than the noise model predicts (misfit, unmodelled effects):
        # inflate the covariance by the excess, never deflate it
        rss_w = float(c @ G @ c)
        expected = st.n_eff * float(np.trace(W @ S)) + st.walk_time * st.torque_dt * float(
            np.trace(W @ np.diag(torque_var)))
        excess = rss_w / expected if expected > 0 else 1.0
    else:
        excess = 1.0
        X = st.A @ T                                               # (n, 3, p + 1)
        e = X @ c                                                  # (n, 3) residuals
        scores = np.einsum('nrp,rs,ns->np', X[..., :p], W, e)
        meat = scores.T @ scores
        for lag in range(1, st.eq.hac_lag + 1):
            wgt = 1.0 - lag / (st.eq.hac_lag + 1.0)
            Gl = scores[lag:].T @ scores[:-lag]
            meat += wgt * (Gl + Gl.T)
    cov = Hinv @ meat @ Hinv.T
    cov = 0.5 * (cov + cov.T) * max(excess, 1.0)
    dof = max(st.n_eff - p, 1)
    H_full = None
    if offset is not None:
        # information of all six elements under the same weights: how the held elements
        # leak into the estimated ones (see _conclude)
        Tf = _selector(np.eye(6), bias)
        pf = Tf.shape[1] - 1
        H_full = (Tf.T @ _metric(st.C, W) @ Tf)[:pf, :pf]
        if bias_comp and st.eq.eiv_var is not None:
            H_full[:6, :6] -= st.n_eff * B6
    return _Fit(beta=beta, cov=cov, H=H, H0=H0, basis=basis, bias=bias, offset=offset,
                resid_rms=np.sqrt(np.maximum(rss, 0.0) / dof), n_eq=st.n, excess=excess,
                g=g, meat=meat * max(excess, 1.0), H_full=H_full)


def _weight(theta: np.ndarray, gyro_var: np.ndarray) -> np.ndarray:
    """Equation weight ``(I S_g I)^-1`` (scaled to max 1) from a first-pass theta."""
    Im = theta_to_matrix(theta)
    if not check_physical(Im).valid:
        Im = nearest_physical(Im, min_moment=1e-3 * max(float(np.sum(np.abs(Im))), 1e-30))
    S = Im @ np.diag(gyro_var) @ Im
    W = np.linalg.inv(S)
    return 0.5 * (W + W.T) / np.max(np.abs(W))


def _fit2(st: _Stats, basis: np.ndarray, bias: bool, gyro_var: np.ndarray,
          torque_var: np.ndarray, offset: np.ndarray | None = None,
          theta0: np.ndarray | None = None) -> _Fit:
    """Two-pass fit: unweighted, then weighted by the first pass's tensor (weighted methods).

    ``theta0`` (6,), a tensor from an earlier fit of the same data, gives the weights at once
    (one weighted pass; model selection refits the same equations several times).
    """
    if theta0 is not None and st.eq.weighted and np.all(gyro_var > 0) \
            and np.all(np.isfinite(theta0)) and np.any(theta0[:3] != 0):
        return _fit(st, basis, bias, _weight(theta0, gyro_var), gyro_var, torque_var,
                    st.eq.weighted, offset)
    f = _fit(st, basis, bias, np.eye(3), gyro_var, torque_var, st.eq.weighted, offset)
    if st.eq.weighted and np.all(gyro_var > 0):
        theta = basis @ f.beta[:basis.shape[1]] + (0.0 if offset is None else offset)
        if np.all(np.isfinite(theta)) and np.any(theta[:3] != 0):
            f = _fit(st, basis, bias, _weight(theta, gyro_var), gyro_var, torque_var,
                     st.eq.weighted, offset)
    return f


# ---------------------------------------------------------------------------------------------
# builders per method
# ---------------------------------------------------------------------------------------------
def _segments(t: np.ndarray, keep_break: np.ndarray, max_len: float | None) -> np.ndarray:
    """Segment start indices: at ``keep_break`` positions and every ``max_len`` seconds."""
    starts = [0, *(np.flatnonzero(keep_break) + 1).tolist()]
    if max_len is not None and max_len > 0:
        out: list[int] = []
        bounds = [*starts, len(t)]
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            n_sub = max(1, int(np.floor((t[b - 1] - t[a]) / max_len + 0.5)))
            edges = np.linspace(t[a], t[b - 1], n_sub + 1)[1:-1]
            out += [a, *(a + np.searchsorted(t[a:b], edges)).tolist()]
        starts = out
    return np.unique(np.asarray(starts, dtype=int))


def _variables(w: np.ndarray, m: np.ndarray, s: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Stack the 13 per-sample variables ``[w, m, s, y]`` (see :func:`_variable_map`)."""
    return np.concatenate([w, m, s[:, None], y], axis=1)


def _build(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
           mask: np.ndarray, breaks: np.ndarray, hold: str, gyro_var: np.ndarray,
           window: float | None) -> _Equations:
    """Equations of ``method`` from the gyro samples selected by ``mask``."""
    # every sample used (the common case): views instead of fancy-indexed copies
    idx: slice | np.ndarray = slice(None) if mask.all() else np.flatnonzero(mask)
    t = tg[idx]
    if method in ('integral', 'integral_ls'):
        comp = method == 'integral'
        M = cumulative_monomials(tg, w, gyro_var if comp else None)[idx]
        T = cumulative_torque(ts, tau, t, hold)
        return _Equations(_variables(w[idx], M, t - t[0], T), t, breaks, 'anchored',
                          eiv_var=gyro_var if comp else None, weighted=comp)
    if method == 'integral_sliding':
        dt = float(np.median(np.diff(t)))
        wl = max(2, round((window or 2.0) / dt))
        stride = max(1, wl // 4)
        M = cumulative_monomials(tg, w)[idx]
        T = cumulative_torque(ts, tau, t, hold)
        seg = np.cumsum(np.append(0, breaks.astype(int)))
        a = np.arange(0, max(len(t) - wl, 0), stride)
        a = a[seg[a] == seg[a + wl]]
        b = a + wl
        wi = w[idx]
        V = _variables(wi[b] - wi[a], M[b] - M[a], t[b] - t[a], T[b] - T[a])
        return _Equations(V, t[b], np.zeros(max(len(b) - 1, 0), dtype=bool), 'hac',
                          hac_lag=int(np.ceil(wl / stride)),
                          info={'window_s': wl * dt, 'windows': len(a)})
    # differential forms: torque value in effect at each gyro time
    j = np.clip(np.searchsorted(ts, t, side='right') - 1, 0, len(ts) - 1)
    if hold == 'zoh':
        tq = tau[j]
    else:
        tq = np.column_stack([np.interp(t, ts, tau[:, c]) for c in range(3)])
    wi = w[idx]
    if method == 'differential_fd':
        wd = np.gradient(wi, t, axis=0)
        m = monomials(wi)
        lag = 2
        info: dict[str, Any] = {}
        # central difference: var = 2 sigma^2 / (t_{k+1} - t_{k-1})^2 per sample
        span = np.empty(len(t))
        span[1:-1] = t[2:] - t[:-2]
        span[0], span[-1] = 2.0 * (t[1] - t[0]), 2.0 * (t[-1] - t[-2])
        noise_gain = float(np.mean(2.0 / span ** 2))
    else:
        dt = float(np.median(np.diff(t)))
        wl = max(5, round((window or 1.0) / dt))
        wl += 1 - wl % 2
        wl = min(wl, len(t) - (1 - len(t) % 2))
        ws = signal.savgol_filter(wi, wl, 3, axis=0)
        wd = signal.savgol_filter(wi, wl, 3, deriv=1, delta=dt, axis=0)
        tq = signal.savgol_filter(tq, wl, 3, axis=0)
        m = monomials(ws)
        lag = wl
        info = {'window_s': wl * dt}
        noise_gain = float(np.sum(signal.savgol_coeffs(wl, 3, deriv=1, delta=dt) ** 2))
    # errors in variables: the share of the differentiated gyro's power that is gyro noise
    noise_pow = noise_gain * gyro_var
    info['regressor_noise_share'] = noise_pow / np.maximum(np.mean(wd ** 2, axis=0), 1e-300)
    V = _variables(wd, m, np.ones(len(t)), tq)
    return _Equations(V, t, np.zeros(len(t) - 1, dtype=bool), 'hac', hac_lag=lag, info=info)


# ---------------------------------------------------------------------------------------------
# result assembly
# ---------------------------------------------------------------------------------------------
def _describe(v: np.ndarray, names: list[str]) -> str:
    """Human readable linear combination, largest coefficients first."""
    v = v / np.max(np.abs(v))
    order = np.argsort(-np.abs(v))
    parts = [f'{v[i]:+.2f} {names[i]}' for i in order if abs(v[i]) >= 0.05]
    return ' '.join(parts)


def _param_names(basis: np.ndarray, bias: bool, model: str) -> list[str]:
    """Names of the fitted parameters."""
    if model == 'axisymmetric':
        names = ['i_transverse', 'i_axial']
    else:
        names = [THETA_NAMES[int(np.argmax(basis[:, i]))] for i in range(basis.shape[1])]
    return names + (['dx', 'dy', 'dz'] if bias else [])


def _conditioning(fit: _Fit, names: list[str]) -> dict[str, Any]:
    """Condition number and weakest direction of the column-scaled information matrix."""
    d = np.sqrt(np.diag(fit.H0))
    if np.any(d == 0):
        k = int(np.argmin(d))
        return {'condition_number': float('inf'), 'weakest_direction': names[k]}
    Hs = fit.H0 / d[:, None] / d[None, :]
    lam, vec = np.linalg.eigh(Hs)
    cond = float(lam[-1] / lam[0]) if lam[0] > 0 else float('inf')
    return {'condition_number': cond, 'weakest_direction': _describe(vec[:, 0], names)}


def _undetermined(f: _Fit) -> tuple[np.ndarray, bool]:
    """Elements (6,) of a full-model fit that the data does not determine.

    For each element, the conditional information (the other parameters partialled out) with
    the gyro-noise contribution removed, ``1 / (H^-1)_kk``, is compared with the same
    information including the noise, ``1 / (H0^-1)_kk``.  Their ratio is the share of what the
    data says about the element that is signal rather than gyro noise; collinear but clean
    columns keep a ratio near 1 (their standard errors say the rest), noise-dominated ones fall
    towards 0 or below.  The element with the smallest ratio under ``_SIGNAL_SHARE`` is
    declared undetermined and removed, and the test is repeated on the rest.  Also, while the
    scaled noise-free information has a direction with less than ``_NULL_FRACTION`` signal,
    the gyro-noise-carrying element loading most on it is removed.

    Returns the mask and True (kept for the caller's interface: the bias is judged by its
    standard error and Wald test).
    """
    out = np.zeros(6, dtype=bool)
    p = len(f.beta)
    h0 = np.diag(f.H0)
    if np.any(h0[:6] <= 0):
        out[:6] = h0[:6] <= 0
        return out, True
    d = 1.0 / np.sqrt(h0)
    Hs = 0.5 * (f.H + f.H.T) * d[:, None] * d[None, :]
    H0s = 0.5 * (f.H0 + f.H0.T) * d[:, None] * d[None, :]
    share = np.zeros(p)                                # gyro-noise share of each column
    share[:6] = 1.0 - np.diag(f.H)[:6] / h0[:6]
    keep = list(range(p))
    while any(k < 6 for k in keep):
        idx = np.ix_(keep, keep)
        theta_pos = [i for i in range(len(keep)) if keep[i] < 6]
        # first: a direction with (almost) no signal once the noise is removed, loaded by
        # columns that carry gyro noise (errors in variables, not mere collinearity)
        lam, vec = np.linalg.eigh(Hs[idx])
        if lam[0] < _NULL_FRACTION:
            v = np.abs(vec[:, 0])
            cand = [i for i in theta_pos if share[keep[i]] >= _NOISE_SHARE]
            if cand:
                keep.remove(keep[max(cand, key=lambda i: v[i])])
                continue
        # then: each element's conditional signal share
        try:
            inv0 = np.diag(np.linalg.inv(H0s[idx]))
            inv = np.diag(np.linalg.pinv(Hs[idx]))
        except np.linalg.LinAlgError:
            break
        ratio = np.where(inv > 0, inv0 / np.where(inv > 0, inv, 1.0), -1.0)
        worst = min(theta_pos, key=lambda i: ratio[i])
        if ratio[worst] >= _SIGNAL_SHARE:
            break
        keep.remove(keep[worst])
    out[sorted(set(range(6)) - set(keep))] = True
    return out, True


def _held_leak(f: _Fit, free: np.ndarray, scale: float) -> np.ndarray:
    """Covariance the estimated elements inherit from the held (undetermined) ones.

    The held elements are uncertain by a plausible spread (diagonal: +-scale/2, products:
    +-scale/4, uniform); through the coupling ``H_FF^-1 H_FU`` of the full-model information
    that uncertainty moves the estimated elements.
    """
    p = len(f.beta)
    if f.H_full is None:
        return np.zeros((p, p))
    Fi = [*np.flatnonzero(free).tolist(), *range(6, f.H_full.shape[0])]
    Ui = np.flatnonzero(~free)
    sens = np.linalg.lstsq(f.H_full[np.ix_(Fi, Fi)], f.H_full[np.ix_(Fi, Ui)], rcond=None)[0]
    spread = np.where(Ui < 3, 0.5 * scale, 0.25 * scale) / np.sqrt(3.0)
    return (sens * spread ** 2) @ sens.T              # (p, p): estimated elements + bias


def _wald(theta: np.ndarray, cov: np.ndarray, R: np.ndarray) -> tuple[float, int, float]:
    """Wald statistic, degrees of freedom and p-value of ``R theta = 0``."""
    r = R @ theta
    V = R @ cov @ R.T
    try:
        stat = float(r @ np.linalg.solve(V, r))
    except np.linalg.LinAlgError:
        stat = float(r @ np.linalg.pinv(V) @ r)
    dof = R.shape[0]
    return stat, dof, float(stats.chi2.sf(stat, dof))


def _complement(basis: np.ndarray) -> np.ndarray:
    """Rows spanning the orthogonal complement of the columns of ``basis`` (6, k)."""
    q, _ = np.linalg.qr(basis, mode='complete')
    return q[:, basis.shape[1]:].T


def _moment_std(I: np.ndarray, cov6: np.ndarray) -> np.ndarray:
    """First-order std of the principal moments from the theta covariance."""
    _, vec = np.linalg.eigh(I)
    out = np.empty(3)
    for i in range(3):
        v = vec[:, i]
        grad = np.array([v[0] ** 2, v[1] ** 2, v[2] ** 2, 2 * v[0] * v[1], 2 * v[0] * v[2],
                         2 * v[1] * v[2]])
        out[i] = np.sqrt(max(float(grad @ cov6 @ grad), 0.0))
    return out


def _axis_std(I: np.ndarray, cov6: np.ndarray) -> np.ndarray:
    """First-order angular std [rad] of each principal axis (ascending moments' order).

    Perturbation of a symmetric eigenproblem: ``dv_i = sum_{j != i} (v_j' dI v_i) /
    (l_i - l_j) v_j``, so ``E|dv_i|^2 = sum_j var(v_j' dI v_i) / (l_i - l_j)^2``: the RMS
    angle between the estimated and the true axis.  Infinite for repeated moments (the axes
    of a degenerate subspace are not determined).
    """
    lam, vec = np.linalg.eigh(I)
    out = np.empty(3)
    for i in range(3):
        var = 0.0
        for j in range(3):
            if j == i:
                continue
            a, b = vec[:, i], vec[:, j]
            g = np.array([a[0] * b[0], a[1] * b[1], a[2] * b[2], a[0] * b[1] + a[1] * b[0],
                          a[0] * b[2] + a[2] * b[0], a[1] * b[2] + a[2] * b[1]])
            gap = float(lam[i] - lam[j])
            var += max(float(g @ cov6 @ g), 0.0) / gap ** 2 if gap != 0.0 else np.inf
        out[i] = np.sqrt(var)
    return out


_TRACE = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])     # theta -> trace of the tensor


def _ratio_cov(theta: np.ndarray, cov6: np.ndarray) -> np.ndarray:
    """First-order covariance (6, 6) of ``theta / trace`` from that of ``theta``."""
    tr = float(_TRACE @ theta)
    J = (np.eye(6) - np.outer(theta / tr, _TRACE)) / tr
    return J @ cov6 @ J.T


def _sym(theta: np.ndarray) -> np.ndarray:
    """theta (6,) -> (3, 3) letting NaN through."""
    return theta_to_matrix(theta, check_finite=False)


# ---------------------------------------------------------------------------------------------
# public entry point
# ---------------------------------------------------------------------------------------------
def estimate(t_gyro: Any, omega: Any, t_torque: Any, torque: Any, *,
             method: str = 'auto', model: str = 'auto', torque_bias: str = 'auto',
             symmetry_axis: Any = None, hold: str = 'zoh', alpha: float = 1e-3,
             gyro_noise: Any = None, torque_noise: Any = None, segment: float | None = None,
             window: float | None = None, identifiability_tol: float = 0.1,
             physical: bool = True) -> InertiaEstimate:
    """Estimate the inertia tensor from gyro and torque samples (Euler's equations).

    Parameters
    ----------
    t_gyro : array_like, shape (N,)
        Gyro sample times [s], strictly increasing.
    omega : array_like, shape (N, 3)
        Angular velocity in body axes [rad/s].
    t_torque : array_like, shape (M,)
        Torque sample times [s], strictly increasing; M = 0 means torque-free data.
    torque : array_like, shape (M, 3)
        Known applied torque about the centre of mass, body axes [N m].
    method : str
        One of :data:`METHODS` (default ``auto``: ``ml``, or ``integral`` on records longer
        than :data:`ML_AUTO_MAX_SAMPLES` gyro samples).
    model : {'auto', 'full', 'diagonal', 'axisymmetric'}
        Parameter set; ``auto`` picks the smallest the data supports (Wald tests at ``alpha``;
        ``axisymmetric`` is only a candidate when ``symmetry_axis`` is given).
    torque_bias : {'auto', 'on', 'off'}
        Estimate a constant unmeasured disturbance torque (3 more parameters).
    symmetry_axis : {'x', 'y', 'z'} or array_like (3,), optional
        Body axis of symmetry for the axisymmetric model.
    hold : {'zoh', 'linear'}
        Torque between samples: zero-order hold (commands) or linear interpolation.
    alpha : float
        Test level of the model-selection Wald tests (0 < alpha < 1).
    gyro_noise, torque_noise : float or array_like (3,), optional
        White-noise std per axis [rad/s] and [N m]; estimated from the data when omitted.
    segment : float, optional
        Maximum anchored-segment duration [s] for the integral methods (default: whole run,
        split only at gaps).
    window : float, optional
        Window length [s] of ``integral_sliding`` (default 2 s) or ``differential_sg``
        (default 1 s; the same Savitzky-Golay filter is applied to the torque).
    identifiability_tol : float
        An element is identifiable when its standard error is below this fraction of the
        largest well-determined principal-diagonal element.
    physical : bool
        Project a physically impossible tensor onto the nearest valid one (reported in
        ``diagnostics['physical']``).

    Returns
    -------
    InertiaEstimate
        Always returned for well-formed input; the status says what the data allowed.

    Raises
    ------
    ValueError
        Malformed input: wrong shapes, NaN/inf, non-increasing times, fewer gyro samples than
        parameters, unknown option names.
    """
    tg = _times(t_gyro, 't_gyro')
    w = _vectors(omega, len(tg), 'omega', 't_gyro')
    ts = _times(t_torque, 't_torque')
    tau = _vectors(torque, len(ts), 'torque', 't_torque')
    if method not in METHODS:
        raise ValueError(f'method: must be one of {METHODS}, got {method!r}')
    if model not in MODELS:
        raise ValueError(f'model: must be one of {MODELS}, got {model!r}')
    if torque_bias not in TORQUE_BIAS:
        raise ValueError(f'torque_bias: must be one of {TORQUE_BIAS}, got {torque_bias!r}')
    if hold not in HOLDS:
        raise ValueError(f'hold: must be one of {HOLDS}, got {hold!r}')
    if not 0.0 < alpha < 1.0:
        raise ValueError(f'alpha: must be in (0, 1), got {alpha!r}')
    if not 0.0 < identifiability_tol:
        raise ValueError(f'identifiability_tol: must be > 0, got {identifiability_tol!r}')
    axis = _axis(symmetry_axis)
    if model == 'axisymmetric' and axis is None:
        raise ValueError("symmetry_axis: required for model='axisymmetric'")
    if len(tg) < 6:
        raise ValueError(f't_gyro: {len(tg)} samples is fewer than the 6 inertia parameters')
    if len(ts) == 1:
        raise ValueError('t_torque: a single torque sample covers no time; give at least 2 '
                         '(or none for torque-free data)')
    selection = None
    if method == 'auto':
        method = 'ml' if len(tg) <= ML_AUTO_MAX_SAMPLES else 'integral'
        selection = {'requested': 'auto', 'chosen': method,
                     'rule': f'ml up to {ML_AUTO_MAX_SAMPLES} gyro samples, integral beyond'}
    if method == 'ml':
        first = estimate(tg, w, ts, tau, method='integral', model=model,
                         torque_bias=torque_bias, symmetry_axis=symmetry_axis, hold=hold,
                         alpha=alpha, gyro_noise=gyro_noise, torque_noise=torque_noise,
                         segment=segment, window=window,
                         identifiability_tol=identifiability_tol, physical=physical)
        res = _maximum_likelihood(first, tg, w, ts, tau, hold, axis)
        if selection is not None:
            res.diagnostics['method_selection'] = selection
        return res
    # work relative to the first stamp: ROS times are ~1.7e9 s, and prefix sums of absolute
    # times would lose the sub-millisecond differences everything depends on
    t_origin = float(min(tg[0], ts[0])) if len(ts) else float(tg[0])
    tg = tg - t_origin
    ts = ts - t_origin
    if segment is not None and not segment > 0:
        raise ValueError(f'segment: must be > 0 s, got {segment!r}')
    if window is not None and not window > 0:
        raise ValueError(f'window: must be > 0 s, got {window!r}')
    if gyro_noise is None:
        gyro_std = noise_std_from_differences(w)
        gyro_std = np.maximum(gyro_std, 0.1 * float(np.max(gyro_std)))   # isotropy floor
    else:
        gyro_std = _noise(gyro_noise, 'gyro_noise')
    torque_std = (noise_std_from_differences(tau) if torque_noise is None or len(ts) == 0
                  else _noise(torque_noise, 'torque_noise'))
    if len(ts) == 0:
        torque_std = np.zeros(3)
    gyro_var, torque_var = gyro_std ** 2, torque_std ** 2
    diag: dict[str, Any] = {'gyro_noise_std': gyro_std, 'torque_noise_std': torque_std,
                            'warnings': []}
    if selection is not None:
        diag['method_selection'] = selection

    # ---- torque coverage and gaps
    dtg = np.diff(tg)
    if len(ts):
        dts = np.diff(ts)
        med_ts = float(np.median(dts))
        tau_end = ts[-1] + (med_ts if hold == 'zoh' else 0.0)
        mask = (tg >= ts[0]) & (tg <= tau_end)
        gap = dts > 5.0 * med_ts
        if np.any(gap):
            j = np.clip(np.searchsorted(ts, tg, side='right') - 1, 0, len(ts) - 1)
            inside_gap = gap[np.minimum(j, len(dts) - 1)] & (j < len(dts)) & (tg > ts[j])
            mask &= ~inside_gap
            diag['warnings'].append(f'{int(np.sum(gap))} torque gap(s) longer than 5 sample '
                                    f'periods: gyro samples inside them dropped')
    else:
        tau_end = float(tg[-1])
        mask = np.ones(len(tg), dtype=bool)
    used = int(np.sum(mask))
    dropped = len(tg) - used
    idx = np.flatnonzero(mask)
    base = dict(method=method, samples_used=used, samples_dropped=dropped)
    if used < 20:
        diag['reason'] = (f'only {used} gyro samples inside the torque coverage '
                          f'[{ts[0] if len(ts) else tg[0]:.6g}, {tau_end:.6g}] s')
        return InertiaEstimate(status='insufficient_data', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    med_g = float(np.median(dtg))
    breaks = (np.diff(idx) > 1) | (np.diff(tg[idx]) > 5.0 * med_g)

    torque_rms = np.sqrt(np.mean(tau ** 2, axis=0)) if len(ts) else np.zeros(3)
    diag['torque_rms'] = torque_rms
    torque_free = len(ts) == 0 or float(np.max(torque_rms)) <= 5.0 * float(
        np.max(torque_std)) or float(np.max(torque_rms)) == 0.0
    if torque_free:
        return _homogeneous(method, tg, w, ts, tau, mask, breaks, hold, gyro_var,
                            segment or 10.0, window, diag, base)

    eq = _build(method, tg, w, ts, tau, mask, breaks, hold, gyro_var, window)
    diag.update(eq.info)
    share = eq.info.get('regressor_noise_share')
    if share is not None and float(np.max(share)) > _EIV_MAX_SHARE:
        diag['reason'] = (
            f'errors in variables: gyro noise is {100 * float(np.max(share)):.3g} % of the '
            f'differentiated gyro (limit {100 * _EIV_MAX_SHARE:g} %), which biases the '
            f'{method} fit towards zero by about as much; use the integral or ml method '
            '(no differentiation)' + (', or a longer window' if method == 'differential_sg'
                                      else ''))
        return InertiaEstimate(status='insufficient_excitation', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    gen_bias = torque_bias != 'off'
    if len(eq.t) < 3 * (6 + 3):
        diag['reason'] = f'{len(eq.t)} equations are too few for the parameters'
        return InertiaEstimate(status='insufficient_data', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    if eq.kind == 'anchored' and segment is None:
        segment, diag['segment_selection'] = _choose_segment(eq, ts, tau_end, gyro_var,
                                                             torque_var, gen_bias)
    st = _stats(eq, segment, ts, tau_end, torque_var)
    if eq.kind == 'anchored':
        diag['segments'] = st.n_seg
        diag['segment_s'] = segment
        if st.n_eff < 3 * (6 + 3):
            diag['reason'] = f'{st.n_eff} equations are too few for the parameters'
            return InertiaEstimate(status='insufficient_data', diagnostics=diag,
                                   **base)   # type: ignore[arg-type]

    def fit(basis: np.ndarray, bias: bool, offset: np.ndarray | None = None,
            theta0: np.ndarray | None = None) -> _Fit:
        """Fit one parameter set on the statistics (weights from ``theta0`` when given)."""
        return _fit2(st, basis, bias, gyro_var, torque_var, offset, theta0)

    return _conclude(fit, model, torque_bias, axis, alpha, identifiability_tol, physical,
                     diag, base)


def _conclude(fit: Any, model: str, torque_bias: str, axis: np.ndarray | None, alpha: float,
              identifiability_tol: float, physical: bool, diag: dict[str, Any],
              base: dict[str, Any]) -> InertiaEstimate:
    """Identifiability, model selection and the result, given ``fit(basis, bias) -> _Fit``."""
    gen_bias = torque_bias != 'off'
    # ---- identifiability on the general model
    f = fit(np.eye(6), gen_bias)
    names = _param_names(np.eye(6), gen_bias, 'full')
    diag.update(_conditioning(f, names))
    und, bias_ok = _undetermined(f)
    if not bias_ok:
        gen_bias = False
        torque_bias = 'off'
        diag['warnings'].append('the torque bias is not determined by this excitation: '
                                'estimated without it')
        f = fit(np.eye(6), False)
        und, _ = _undetermined(f)
    free = ~und
    insufficient = InertiaEstimate(
        status='insufficient_excitation', diagnostics=dict(
            diag, reason='no principal-diagonal element is determined by the data'),
        **base)   # type: ignore[arg-type]
    if not np.any(free[:3]):
        return insufficient
    if np.any(und):
        # undetermined elements held at a plausible value (the mean determined moment, zero
        # products) so that the weights and the other elements see a physical tensor
        det = [abs(float(f.beta[i])) for i in range(3) if free[i]]
        hold = float(np.median(det))
        offset = np.zeros(6)
        for _ in range(2):
            offset = np.zeros(6)
            offset[:3][und[:3]] = hold
            f = fit(np.eye(6)[:, free], gen_bias, offset)
            theta_f = np.eye(6)[:, free] @ f.beta[:int(np.sum(free))]
            hold = float(np.mean([abs(theta_f[i]) for i in range(3) if free[i]]))
        diag['undetermined_held_at'] = dict(zip(
            [n for n, u in zip(THETA_NAMES, und, strict=True) if u], offset[und], strict=True))
    k = int(np.sum(free))
    basis = np.eye(6)[:, free]
    theta = basis @ f.beta[:k]
    se = basis @ np.sqrt(np.maximum(np.diag(f.cov)[:k], 0.0))
    good = [float(theta[i]) for i in range(3)
            if free[i] and theta[i] > 0 and se[i] < 0.2 * theta[i]]
    if not good:
        return insufficient
    scale = max(good)
    if np.any(und):
        f.cov = f.cov + _held_leak(f, free, scale)
        se = basis @ np.sqrt(np.maximum(np.diag(f.cov)[:k], 0.0))
    free = free & (se < identifiability_tol * scale)
    if not np.any(free[:3]):
        diag['reason'] = 'no principal-diagonal element is determined by the data'
        return InertiaEstimate(status='insufficient_excitation', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    if not np.all(free):
        if torque_bias == 'auto' and gen_bias:
            stat, dof, pval = _wald(f.beta, f.cov, np.eye(len(f.beta))[k:])
            diag['model_selection'] = {'bias': {'wald': stat, 'dof': dof, 'p_value': pval,
                                                'kept': bool(pval < alpha)}}
            if pval >= alpha:
                held = f.offset if f.offset is not None else np.zeros(6)
                f = fit(np.eye(6)[:, free], False, held)
                f.cov = f.cov + _held_leak(f, free, scale)
        return _assemble('partially_identifiable', f, 'full', free, diag, base, physical=False)

    # ---- model selection: bias first, then the parameter set
    selection: dict[str, Any] = {}
    bias_on = torque_bias == 'on'
    if torque_bias == 'auto':
        stat, dof, pval = _wald(f.beta, f.cov, np.eye(9)[6:])
        bias_on = pval < alpha
        selection['bias'] = {'wald': stat, 'dof': dof, 'p_value': pval,
                             'kept': bool(bias_on)}
        if not bias_on:
            f = fit(np.eye(6), False, theta0=f.basis @ f.beta[:6])
    chosen = model
    if model == 'auto':
        candidates = (['axisymmetric'] if axis is not None else []) + ['diagonal']
        tested = {}
        chosen = 'full'
        cov6 = f.cov[:6, :6]
        for cand in candidates:
            stat, dof, pval = _wald(f.beta[:6], cov6, _complement(model_basis(cand, axis)))
            tested[cand] = {'wald': stat, 'dof': dof, 'p_value': pval,
                            'rejected': bool(pval < alpha)}
            if pval >= alpha and chosen == 'full':
                chosen = cand
        selection['models'] = tested
        selection['rule'] = (f'smallest parameter set whose restriction of the full model is '
                             f'not rejected by a Wald test at alpha={alpha:g}')
        selection['chosen'] = chosen
    if selection:
        diag['model_selection'] = selection
    if chosen != 'full':
        f = fit(model_basis(chosen, axis), bias_on, theta0=f.basis @ f.beta[:6])
    return _assemble('ok', f, chosen, free, diag, base, physical=physical)


def _choose_segment(eq: _Equations, ts: np.ndarray, tau_end: float, gyro_var: np.ndarray,
                    torque_var: np.ndarray, bias: bool) -> tuple[float | None, dict[str, Any]]:
    """Anchored-segment length that minimises the predicted relative variance of the tensor.

    Short segments lose the information in slow motion and leave more errors-in-variables
    bias; long ones let the integrated torque noise (a random walk) grow.  The candidates are
    evaluated with the calibrated covariance of the full model; all candidates share the raw
    statistics (see :func:`_stats`), so the search costs little.  Long records are searched on
    their first ``_SELECT_MAX_ROWS`` equations (the optimum depends on the dynamics, not on the
    record length).
    """
    if len(eq.t) > _SELECT_MAX_ROWS:
        sub = eq.head(_SELECT_MAX_ROWS)
        ts = ts[:max(int(np.searchsorted(ts, sub.t[-1], side='right')), 2)]
        tau_end = max(float(sub.t[-1]), float(ts[-1]))
    else:
        sub = eq
    span = float(sub.t[-1] - sub.t[0])
    cands: list[float | None] = [s for s in _SEGMENT_CANDIDATES if s < 0.75 * span]
    cands.append(None)
    scores: dict[str, float] = {}
    best, best_score = None, np.inf
    for cand in cands:
        st = _stats(sub, cand, ts, tau_end, torque_var)
        if st.n_eff < 3 * (6 + 3):
            continue
        f = _fit2(st, np.eye(6), bias, gyro_var, torque_var)
        scale = float(np.mean(np.abs(f.beta[:3])))
        score = float(np.trace(f.cov[:6, :6])) / scale ** 2 if scale > 0 else np.inf
        scores['whole' if cand is None else f'{cand:g}'] = score
        if score < best_score:
            best, best_score = cand, score
    if best is None and sub is not eq:
        best = span                     # 'whole' of the searched part, not of the record
    return best, {'candidates_s': scores, 'chosen_s': 'whole' if best is None else best,
                  'rule': 'minimum predicted relative variance of theta'}


def _noise(x: Any, name: str) -> np.ndarray:
    """Validated per-axis noise std (scalar or (3,))."""
    arr = np.broadcast_to(np.asarray(x, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f'{name}: must be finite and >= 0, got {x!r}')
    return arr


def _assemble(status: str, f: _Fit, model: str, free: np.ndarray, diag: dict[str, Any],
              base: dict[str, Any], physical: bool) -> InertiaEstimate:
    """Build the :class:`InertiaEstimate` from a fit."""
    k = f.basis.shape[1]
    theta = f.basis @ f.beta[:k]
    cov6 = f.basis @ f.cov[:k, :k] @ f.basis.T
    se = np.sqrt(np.maximum(np.diag(cov6), 0.0))
    theta = np.where(free, theta, np.nan)
    se = np.where(free, se, np.nan)
    I = _sym(theta)
    I_std = _sym(se)
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
        moments, axes = principal_axes(I)
        diag['principal_moments_std'] = _moment_std(I, cov6)
        diag['principal_axes_std'] = _axis_std(I, cov6)
    else:
        undetermined = [n for n, ok in zip(THETA_NAMES, free, strict=True) if not ok]
        diag['undetermined'] = undetermined
        diag['reason'] = ('the excitation does not determine ' + ', '.join(undetermined)
                          + ' (reported as null)')
    ratios = I / np.trace(I)
    # undetermined products leave the other ratios defined; an undetermined moment, none
    r_se = np.sqrt(np.maximum(np.diag(_ratio_cov(np.where(free, theta, 0.0), cov6)), 0.0))
    ratios_std = _sym(np.where(free & bool(np.all(free[:3])), r_se, np.nan))
    bias = f.beta[k:k + 3] if f.bias else None
    if f.bias:
        diag['torque_bias_std'] = np.sqrt(np.maximum(np.diag(f.cov)[k:k + 3], 0.0))
    name = model + ('+bias' if f.bias else '')
    return InertiaEstimate(status=status, inertia=I, inertia_std=I_std,
                           principal_moments=moments, principal_axes=axes, ratios=ratios,
                           ratios_std=ratios_std,
                           identifiable=dict(zip(THETA_NAMES, map(bool, free), strict=True)),
                           torque_bias=bias, model=name, diagnostics=diag,
                           **base)   # type: ignore[arg-type]


def _homogeneous(method: str, tg: np.ndarray, w: np.ndarray, ts: np.ndarray, tau: np.ndarray,
                 mask: np.ndarray, breaks: np.ndarray, hold: str, gyro_var: np.ndarray,
                 segment: float | None, window: float | None, diag: dict[str, Any],
                 base: dict[str, Any]) -> InertiaEstimate:
    """Torque-free data: ratios and axes from the null vector of the homogeneous problem."""
    if len(ts) == 0:
        ts = np.array([tg[0], tg[-1]])
        tau = np.zeros((2, 3))
    meth = method if method != 'integral_ls' else 'integral'
    eq = _build(meth, tg, w, ts, tau, mask, breaks, hold, gyro_var, window)
    st = _stats(eq, segment, ts, float(ts[-1]), np.zeros(3))
    return _homogeneous_from_stats(st, gyro_var, diag, base)


def _trace_free_basis() -> np.ndarray:
    """Orthonormal basis (6, 5) of the theta directions that leave the trace unchanged."""
    q, _ = np.linalg.qr(np.array([[1.0, 0.0], [-1.0, 1.0], [0.0, -1.0]]))
    basis = np.zeros((6, 5))
    basis[:3, :2] = q
    basis[3:, 2:] = np.eye(3)
    return basis


_TRACE_FREE = _trace_free_basis()


def _homogeneous_from_stats(st: _Stats, gyro_var: np.ndarray, diag: dict[str, Any],
                            base: dict[str, Any], cov_scale: float = 1.0) -> InertiaEstimate:
    """Torque-free data: the ratios ``inertia / trace`` with their standard errors, and axes.

    With no torque the equations are homogeneous, ``X6 theta = e``: ``theta`` is fitted
    under the constraint ``trace = 1`` (``theta = offset + B psi`` with ``B`` spanning the
    trace-free directions), by the same weighted, bias-compensated least squares and
    covariance model as the torque-driven fits (:func:`_fit2`), the torque column dropped (it
    holds only sensor noise).  The eigenvalue gap of the homogeneous information says
    whether the motion singles out the ratios at all.

    Shared by the batch ``_homogeneous`` and the recursive estimator, so that both report
    the same ``scale_unobservable`` result.

    Parameters
    ----------
    st : _Stats
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
    A = None
    if st.A is not None:
        A = st.A.copy()
        A[..., 9] = 0.0
    st = replace(st, C=C, CP=None, A=A)
    eiv_var = st.eq.eiv_var
    n_eff = st.n_eff
    H0 = _metric(C, np.eye(3))[:6, :6]
    H = H0.copy()
    if eiv_var is not None:
        H -= n_eff * np.einsum('c,crk,csl->kl', eiv_var, _L_BASIS, _L_BASIS)
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
        diag['weakest_direction'] = _describe(vec[:, 1] / d, list(THETA_NAMES))
        return InertiaEstimate(status='insufficient_excitation', diagnostics=diag,
                               **base)   # type: ignore[arg-type]
    offset = _TRACE / 3.0
    f = _fit2(st, _TRACE_FREE, False, gyro_var, np.zeros(3), offset)
    theta = _TRACE_FREE @ f.beta + offset
    cov6 = cov_scale * (_TRACE_FREE @ f.cov @ _TRACE_FREE.T)
    diag['residual_excess'] = f.excess
    R = theta_to_matrix(theta)
    chk = check_physical(R)
    if not chk.valid:
        diag['physical'] = {'valid': False, 'failures': list(chk.failures), 'projected': True}
        R = nearest_physical(R)
        R /= np.trace(R)
    ratios, axes = principal_axes(R)
    diag['principal_ratios'] = ratios
    diag['principal_ratios_std'] = _moment_std(R, cov6)
    diag['principal_axes_std'] = _axis_std(R, cov6)
    return InertiaEstimate(status='scale_unobservable', ratios=R,
                           ratios_std=_sym(np.sqrt(np.maximum(np.diag(cov6), 0.0))),
                           principal_axes=axes, identifiable=dict.fromkeys(THETA_NAMES, False),
                           model='homogeneous', diagnostics=diag,
                           **base)   # type: ignore[arg-type]


def _maximum_likelihood(first: InertiaEstimate, tg: np.ndarray, w: np.ndarray, ts: np.ndarray,
                        tau: np.ndarray, hold: str, axis: np.ndarray | None) -> InertiaEstimate:
    """Refine an ``integral`` estimate by maximum likelihood (:func:`.ml.refine`)."""
    diag = dict(first.diagnostics)
    diag['warnings'] = list(diag.get('warnings', []))
    info: dict[str, Any] = {'refined': False, 'start': 'integral'}
    diag['ml'] = info

    def keep(reason: str) -> InertiaEstimate:
        info['reason'] = reason + '; the integral estimate is reported'
        return replace(first, method='ml', diagnostics=diag)

    if first.status != 'ok' or first.inertia is None:
        return keep(f'the starting estimate is {first.status!r}, only ok estimates are refined')
    if hold != 'zoh':
        return keep("the likelihood model holds each torque sample (hold='zoh' only)")
    if any('torque gap' in str(m) for m in diag['warnings']):
        return keep('torque gaps: the held-torque model does not cover them')
    t0 = float(min(tg[0], ts[0]))
    tg, ts = tg - t0, ts - t0
    # the gyro samples the integral stage used: inside the held torque's coverage
    inside = (tg >= ts[0]) & (tg <= ts[-1] + float(np.median(np.diff(ts))))
    name = first.model.removesuffix('+bias')
    basis = model_basis(name, axis)
    theta0 = first.theta
    assert theta0 is not None
    res = refine(tg[inside], w[inside], ts, tau, theta0, basis,
                 None if first.torque_bias is None else np.asarray(first.torque_bias),
                 np.asarray(diag['gyro_noise_std']), np.asarray(diag['torque_noise_std']))
    info.update(iterations=res.iterations, steps_in_std=res.steps, residual_excess=res.excess)
    if not res.converged:
        return keep(f'the refinement did not converge ({res.reason})')
    k = basis.shape[1]
    theta = basis @ res.beta
    cov6 = basis @ res.cov[:k, :k] @ basis.T
    I = _sym(theta)
    chk = check_physical(I)
    if not chk.valid:
        return keep('the refined tensor is not physical (' + '; '.join(chk.failures) + ')')
    info['refined'] = True
    if res.excess > 1.5:
        diag['warnings'].append(f'likelihood residuals are {res.excess:.3g} times the noise '
                                'model: standard errors inflated accordingly')
    moments, axes = principal_axes(I)
    diag['principal_moments_std'] = _moment_std(I, cov6)
    diag['principal_axes_std'] = _axis_std(I, cov6)
    diag['physical'] = {'valid': True, 'projected': False}
    if res.bias is not None:
        diag['torque_bias_std'] = np.sqrt(np.maximum(np.diag(res.cov)[k:k + 3], 0.0))
    return replace(first, method='ml', inertia=I,
                   inertia_std=_sym(np.sqrt(np.maximum(np.diag(cov6), 0.0))),
                   principal_moments=moments, principal_axes=axes, ratios=I / np.trace(I),
                   torque_bias=res.bias, diagnostics=diag)
