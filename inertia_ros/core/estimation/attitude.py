"""The body's attitude and its time integral from the gyro, for a torque fixed in inertial axes.

A disturbance torque constant in inertial axes, ``d`` (3,) in the body axes at the start of a
run, acts in body axes as ``R(t)' d``, where ``R(t)`` (3, 3) turns body axes at ``t`` into those
at the start (``R(t0) = 1``, ``R_dot = R [w]x``).  In the anchored momentum equations it adds
``(C(t_b) - C(t_a)) d`` with the cumulative integral ``C(t) = int_t0^t R(s)' ds`` [s]: linear in
``d``, so its nine entries are per-sample variables like the monomial integrals
(:mod:`.regressors`).  This module computes ``R`` and ``C`` at the gyro stamps of one
gap-free run (:func:`attitude_integral`).

Between two samples the rate is taken as constant (by default the mean of the two samples, a
second-order rule; any per-interval rates may be given), and for a constant rate ``u`` over a
step ``h`` both the step's rotation and its integral are closed forms (Rodrigues):

    exp([phi]x)                       = 1 + (sin q / q) [phi]x + ((1 - cos q) / q^2) [phi]x^2
    int_0^h exp(-[u s]x) ds           = h (1 - ((1 - cos q) / q^2) [phi]x
                                             + ((q - sin q) / q^3) [phi]x^2)

(``phi = u h``, ``q = |phi|``), so ``R_(k+1) = R_k exp([phi_k]x)`` and ``C_(k+1) = C_k +
J_k R_k'`` are exact for piecewise-constant rates, whatever the step.  The running product of
the step rotations is a scan, done in blocks of rows on flat arrays: every per-step 3 x 3 map
is held as nine entry planes (one vectorised operation per entry or per product, no stacked
small-matrix calls and no (N, 3, 3) temporaries of a long record), each block's steps laid
out as ``L`` short runs side by side and scanned ``L`` steps at a time across all runs at once
(with ``Q`` a run's own product and ``S`` the rotation at its start, ``R = S Q`` and the
run's share of ``C`` is ``(sum J Q') S'``), the runs' totals scanned the same way.  Three
3 x 3 products per sample and a few thousand vectorised operations for an hour of 200 Hz
gyro (~0.09 s per 720 000 samples on the 2-core development machine, 4-5x the stacked
implementation of fc1dd39, same values to ~1e-13 relative); each rotation is a product of at
most a few hundred factors (rounding ~1e-13, no re-orthonormalisation needed).

numpy only: the integral path imports no scipy.
"""
from __future__ import annotations

import numpy as np

__all__ = ['attitude_integral', 'cross_matrix', 'step_maps']

#: Intervals per block of :func:`attitude_integral` (the blocks' work arrays, about 50 floats
#: per interval, are allocated once per call and reused; the carried rotation and integral join
#: the blocks).
BLOCK_INTERVALS = 32_768
#: Steps scanned one after another in a block (``L``), each across all the block's runs.
_SCAN_STEPS = 32
#: Below this rotation angle per step [rad] the ratios of :func:`step_maps` are their series.
_SERIES_BELOW = 0.1
#: Taylor coefficients in ``q^2`` of ``sin q / q``, ``(1 - cos q) / q^2``, ``(q - sin q) / q^3``.
_SERIES = ((1.0, -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0),
           (0.5, -1.0 / 24.0, 1.0 / 720.0, -1.0 / 40320.0),
           (1.0 / 6.0, -1.0 / 120.0, 1.0 / 5040.0, -1.0 / 362880.0))
#: The 3 x 3 product ``A B`` of flat maps (3, 3, runs).
_PRODUCT = 'ikb,kjb->ijb'


def cross_matrix(v: np.ndarray) -> np.ndarray:
    """Skew matrices ``[v]x`` (..., 3, 3) of vectors ``v`` (..., 3): ``[v]x a = v x a``."""
    v = np.asarray(v, dtype=float)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def _ratios(q2: np.ndarray, out: np.ndarray) -> None:
    """Write ``sin q / q``, ``(1 - cos q) / q^2`` and ``(q - sin q) / q^3`` of the step angles'
    squares ``q2`` (...) [rad^2] into ``out`` (3, ...): their series (to ``q^6``) below
    :data:`_SERIES_BELOW`, else the closed forms (computed only where needed)."""
    for f, (c0, c1, c2, c3) in zip(out, _SERIES, strict=True):
        np.multiply(q2, c3, out=f)
        f += c2
        f *= q2
        f += c1
        f *= q2
        f += c0
    big = np.nonzero(q2 >= _SERIES_BELOW ** 2)
    if len(big[0]):
        q = np.sqrt(q2[big])
        sq = np.sin(q)
        out[(0, *big)] = sq / q
        out[(1, *big)] = 2.0 * (np.sin(0.5 * q) / q) ** 2
        out[(2, *big)] = (q - sq) / (q * q * q)


def _flat_maps(phi: np.ndarray, h: np.ndarray, E: np.ndarray, J: np.ndarray,
               work: np.ndarray) -> None:
    """:func:`step_maps` on flat arrays, entry by entry: ``E``, ``J`` (3, 3, ...) written from
    the step rotation vectors ``phi = u h`` (3, ...) [rad] and the steps ``h`` (...) [s];
    ``work`` (16, ...) is scratch.

    ``[phi]x^2 = phi phi' - q^2 1``: ``E = f2 P + f1 K + (1 - f2 q^2) 1``, ``J = h (f3 P - f2 K
    + (1 - f3 q^2) 1)`` with ``P = phi phi'``, ``K = [phi]x`` (``K[i, j] = -phi_k = -K[j, i]``
    for ``(i, j, k)`` a cyclic order)."""
    q2, f, de, dj = work[0], work[1:4], work[4], work[5]
    a, b, c, e = work[6:9], work[9:12], work[12:15], work[15]
    np.einsum('i...,i...->...', phi, phi, out=q2)
    _ratios(q2, f)
    np.multiply(f[1], q2, out=de)
    np.subtract(1.0, de, out=de)                              # 1 - f2 q^2
    np.multiply(f[1], phi, out=a)                             # f2 phi
    np.multiply(f[0], phi, out=b)                             # f1 phi
    f[1] *= h                                                 # from here f2 h, f3 h
    f[2] *= h
    np.multiply(f[2], q2, out=dj)
    np.subtract(h, dj, out=dj)                                # h (1 - f3 q^2)
    np.multiply(f[2], phi, out=c)                             # f3 h phi
    for (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(a[i], phi[j], out=E[i, j])
        np.add(E[i, j], b[k], out=E[j, i])
        E[i, j] -= b[k]
        np.multiply(f[1], phi[k], out=e)                      # f2 h phi_k
        np.multiply(c[i], phi[j], out=J[i, j])
        np.subtract(J[i, j], e, out=J[j, i])
        J[i, j] += e
    for i in range(3):
        np.multiply(a[i], phi[i], out=E[i, i])
        E[i, i] += de
        np.multiply(c[i], phi[i], out=J[i, i])
        J[i, i] += dj


def step_maps(rates: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation and the integral of the transposed rotation over steps of constant rate.

    Parameters
    ----------
    rates : ndarray, shape (n, 3)
        Body rate over each step [rad/s].
    h : ndarray, shape (n,)
        Step lengths [s] (>= 0).

    Returns
    -------
    E : ndarray, shape (n, 3, 3)
        ``exp([u h]x)``: body axes at the step's end into those at its start.
    J : ndarray, shape (n, 3, 3)
        ``int_0^h exp(-[u s]x) ds`` [s]: with ``R`` at the step's start, the step adds
        ``J R'`` to ``int R' dt``.
    """
    h = np.asarray(h, dtype=float)
    phi = np.asarray(rates, dtype=float).T * h
    E, J = np.empty((2, 3, 3, len(h)))
    _flat_maps(phi, h, E, J, np.empty((16, len(h))))
    return np.moveaxis(E, -1, 0), np.moveaxis(J, -1, 0)


def _prefix(R0: np.ndarray, E: np.ndarray) -> np.ndarray:
    """``R0 E_0 ... E_k`` for every ``k`` (3, 3, n) of flat maps ``E`` (3, 3, n) in order: one
    by one when few, else laid out as runs side by side and scanned by :func:`_scan`."""
    n = E.shape[-1]
    if n <= 2 * _SCAN_STEPS:
        P = np.empty((3, 3, n))
        r = R0
        for k in range(n):
            r = P[..., k] = r @ E[..., k]
        return P
    L = int(np.ceil(np.sqrt(n)))
    B = -(-n // L)
    flat = np.empty((3, 3, B * L))
    flat[..., :n] = E
    flat[..., n:] = np.eye(3)[..., None]                      # identity steps after the last
    runs = np.ascontiguousarray(flat.reshape(3, 3, B, L).transpose(3, 0, 1, 2))
    P = _scan(R0, runs, np.empty_like(runs), np.empty_like(runs))
    return P.transpose(1, 2, 3, 0).reshape(3, 3, B * L)[..., :n]


def _scan(R0: np.ndarray, E: np.ndarray, Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Running products of runs laid side by side: ``P[j, :, :, b] = R0 E_0 ... E_k`` for the
    step ``k = b L + j`` stored at ``E[j, :, :, b]`` (L, 3, 3, B); ``Q`` and ``P`` (same
    shape) are work and result (``P`` returned).  ``L`` products, each across all ``B`` runs,
    the runs' totals by :func:`_prefix`, then one product by what precedes each run."""
    L = E.shape[0]
    Q[0] = E[0]
    for j in range(1, L):
        np.einsum(_PRODUCT, Q[j - 1], E[j], out=Q[j])
    return np.einsum('ikb,lkjb->lijb', _preceding(R0, Q[L - 1]), Q, out=P)


def _preceding(R0: np.ndarray, T: np.ndarray) -> np.ndarray:
    """``R0 T_0 ... T_(b-1)`` (3, 3, B) for every run ``b`` of totals ``T`` (3, 3, B)."""
    S = np.empty(T.shape)
    S[..., 0] = R0
    if S.shape[-1] > 1:
        S[..., 1:] = _prefix(R0, T[..., :-1])
    return S


def _to_runs(x: np.ndarray, out: np.ndarray) -> None:
    """Lay the rows of ``x`` (m, k) out as runs: row ``b L + j`` into ``out[:, j, b]``
    (k, L, B); the rows after the last are zeros."""
    L = out.shape[1]
    full, rest = divmod(len(x), L)
    out[:, :, :full] = x[:full * L].reshape(full, L, -1).transpose(2, 1, 0)
    if rest:
        out[:, :rest, full] = x[full * L:].T
        out[:, rest:, full] = 0.0


class _Rows:
    """The rows ``m`` (m, 3, 3) of a result written run step by run step: step ``j`` of every
    run, ``X`` (3, 3, B), goes to the rows ``b L + j``."""

    def __init__(self, rows: np.ndarray, L: int) -> None:
        self.full, self.rest = divmod(len(rows), L)
        self.runs = rows[:self.full * L].reshape(self.full, L, 3, 3)
        self.tail = rows[self.full * L:]

    def put(self, j: int, X: np.ndarray) -> None:
        self.runs[:, j] = X[..., :self.full].transpose(2, 0, 1)
        if j < self.rest:
            self.tail[j] = X[..., self.full]


def _block(R0: np.ndarray, C0: np.ndarray, u: np.ndarray, h: np.ndarray, work: np.ndarray,
           C: np.ndarray, R: np.ndarray | None) -> np.ndarray:
    """One block of :func:`attitude_integral`: ``m`` intervals of rates ``u`` (m, 3) and steps
    ``h`` (m,) from the rotation ``R0`` (3, 3) and integral ``C0`` (3, 3) at their start;
    writes ``C`` and ``R`` (m, 3, 3) at the intervals' ends and returns the last rotation.

    The intervals are laid out as runs of ``L`` side by side (interval ``b L + j`` at
    ``[j, ..., b]``; padded with identity steps of zero length), in views of ``work``.  With
    ``Q_j`` a run's own running product (``Q_-1 = 1``) and ``S`` the rotation at its start,
    ``R = S Q`` and ``C = C_start + (sum_j J_j Q_(j-1)') S'``: two products per step in one
    pass over the runs, the runs' starts (:func:`_preceding`), one product per step in a
    second pass that writes the rows."""
    m = len(h)
    L = min(_SCAN_STEPS, m)
    B = -(-m // L)
    size = L * B
    E, J, Q, Y = work[:36 * size].reshape(4, L, 3, 3, B)
    phi = work[36 * size:39 * size].reshape(3, L, B)
    hr = work[39 * size:40 * size].reshape(1, L, B)
    _to_runs(u, phi)
    _to_runs(h[:, None], hr)
    phi *= hr
    _flat_maps(phi, hr[0], E.transpose(1, 2, 0, 3), J.transpose(1, 2, 0, 3),
               work[40 * size:56 * size].reshape(16, L, B))
    Q[0], Y[0] = E[0], J[0]
    for j in range(1, L):
        np.einsum('ikb,jkb->ijb', J[j], Q[j - 1], out=Y[j])
        Y[j] += Y[j - 1]
        np.einsum(_PRODUCT, Q[j - 1], E[j], out=Q[j])
    S = _preceding(R0, Q[L - 1])
    start = np.einsum('ikb,jkb->ijb', Y[L - 1], S)            # each run's total, then
    np.cumsum(start, axis=-1, out=start)                      # the integral at each start
    start[..., 1:] = start[..., :-1]
    start[..., 0] = 0.0
    start += C0[..., None]
    rows, rot = _Rows(C, L), None if R is None else _Rows(R, L)
    X = np.empty((3, 3, B))
    for j in range(L):
        np.einsum('ikb,jkb->ijb', Y[j], S, out=X)
        X += start
        rows.put(j, X)
        if rot is not None:
            rot.put(j, np.einsum(_PRODUCT, S, Q[j], out=X))
    last = divmod(m - 1, L)
    return S[..., last[0]] @ Q[last[1], ..., last[0]]


def _checked(t: np.ndarray, omega: np.ndarray, rates: np.ndarray | None,
             out: np.ndarray | None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`attitude_integral`'s inputs as float arrays, the steps and the (N, 3, 3) result
    array (zeros, or the view of ``out`` with its first row zeroed); ``ValueError`` on a
    wrong shape or a decreasing ``t``."""
    t = np.asarray(t, dtype=float)
    w = np.asarray(omega, dtype=float)
    n = len(t)
    if t.ndim != 1 or w.shape != (n, 3):
        raise ValueError(f'attitude_integral: t (N,) and omega (N, 3) expected, got {t.shape} '
                         f'and {w.shape}')
    h = np.diff(t)
    if np.any(h < 0):
        raise ValueError('attitude_integral: t must be non-decreasing')
    if rates is not None:
        rates = np.asarray(rates, dtype=float)
        if rates.shape != (max(n - 1, 0), 3):
            raise ValueError(f'attitude_integral: rates (N - 1, 3) = ({max(n - 1, 0)}, 3) '
                             f'expected, got {rates.shape}')
    if out is None:
        C = np.zeros((n, 3, 3))
    else:
        C = out.reshape(n, 3, 3) if out.shape == (n, 9) else None
        if C is None or not np.shares_memory(C, out):
            raise ValueError(f'attitude_integral: out must be (N, 9) = ({n}, 9), viewable as '
                             f'(N, 3, 3); got {out.shape}')
        C[:1] = 0.0
    return t, w, h, rates, C


def attitude_integral(t: np.ndarray, omega: np.ndarray, rates: np.ndarray | None = None, *,
                      rotations: bool = False, block: int = BLOCK_INTERVALS,
                      out: np.ndarray | None = None
                      ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """``C(t_k) = int_t0^t_k R(s)' ds`` at every gyro stamp of one gap-free run.

    ``R(s)`` turns body axes at ``s`` into those at ``t0 = t[0]`` (``R(t0) = 1``,
    ``R_dot = R [w]x``), so a torque ``d`` constant in the start's body axes acts as
    ``R(s)' d`` and its angular impulse from ``t0`` to ``t_k`` is ``C(t_k) d``.  Exact for a
    rate constant over each interval.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Gyro stamps [s], non-decreasing.
    omega : ndarray, shape (N, 3)
        Body rates [rad/s].
    rates : ndarray, shape (N - 1, 3), optional
        The rate over each interval [rad/s]; default the mean of its two samples.
    rotations : bool
        Also return the rotations ``R(t_k)``.
    block : int
        Intervals per block (the result does not depend on it beyond rounding).
    out : ndarray, shape (N, 9), optional
        Written with ``C`` row by row (``out[k, 3 r + c] = C_k[r, c]``; may be a view, e.g.
        nine columns of a wider array) and returned as its (N, 3, 3) view: no (N, 3, 3)
        temporary for a long record.

    Returns
    -------
    C : ndarray, shape (N, 3, 3)
        [s]; ``C[0] = 0``.
    R : ndarray, shape (N, 3, 3)
        Only with ``rotations``; ``R[0] = 1``.

    Raises
    ------
    ValueError
        ``omega``, ``rates`` or ``out`` of the wrong shape, or ``t`` decreasing.
    """
    t, w, h, rates, C = _checked(t, omega, rates, out)
    n = len(t)
    R = np.empty((n, 3, 3)) if rotations else None
    Rk = np.eye(3)
    if R is not None and n:
        R[0] = Rk
    step = max(int(block), 1)
    # the blocks' work arrays, once: 56 floats per interval of a block (L B < m + L)
    work = np.empty(56 * (min(step, max(n - 1, 0)) + _SCAN_STEPS))
    for a in range(0, n - 1, step):
        b = min(a + step, n - 1)                              # intervals a .. b-1
        u = rates[a:b] if rates is not None else 0.5 * (w[a:b] + w[a + 1:b + 1])
        Rk = _block(Rk, C[a], u, h[a:b], work, C[a + 1:b + 1],
                    None if R is None else R[a + 1:b + 1])
    return (C, R) if R is not None else C
