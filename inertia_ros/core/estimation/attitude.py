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
the step rotations is a scan: evaluated in blocks of rows, each block as a two-level product
(vectorised across sub-blocks, then their totals), so an hour of 200 Hz gyro costs a few
hundred vectorised steps instead of 720 000 Python-level ones, and each rotation is a product
of at most a few hundred factors (rounding ~1e-13, no re-orthonormalisation needed).

numpy only: the integral path imports no scipy.
"""
from __future__ import annotations

import numpy as np

__all__ = ['attitude_integral', 'cross_matrix', 'step_maps']

#: Intervals per block of :func:`attitude_integral` (the temporaries of a block, a few
#: (rows, 3, 3) arrays, stay small; the carried rotation and integral join the blocks).
BLOCK_INTERVALS = 65_536
#: Below this rotation angle per step [rad] the ratios of :func:`step_maps` are their series.
_SERIES_BELOW = 0.1


def cross_matrix(v: np.ndarray) -> np.ndarray:
    """Skew matrices ``[v]x`` (..., 3, 3) of vectors ``v`` (..., 3): ``[v]x a = v x a``."""
    v = np.asarray(v, dtype=float)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


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
    phi = np.asarray(rates, dtype=float) * h[:, None]
    q2 = np.einsum('ij,ij->i', phi, phi)
    small = q2 < _SERIES_BELOW ** 2
    q = np.sqrt(np.where(small, 1.0, q2))                     # (1 where the series is used)
    c = q2 / 6.0
    f1 = np.where(small, 1.0 - c * (1.0 - q2 / 20.0 * (1.0 - q2 / 42.0)),
                  np.sin(q) / q)                              # sin q / q
    f2 = np.where(small, 0.5 * (1.0 - q2 / 12.0 * (1.0 - q2 / 30.0 * (1.0 - q2 / 56.0))),
                  2.0 * (np.sin(0.5 * q) / q) ** 2)           # (1 - cos q) / q^2
    f3 = np.where(small, (1.0 - q2 / 20.0 * (1.0 - q2 / 42.0 * (1.0 - q2 / 72.0))) / 6.0,
                  (q - np.sin(q)) / (q * q * q))              # (q - sin q) / q^3
    # [phi]x^2 = phi phi' - q^2 1: no stacked matrix products
    P = phi[:, :, None] * phi[:, None, :]
    K = cross_matrix(phi)
    E = f2[:, None, None] * P
    E += f1[:, None, None] * K
    J = f3[:, None, None] * P
    J -= f2[:, None, None] * K
    i = np.arange(3)
    E[:, i, i] += (1.0 - f2 * q2)[:, None]
    J[:, i, i] += (1.0 - f3 * q2)[:, None]
    J *= h[:, None, None]
    return E, J


def _running_product(R0: np.ndarray, E: np.ndarray) -> np.ndarray:
    """``R0 E_0 ... E_k`` for every ``k`` (n, 3, 3): a two-level scan (sub-blocks of about
    ``sqrt(n)`` steps at once, then the sub-blocks' totals in order)."""
    n = len(E)
    L = max(1, int(np.ceil(np.sqrt(n))))
    B = -(-n // L)
    Eb = np.empty((B * L, 3, 3))
    Eb[:n] = E
    Eb[n:] = np.eye(3)
    Eb = Eb.reshape(B, L, 3, 3)
    Q = np.empty_like(Eb)                                     # prefix products in each
    Q[:, 0] = Eb[:, 0]
    for j in range(1, L):
        np.matmul(Q[:, j - 1], Eb[:, j], out=Q[:, j])
    S = np.empty((B, 3, 3))                                   # what precedes each sub-block
    S[0] = R0
    for b in range(1, B):
        S[b] = S[b - 1] @ Q[b - 1, -1]
    return (S[:, None] @ Q).reshape(B * L, 3, 3)[:n]


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
    for a in range(0, n - 1, step):
        b = min(a + step, n - 1)                              # intervals a .. b-1
        u = rates[a:b] if rates is not None else 0.5 * (w[a:b] + w[a + 1:b + 1])
        E, J = step_maps(u, h[a:b])
        Rs = np.empty((b - a, 3, 3))                          # rotations at the intervals' starts
        Rs[0] = Rk
        if b - a > 1:
            Rs[1:] = _running_product(Rk, E[:-1])
        inc = J @ Rs.transpose(0, 2, 1)
        np.cumsum(inc, axis=0, out=C[a + 1:b + 1])
        C[a + 1:b + 1] += C[a]
        Rk = Rs[-1] @ E[-1]
        if R is not None:
            R[a + 1:b] = Rs[1:]
            R[b] = Rk
    return (C, R) if R is not None else C
