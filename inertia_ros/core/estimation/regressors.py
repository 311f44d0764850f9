"""Regressor building blocks for Euler's equations, shared by every estimator.

Euler's equation about the centre of mass in body axes, ``tau = I w_dot + w x (I w)``, is
linear in ``theta = [ixx, iyy, izz, ixy, ixz, iyz]``:

* ``I v = momentum_matrix(v) @ theta`` for any vector ``v`` (3x6 per sample);
* ``w x (I w) = gyroscopic_matrix(m) @ theta`` where ``m`` holds the six quadratic monomials
  ``[wx^2, wy^2, wz^2, wx wy, wx wz, wy wz]`` of ``w`` (3x6, linear in ``m``).

So the integral (momentum) form over ``[a, b]``,
``I (w_b - w_a) + int_a^b w x (I w) dt = int_a^b tau dt``, only needs ``w`` at the window ends,
the cumulative integral of the monomials and the cumulative integral of the torque: with
cumulative sums every window of every length costs O(1) after O(N) preprocessing.
The differential form uses the same two matrices with ``w_dot`` and the monomials themselves.

Every equation block of the batch and recursive estimators, ``A_b = [X6 | Xd | y]`` (3 x 10),
is a fixed linear map (:data:`VARIABLE_MAP`) of 13 per-sample variables
``v_b = [w (3), m (6), s (1), y (3)]`` (:func:`variables`), so every statistic of the
equations is a quadratic form in ``v``: the data are reduced to 13 x 13 Gram matrices
(:func:`gram`) and lifted to the blocks' cross Grams (:func:`lift`).

A torque ``d`` constant in inertial axes (body axes at the start of a gyro run,
:mod:`.attitude`) adds nine variables, the entries of ``C = int R' dt``, after the 13:
``v_b = [w, m, s, y, c (9)]`` (22), blocks ``[X6 | Xd | y | Xi]`` (3 x 13) with ``Xi = -C``
(:data:`VARIABLE_MAP_WIDE`).  The torque integral stays block column 9, so the 13-variable
map and its Grams are exact sub-blocks of the wide ones; :func:`blocks` and :func:`lift`
take either width.
"""
from __future__ import annotations

import numpy as np

from ..tensor import THETA_COLS, THETA_ROWS, theta_to_matrix
from .options import GAP_FACTOR

__all__ = [
    'GYROSCOPIC_MAP',
    'MOMENTUM_BASIS',
    'MOMENTUM_MAP',
    'MONOMIAL_I',
    'MONOMIAL_J',
    'N_REGRESSOR_VARIABLES',
    'N_VARIABLES_WIDE',
    'REGRESSOR_COLUMNS_WIDE',
    'VARIABLE_MAP',
    'VARIABLE_MAP_WIDE',
    'blocks',
    'cumtrapz',
    'cumulative_monomials',
    'cumulative_torque',
    'gram',
    'gyroscopic_matrix',
    'lift',
    'metric',
    'momentum_matrix',
    'monomials',
    'variables',
]

# E[k] = d I / d theta_k, shape (6, 3, 3).
_E = theta_to_matrix(np.eye(6))
#: Index pairs ``(i, j)`` of the monomials ``w_i w_j``: the tensor's element order.
MONOMIAL_I = THETA_ROWS
MONOMIAL_J = THETA_COLS


def _gyro_coefficients() -> np.ndarray:
    """Coefficients ``A[r, k, m]`` with ``(w x (E_k w))_r = sum_m A[r, k, m] mono_m(w)``."""
    def f(w: np.ndarray) -> np.ndarray:            # (3, 6): columns w x (E_k w)
        return np.cross(w, (_E @ w)).T

    eye = np.eye(3)
    A = np.zeros((3, 6, 6))
    for m, (i, j) in enumerate(zip(MONOMIAL_I, MONOMIAL_J, strict=True)):
        if i == j:
            A[:, :, m] = f(eye[i])
        else:
            A[:, :, m] = f(eye[i] + eye[j]) - f(eye[i]) - f(eye[j])
    return A


_A = _gyro_coefficients()
#: ``L(v) = (v @ MOMENTUM_MAP).reshape(3, 6)``: shape (3, 18), entry ``(c, r*6 + k)``.
MOMENTUM_MAP = np.ascontiguousarray(_E.transpose(2, 1, 0).reshape(3, 18))
#: ``Q(m) = (m @ GYROSCOPIC_MAP).reshape(3, 6)``: shape (6, 18), entry ``(m, r*6 + k)``.
GYROSCOPIC_MAP = np.ascontiguousarray(_A.transpose(2, 0, 1).reshape(6, 18))


def momentum_matrix(v: np.ndarray) -> np.ndarray:
    """Matrices ``L(v)`` with ``I v = L(v) @ theta``.

    Parameters
    ----------
    v : ndarray, shape (..., 3)
        Vectors (e.g. angular velocity [rad/s] or its increment).

    Returns
    -------
    ndarray, shape (..., 3, 6)
        Linear in ``v``; ``L(v) @ theta`` has the units of ``theta`` times ``v``.
    """
    # L[..., r, k] = sum_c E[k, r, c] v_c, as one matrix product
    v = np.asarray(v, dtype=float)
    return (v @ MOMENTUM_MAP).reshape(v.shape[:-1] + (3, 6))


def monomials(omega: np.ndarray) -> np.ndarray:
    """The six quadratic monomials ``[wx^2, wy^2, wz^2, wx wy, wx wz, wy wz]``.

    Parameters
    ----------
    omega : ndarray, shape (..., 3)
        Angular velocity [rad/s].

    Returns
    -------
    ndarray, shape (..., 6)
        [rad^2/s^2].
    """
    omega = np.asarray(omega, dtype=float)
    out = np.empty(omega.shape[:-1] + (6,))
    for k, (i, j) in enumerate(zip(MONOMIAL_I, MONOMIAL_J, strict=True)):   # no fancy-index copies
        np.multiply(omega[..., i], omega[..., j], out=out[..., k])
    return out


def gyroscopic_matrix(m: np.ndarray) -> np.ndarray:
    """Matrices ``Q(m)`` with ``w x (I w) = Q(monomials(w)) @ theta`` (linear in ``m``).

    Also valid for integrated monomials: ``int w x (I w) dt = Q(int m dt) @ theta``.

    Parameters
    ----------
    m : ndarray, shape (..., 6)
        Monomials or their integrals (``xx, yy, zz, xy, xz, yz`` order).

    Returns
    -------
    ndarray, shape (..., 3, 6)
    """
    m = np.asarray(m, dtype=float)
    return (m @ GYROSCOPIC_MAP).reshape(m.shape[:-1] + (3, 6))


#: Rows per block of :func:`cumulative_monomials` and :func:`cumulative_torque`: a block's
#: temporaries (a few (rows, 6) arrays) stay in the processor's cache, so an hour-long record
#: (720k rows) is read and written about twice instead of a dozen times.  The results do not
#: depend on it (the running sums carry over from block to block in the same order).
BLOCK_ROWS = 8192


def cumulative_monomials(t: np.ndarray, omega: np.ndarray,
                         noise_var: np.ndarray | None = None,
                         end_correction: bool = True, *, rows: slice | None = None,
                         out: np.ndarray | None = None) -> np.ndarray:
    """Cumulative integral of the quadratic monomials from ``t[0]`` to each ``t[i]``.

    Trapezoid rule with the Euler-Maclaurin end correction ``-h^2/12 f'`` (fourth-order for
    smooth signals on a uniform grid; the constant part of the correction is irrelevant to the
    estimators, which remove a constant per segment).  When ``noise_var`` is given, the
    expected contribution of white gyro noise to the squares, ``sigma_c^2 (t - t0)``, is
    subtracted so that the integrals are unbiased.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Strictly increasing sample times [s].
    omega : ndarray, shape (N, 3)
        Angular velocity [rad/s].
    noise_var : ndarray, shape (3,), optional
        Gyro white-noise variance per axis [rad^2/s^2].
    end_correction : bool
        Apply the ``-h^2/12 f'`` correction.
    rows : slice, optional
        Only the rows ``rows.start:rows.stop`` (step 1) of the result are returned (still
        integrated from ``t[0]``); default all.
    out : ndarray, shape (rows, 6), optional
        Written in place and returned (may be a strided view, e.g. columns of a wider array).

    Returns
    -------
    ndarray, shape (N, 6) (or the rows asked for)
        ``int_{t0}^{t_i} m(w) dt`` [rad^2/s].
    """
    t = np.asarray(t, dtype=float)
    omega = np.asarray(omega, dtype=float)
    n = len(t)
    r0, r1 = (0, n) if rows is None else (int(rows.start or 0), int(n if rows.stop is None
                                                                     else rows.stop))
    if rows is not None and (rows.step not in (None, 1) or not 0 <= r0 <= r1 <= n):
        raise ValueError(f'rows: expected a slice of step 1 inside [0, {n}], got {rows!r}')
    if out is None:
        out = np.empty((r1 - r0, 6))
    if r1 == r0:
        return out
    correct = end_correction and n > 2
    shift = np.zeros(6)            # the constant removed so that the first row is 0
    if correct:
        ends = _end_derivatives(t, omega)
        shift = 0.0 - ends[0] * ((t[1] - t[0]) * (t[1] - t[0]) / 12.0)
    nv = None if noise_var is None else np.asarray(noise_var, dtype=float)
    carry = np.zeros(6)
    for a in range(0, r1, BLOCK_ROWS):
        b = min(a + BLOCK_ROWS, r1)
        lo, hi = max(a - 1, 0), min(b + 1, n)          # one row of context on either side
        p = monomials(omega[lo:hi])
        blk = np.empty((b - a, 6))
        k = a - lo                                     # row a within p
        if a == 0:
            blk[0] = 0.0
            if b > 1:
                inc = p[1:b] + p[:b - 1]
                inc *= (0.5 * (t[1:b] - t[:b - 1]))[:, None]
                np.cumsum(inc, axis=0, out=blk[1:])
        else:
            inc = p[k:k + b - a] + p[k - 1:k - 1 + b - a]
            inc *= (0.5 * (t[a:b] - t[a - 1:b - 1]))[:, None]
            inc[0] += carry
            np.cumsum(inc, axis=0, out=blk)
        carry = blk[-1].copy()
        if correct:
            blk -= _scaled_derivative(t, p, lo, a, b, ends)
            blk -= shift
        if nv is not None:
            span = t[a:b] - t[0]
            for c, v in enumerate(nv):                 # no (N, 3) temporary
                blk[:, c] -= span * v
        if b > r0:
            s0 = max(a, r0)
            out[s0 - r0:b - r0] = blk[s0 - a:]
    return out


def _end_derivatives(t: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``f'`` of the monomials at the first and the last sample (n > 2, before the ``h^2/12``
    scale): linear extrapolation of the two neighbouring central differences (with n = 3, the
    one central difference)."""
    n = len(t)
    tail = max(n - 4, 0)
    ph, pt = monomials(omega[:4]), monomials(omega[tail:])

    def central(p: np.ndarray, i: int, lo: int) -> np.ndarray:
        return (p[i + 1 - lo] - p[i - 1 - lo]) / (t[i + 1] - t[i - 1])

    if n == 3:
        only = central(ph, 1, 0)
        return only, only
    return (2.0 * central(ph, 1, 0) - central(ph, 2, 0),
            2.0 * central(pt, n - 2, tail) - central(pt, n - 3, tail))


def _scaled_derivative(t: np.ndarray, p: np.ndarray, lo: int, a: int, b: int,
                       ends: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """``h_i^2/12 f'(t_i)`` for the rows ``a:b`` (``p``: monomials of rows ``lo:...``).

    ``f'`` by central differences, at the record's ends ``ends`` (:func:`_end_derivatives`);
    ``h_i = t_i - t_(i-1)`` (``h_0 = t_1 - t_0``).
    """
    n = len(t)
    d = np.empty((b - a, 6))
    i0, i1 = max(a, 1), min(b, n - 1)                  # interior rows of the block
    if i1 > i0:
        np.subtract(p[i0 + 1 - lo:i1 + 1 - lo], p[i0 - 1 - lo:i1 - 1 - lo],
                    out=d[i0 - a:i1 - a])
        d[i0 - a:i1 - a] /= (t[i0 + 1:i1 + 1] - t[i0 - 1:i1 - 1])[:, None]
    if a == 0:
        d[0] = ends[0]
    if b == n:
        d[-1] = ends[1]
    h = np.empty(b - a)
    h[:] = t[a:b] - t[a - 1:b - 1] if a > 0 else np.r_[t[1] - t[0], t[1:b] - t[:b - 1]]
    # the first sample after a gap (a step over GAP_FACTOR times the next one): its step is
    # the next one, as for the samples after it; the gap's step would make its correction
    # h^2/12 f' a lone outlier of its anchored segment (issue 26: 0.75 f' after a 3 s gap)
    m = min(b, n - 1) - a
    if m > 0:
        h_next = t[a + 1:a + 1 + m] - t[a:a + m]
        h[:m] = np.where(h[:m] > GAP_FACTOR * h_next, h_next, h[:m])
    d *= (h * h / 12.0)[:, None]
    return d


def _interval_index(t_tau: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Index of the last torque sample at or before each query time (0 before the first).

    Sorted queries (the common case) take one search per torque sample and a repeat instead
    of one search per query.
    """
    m = len(t_tau)
    if len(t) > m and np.all(t[1:] >= t[:-1]):
        first = np.searchsorted(t, t_tau, side='left')
        first[0] = 0
        return np.repeat(np.arange(m), np.diff(np.append(first, len(t))))
    return np.clip(np.searchsorted(t_tau, t, side='right') - 1, 0, m - 1)


def cumtrapz(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Cumulative trapezoid of ``f`` (..., n, ...) over the stamps ``t`` (..., n) [s] along
    ``t``'s last axis (one run, or pieces of runs of one length), 0 at the first stamp."""
    k = t.ndim - 1
    dt = np.diff(t, axis=-1).reshape(t.shape[:-1] + (-1,) + (1,) * (f.ndim - t.ndim))
    lo = (slice(None),) * k
    out = np.empty_like(f)
    out[lo + (0,)] = 0.0
    inc = f[lo + (slice(1, None),)] + f[lo + (slice(None, -1),)]
    inc *= 0.5
    inc *= dt
    np.cumsum(inc, axis=k, out=out[lo + (slice(1, None),)])
    return out


def cumulative_torque(t_tau: np.ndarray, tau: np.ndarray, t: np.ndarray,
                      hold: str = 'zoh', *, out: np.ndarray | None = None) -> np.ndarray:
    """Exact integral of the sampled torque from ``t_tau[0]`` to each query time.

    Parameters
    ----------
    t_tau : ndarray, shape (M,)
        Strictly increasing torque sample times [s].
    tau : ndarray, shape (M, 3)
        Torque samples [N m].
    t : ndarray, shape (K,)
        Query times [s], each ``>= t_tau[0]``.  Under ``zoh`` a time after the last sample
        holds the last value; under ``linear`` it extrapolates the last value flat as well.
    hold : {'zoh', 'linear'}
        Sampling assumption between samples: zero-order hold of each sample until the next
        (torque commands), or linear interpolation.
    out : ndarray, shape (K, 3), optional
        Written in place and returned (may be a strided view).

    Returns
    -------
    ndarray, shape (K, 3)
        ``int_{t_tau[0]}^{t_k} tau dt`` [N m s].
    """
    dts = np.diff(t_tau)
    cum = np.zeros_like(tau)
    slope = None
    if hold == 'zoh':
        if len(dts):
            np.cumsum(tau[:-1] * dts[:, None], axis=0, out=cum[1:])
    elif hold != 'linear':
        raise ValueError(f"hold: must be 'zoh' or 'linear', got {hold!r}")
    else:
        cum = cumtrapz(t_tau, tau) if len(dts) else cum
        slope = np.zeros_like(tau)
        if len(dts):
            slope[:-1] = (tau[1:] - tau[:-1]) / dts[:, None]
    j_all = _interval_index(t_tau, t)
    if out is None:
        out = np.empty((len(t), 3))
    for a in range(0, len(t), BLOCK_ROWS):           # cache-sized blocks, as above
        b = min(a + BLOCK_ROWS, len(t))
        j = j_all[a:b]
        # np.take: half the time of fancy indexing on these row gathers
        if slope is None:
            blk = np.take(tau, j, axis=0)
            blk *= (t[a:b] - t_tau.take(j))[:, None]
            blk += np.take(cum, j, axis=0)
        else:                     # (the last slope row is 0: flat after the last sample)
            u = (t[a:b] - t_tau.take(j))[:, None]
            blk = np.take(tau, j, axis=0) * u + np.take(cum, j, axis=0)
            blk += 0.5 * np.take(slope, j, axis=0) * u * u
        out[a:b] = blk
    return out


# ---------------------------------------------------------------------------------------------
# the 13 per-sample variables and their Gram matrices
# ---------------------------------------------------------------------------------------------
#: Regressor variables ``[w, m, s]`` among the 13 (the torque integral ``y`` is the rest).
N_REGRESSOR_VARIABLES = 10


def _variable_map() -> np.ndarray:
    """``E`` (13, 3, 10): equation block ``A_b = [X6 | Xd | y]`` from 13 per-sample variables.

    ``v_b = [w (3), m (6), s (1), y (3)]``: ``X6 = L(w) + Q(m)``, ``Xd = -s * 1``, ``y``.
    """
    E = np.zeros((13, 3, 10))
    E[:3, :, :6] = momentum_matrix(np.eye(3))
    E[3:9, :, :6] = gyroscopic_matrix(np.eye(6))
    for r in range(3):
        E[9, r, 6 + r] = -1.0
        E[10 + r, r, 9] = 1.0
    return E


#: ``A_b[r, q] = sum_i v_b[i] VARIABLE_MAP[i, r, q]``, shape (13, 3, 10).
VARIABLE_MAP = _variable_map()
_VMAP2 = np.ascontiguousarray(VARIABLE_MAP.reshape(13, 30))
#: ``L(e_c)`` for the three axes, shape (3, 3, 6): the gyro-noise bias of ``L(w)' L(w)``.
MOMENTUM_BASIS = momentum_matrix(np.eye(3))

#: Variables with a torque fixed in inertial axes: the 13, then ``c[3 r + k] = C[r, k]``.
N_VARIABLES_WIDE = 22
#: The regressor variables of the wide layout: all but the torque integral ``y`` (10:13).
REGRESSOR_COLUMNS_WIDE = np.r_[0:10, 13:22]


def _variable_map_wide() -> np.ndarray:
    """``E`` (22, 3, 13): blocks ``[X6 | Xd | y | Xi]`` from ``[w, m, s, y, c]``.

    The first 13 variables map as :data:`VARIABLE_MAP` onto the first 10 columns; the
    inertial torque's columns are ``Xi[r, k] = -C[r, k]`` (the disturbance's angular impulse
    ``C d`` moved to the left-hand side, as ``Xd = -s`` for the body-axis bias).
    """
    E = np.zeros((N_VARIABLES_WIDE, 3, 13))
    E[:13, :, :10] = VARIABLE_MAP
    for r in range(3):
        for k in range(3):
            E[13 + 3 * r + k, r, 10 + k] = -1.0
    return E


#: ``A_b[r, q] = sum_i v_b[i] VARIABLE_MAP_WIDE[i, r, q]``, shape (22, 3, 13).
VARIABLE_MAP_WIDE = _variable_map_wide()
_VMAP2_WIDE = np.ascontiguousarray(VARIABLE_MAP_WIDE.reshape(N_VARIABLES_WIDE, 39))


def _map_of(n_var: int) -> tuple[np.ndarray, int]:
    """The flat map (n_var, 3 q) and block width ``q`` of 13 or 22 variables."""
    if n_var == 13:
        return _VMAP2, 10
    if n_var == N_VARIABLES_WIDE:
        return _VMAP2_WIDE, 13
    raise ValueError(f'expected 13 or {N_VARIABLES_WIDE} variables per sample, got {n_var}')


def variables(w: np.ndarray, m: np.ndarray, s: np.ndarray, y: np.ndarray,
              c: np.ndarray | None = None) -> np.ndarray:
    """Stack the 13 per-sample variables ``[w, m, s, y]`` (22 with ``c``).

    Parameters
    ----------
    w : ndarray, shape (n, 3)
        Angular velocity (or its increment / derivative) [rad/s].
    m : ndarray, shape (n, 6)
        Monomials or their integrals.
    s : ndarray, shape (n,)
        Coefficient of the torque bias (time since the anchor [s], or 1).
    y : ndarray, shape (n, 3)
        Torque (or its integral).
    c : ndarray, shape (n, 3, 3), optional
        Coefficient of a torque fixed in inertial axes: ``int R' dt`` [s]
        (:func:`.attitude.attitude_integral`), or ``R'`` in a differential form.

    Returns
    -------
    ndarray, shape (n, 13) or (n, 22)
    """
    parts = [w, m, s[:, None], y] + ([] if c is None else [c.reshape(len(c), 9)])
    return np.concatenate(parts, axis=1)


def blocks(V: np.ndarray) -> np.ndarray:
    """Equation blocks ``A`` (n, 3, 10) of the variables ``V`` (n, 13), or (n, 3, 13) of
    the wide ``V`` (n, 22)."""
    E, q = _map_of(V.shape[1])
    return (V @ E).reshape(-1, 3, q)


def gram(V: np.ndarray) -> np.ndarray:
    """``V' V`` by BLAS.

    Measured on this project's 2-core machine under load, single- or multi-threaded BLAS is
    5x faster than numpy's ``einsum`` loop from 12 000 rows (0.18 against 0.93 ms) to
    720 000 (11 against 56 ms).
    """
    return V.T @ V


def lift(G13: np.ndarray) -> np.ndarray:
    """Cross Grams (3, 3, 10, 10) of the equation blocks from a 13 x 13 Gram of ``V``
    ((3, 3, 13, 13) from a 22 x 22 Gram of the wide ``V``).

    ``C[r, s, q, p] = sum_ij VARIABLE_MAP[i, r, q] G13[i, j] VARIABLE_MAP[j, s, p]``, as two
    small matrix products (a tenth of the time of the three-operand ``einsum``; the recursive
    estimator runs it twice per ``estimate()``).
    """
    E, q = _map_of(G13.shape[0])
    C = E.T @ G13 @ E                                 # (3q, 3q): [r q] x [s p]
    return np.ascontiguousarray(C.reshape(3, q, 3, q).transpose(0, 2, 1, 3))


def metric(C: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``sum_b A_b' M A_b`` (q, q) from the cross Grams ``C`` (3, 3, q, q) and ``M`` (3, 3)."""
    return np.einsum('rs,rsij->ij', M, C)
