"""Rigid-body inertia tensors: conversions, principal axes, physical validity, Euler's equations.

Conventions (DESIGN.md, contract): SI units (kg m^2, rad/s, rad/s^2, N m); the tensor elements
are the matrix entries, as in geometry_msgs/Inertia and URDF::

    I = [[ixx, ixy, ixz],
         [ixy, iyy, iyz],
         [ixz, iyz, izz]]

(``ixy`` is the matrix element, not a negated product of inertia) and the parameter order is
``theta = [ixx, iyy, izz, ixy, ixz, iyz]`` (:data:`THETA_NAMES`).  Principal moments are
ascending (I1 <= I2 <= I3); principal axes are the columns of a proper rotation matrix, the
first two each with its largest-magnitude component positive, the third their cross product.

Everything here is pure numpy/scipy and vectorised over leading dimensions where the docstring
says so.  This module holds the array functions, the :class:`InertiaTensor` value type and the
dynamics helpers; the textbook primitives (point mass, rod, lamina, ... cone) and composite
bodies are in :mod:`inertia_ros.core.bodies`.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    'THETA_NAMES',
    'PhysicalCheck',
    'as_inertia_matrix',
    'check_physical',
    'euler_omega_dot',
    'euler_torque',
    'matrix_to_theta',
    'nearest_physical',
    'principal_axes',
    'theta_to_matrix',
]

#: Names of the six unique tensor elements, in the parameter order of ``theta`` (contract).
THETA_NAMES: tuple[str, ...] = ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')

# (row, column) of each theta element in the 3x3 matrix, in THETA_NAMES order.
_THETA_ROWS = np.array([0, 1, 2, 0, 0, 1])
_THETA_COLS = np.array([0, 1, 2, 1, 2, 2])
# theta index of each matrix element (row-major), for theta_to_matrix.
_MATRIX_INDEX = np.array([[0, 3, 4],
                          [3, 1, 5],
                          [4, 5, 2]])

#: Default relative tolerance for "symmetric within tolerance" (relative to max |I_ij|).
SYMMETRY_RTOL = 1e-9
#: Relative spread (to the largest |moment|) below which principal moments count as repeated.
DEGENERACY_RTOL = 1e-12


# ---------------------------------------------------------------------------------------------
# validation helpers (shared with bodies.py)
# ---------------------------------------------------------------------------------------------
def _as_float_array(x: Any, name: str) -> np.ndarray:
    """Convert ``x`` to a float64 array, raising ValueError naming ``name`` on failure."""
    try:
        arr = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name}: expected an array of real numbers, got {type(x).__name__} '
                         f'({exc})') from None
    return arr


def _check_finite(arr: np.ndarray, name: str) -> None:
    """Raise ValueError naming ``name`` if ``arr`` holds NaN or infinity."""
    if not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f'{name}: must be finite, found {bad} NaN/inf value(s)')


def _as_vectors(x: Any, name: str, *, check_finite: bool = True) -> np.ndarray:
    """A float array of shape (..., 3), validated; ValueError names ``name``."""
    arr = _as_float_array(x, name)
    if arr.ndim < 1 or arr.shape[-1] != 3:
        raise ValueError(f'{name}: expected shape (..., 3), got {arr.shape}')
    if check_finite:
        _check_finite(arr, name)
    return arr


def _as_vector3(x: Any, name: str) -> np.ndarray:
    """A finite float array of shape exactly (3,); ValueError names ``name``."""
    arr = _as_float_array(x, name)
    if arr.shape != (3,):
        raise ValueError(f'{name}: expected shape (3,), got {arr.shape}')
    _check_finite(arr, name)
    return arr


def _max_asymmetry(m: np.ndarray) -> float:
    """Largest |M_ij - M_ji| of a (..., 3, 3) array (0 for an empty stack)."""
    if m.size == 0:
        return 0.0
    return float(np.max(np.abs(m - np.swapaxes(m, -1, -2))))


def _check_symmetric(m: np.ndarray, name: str, rtol: float) -> None:
    """Raise ValueError if a (..., 3, 3) array is not symmetric within ``rtol`` of max |M_ij|."""
    if m.size == 0:
        return
    asym = _max_asymmetry(m)
    scale = float(np.max(np.abs(m)))
    if asym > rtol * scale:
        raise ValueError(f'{name}: not symmetric: max |I_ij - I_ji| = {asym:.3g} exceeds '
                         f'rtol * max|I_ij| = {rtol:.1g} * {scale:.3g}')


def as_inertia_matrix(I: Any, name: str = 'I', *, rtol: float = SYMMETRY_RTOL,
                      check_finite: bool = True, stacked: bool = False) -> np.ndarray:
    """Validate and return a symmetric 3x3 inertia matrix (or a stack of them).

    Accepts a (3, 3) array-like, or anything with a ``matrix`` attribute (such as
    :class:`~inertia_ros.core.bodies.InertiaTensor`).

    Parameters
    ----------
    I : array_like, shape (3, 3) (or (..., 3, 3) when ``stacked``), or InertiaTensor
        Inertia matrix [kg m^2].
    name : str
        Argument name used in error messages.
    rtol : float
        Symmetry tolerance relative to max |I_ij|.
    check_finite : bool
        Reject NaN and infinity.
    stacked : bool
        Allow leading dimensions (..., 3, 3).

    Returns
    -------
    ndarray, shape (3, 3) or (..., 3, 3)
        The symmetric part (I + I^T) / 2, float64 [kg m^2].

    Raises
    ------
    ValueError
        Wrong shape, non-finite elements, or asymmetry beyond ``rtol``.
    """
    if hasattr(I, 'matrix') and not isinstance(I, np.ndarray):
        I = I.matrix
    arr = _as_float_array(I, name)
    if stacked:
        if arr.ndim < 2 or arr.shape[-2:] != (3, 3):
            raise ValueError(f'{name}: expected shape (..., 3, 3), got {arr.shape}')
    elif arr.shape != (3, 3):
        raise ValueError(f'{name}: expected shape (3, 3), got {arr.shape}')
    if check_finite:
        _check_finite(arr, name)
    _check_symmetric(arr, name, rtol)
    return 0.5 * (arr + np.swapaxes(arr, -1, -2))


# ---------------------------------------------------------------------------------------------
# theta <-> matrix
# ---------------------------------------------------------------------------------------------
def theta_to_matrix(theta: Any, *, check_finite: bool = True) -> np.ndarray:
    """Build inertia matrices from the six unique elements.

    Parameters
    ----------
    theta : array_like, shape (..., 6)
        ``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2]; ``ixy`` etc. are matrix elements.
    check_finite : bool
        Reject NaN/inf (pass False to let NaN propagate, e.g. for unidentified elements).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Symmetric matrices [kg m^2].

    Raises
    ------
    ValueError
        ``theta`` does not end in a dimension of 6, or holds NaN/inf when ``check_finite``.
    """
    arr = _as_float_array(theta, 'theta')
    if arr.ndim < 1 or arr.shape[-1] != 6:
        raise ValueError(f'theta: expected shape (..., 6), got {arr.shape}')
    if check_finite:
        _check_finite(arr, 'theta')
    return arr[..., _MATRIX_INDEX]


def matrix_to_theta(I: Any, *, rtol: float = SYMMETRY_RTOL,
                    check_finite: bool = True) -> np.ndarray:
    """Extract the six unique elements from symmetric inertia matrices.

    Parameters
    ----------
    I : array_like, shape (..., 3, 3), or InertiaTensor
        Inertia matrices [kg m^2], symmetric within ``rtol`` (relative to max |I_ij|).
    rtol : float
        Symmetry tolerance; the symmetric part is used.
    check_finite : bool
        Reject NaN/inf.

    Returns
    -------
    ndarray, shape (..., 6)
        ``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2].

    Raises
    ------
    ValueError
        Wrong shape, NaN/inf (when ``check_finite``), or asymmetry beyond ``rtol``.
    """
    sym = as_inertia_matrix(I, 'I', rtol=rtol, check_finite=check_finite, stacked=True)
    return sym[..., _THETA_ROWS, _THETA_COLS]


# ---------------------------------------------------------------------------------------------
# principal axes
# ---------------------------------------------------------------------------------------------
def _fix_sign(v: np.ndarray) -> np.ndarray:
    """Flip ``v`` so that its largest-magnitude component (first on ties) is positive."""
    k = int(np.argmax(np.abs(v)))
    return -v if v[k] < 0 else v


def _plane_basis_vector(normal: np.ndarray) -> np.ndarray:
    """A deterministic unit vector perpendicular to unit ``normal``.

    The projection onto the plane of the coordinate axis with the largest projection (first
    on ties), normalised and sign-fixed.
    """
    proj = np.eye(3) - np.outer(normal, normal)        # rows: e_k projected onto the plane
    norms = np.linalg.norm(proj, axis=1)
    k = int(np.argmax(norms))
    return _fix_sign(proj[k] / norms[k])


def principal_axes(I: Any, *, rtol: float = SYMMETRY_RTOL) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and axes with the DESIGN.md ordering and sign convention.

    Moments are ascending.  Axes are the columns of a proper rotation ``R`` (det +1) with
    ``I = R @ diag(moments) @ R.T``; the first two columns each have their largest-magnitude
    component positive (first such index on ties) and the third is their cross product.

    Repeated moments (within ``DEGENERACY_RTOL`` of the largest |moment|) get a deterministic
    basis of their eigenspace: a fully spherical tensor gives the identity; an axisymmetric
    one gives the unique axis plus, in the degenerate plane, the projection of the coordinate
    axis closest to that plane (e.g. ``diag(a, a, c)`` gives the identity).  Never NaN.

    Parameters
    ----------
    I : array_like, shape (3, 3), or InertiaTensor
        Symmetric inertia matrix [kg m^2] (symmetric within ``rtol``).
    rtol : float
        Symmetry tolerance relative to max |I_ij|.

    Returns
    -------
    moments : ndarray, shape (3,)
        Principal moments, ascending [kg m^2].
    axes : ndarray, shape (3, 3)
        Principal axes as columns (a proper rotation matrix, dimensionless).

    Raises
    ------
    ValueError
        Wrong shape, NaN/inf, or asymmetric input.
    """
    sym = as_inertia_matrix(I, 'I', rtol=rtol)
    moments, vecs = np.linalg.eigh(sym)
    scale = float(np.max(np.abs(moments)))
    tol = DEGENERACY_RTOL * scale
    gap01 = moments[1] - moments[0] <= tol
    gap12 = moments[2] - moments[1] <= tol
    if scale == 0.0 or (gap01 and gap12):
        axes = np.eye(3)
    elif gap01:                                        # unique axis is the third
        u = _fix_sign(vecs[:, 2])
        a0 = _plane_basis_vector(u)
        a1 = _fix_sign(np.cross(u, a0))
        axes = np.column_stack([a0, a1, np.cross(a0, a1)])
    elif gap12:                                        # unique axis is the first
        a0 = _fix_sign(vecs[:, 0])
        a1 = _plane_basis_vector(a0)
        axes = np.column_stack([a0, a1, np.cross(a0, a1)])
    else:
        a0 = _fix_sign(vecs[:, 0])
        a1 = _fix_sign(vecs[:, 1])
        axes = np.column_stack([a0, a1, np.cross(a0, a1)])
    return moments, axes


# ---------------------------------------------------------------------------------------------
# physical validity
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PhysicalCheck:
    """Result of :func:`check_physical`: which physical conditions hold and by how much.

    Attributes
    ----------
    valid : bool
        True when every condition holds (within the tolerance used).
    failures : tuple of str
        One human-readable line per failed condition, naming it and the amount of violation.
    moments : ndarray, shape (3,)
        Principal moments of the symmetric part, ascending [kg m^2].
    min_moment : float
        Smallest principal moment I1 [kg m^2]; the positive-definiteness margin.
    triangle_margins : ndarray, shape (3,)
        ``[I2 + I3 - I1, I1 + I3 - I2, I1 + I2 - I3]`` [kg m^2]; each must be >= 0.  The last
        is the binding one for ascending moments.
    asymmetry : float
        max |I_ij - I_ji| [kg m^2].
    tolerance : float
        Absolute tolerance the margins were compared with, ``rtol * max |moment|`` [kg m^2].
    """

    valid: bool
    failures: tuple[str, ...]
    moments: np.ndarray
    min_moment: float
    triangle_margins: np.ndarray
    asymmetry: float
    tolerance: float

    def __bool__(self) -> bool:
        """Truth value is :attr:`valid`."""
        return self.valid


def check_physical(I: Any, rtol: float = 1e-9, *, allow_singular: bool = False) -> PhysicalCheck:
    """Check that an inertia matrix is a physically possible rigid-body tensor.

    Conditions: symmetric; positive definite (I1 > 0, or I1 >= 0 with ``allow_singular``, for
    idealised bodies such as a thin rod or a point mass); the triangle inequalities on the
    principal moments ``I_i + I_j >= I_k`` for every permutation.  Margins are compared with
    ``tol = rtol * max |moment|``.

    Parameters
    ----------
    I : array_like, shape (3, 3), or InertiaTensor
        Inertia matrix [kg m^2] about the centre of mass (or any point).
    rtol : float
        Relative tolerance (to the largest |moment|, and to max |I_ij| for symmetry).
    allow_singular : bool
        Accept a zero smallest moment (positive semi-definite), e.g. a thin rod about its axis.

    Returns
    -------
    PhysicalCheck
        ``valid``, ``failures`` (human readable) and the margins.

    Raises
    ------
    ValueError
        Wrong shape or NaN/inf (asymmetry is reported as a failure, not raised).
    """
    if not (np.isfinite(rtol) and rtol >= 0):
        raise ValueError(f'rtol: must be a finite number >= 0, got {rtol!r}')
    if hasattr(I, 'matrix') and not isinstance(I, np.ndarray):
        I = I.matrix
    arr = _as_float_array(I, 'I')
    if arr.shape != (3, 3):
        raise ValueError(f'I: expected shape (3, 3), got {arr.shape}')
    _check_finite(arr, 'I')
    sym = 0.5 * (arr + arr.T)
    asym = _max_asymmetry(arr)
    moments = np.linalg.eigvalsh(sym)
    scale = float(np.max(np.abs(moments)))
    tol = rtol * scale
    failures: list[str] = []
    elem_scale = float(np.max(np.abs(arr)))
    if asym > rtol * elem_scale:
        failures.append(f'not symmetric: max |I_ij - I_ji| = {asym:.6g} kg m^2 '
                        f'(tolerance {rtol * elem_scale:.3g})')
    i1 = float(moments[0])
    if scale == 0.0:
        if not allow_singular:
            failures.append('not positive definite: all principal moments are zero')
    elif allow_singular:
        if i1 < -tol:
            failures.append(f'not positive semi-definite: smallest principal moment '
                            f'I1 = {i1:.6g} kg m^2 is below 0 by {-i1:.6g}')
    elif i1 <= tol:
        failures.append(f'not positive definite: smallest principal moment I1 = {i1:.6g} kg m^2 '
                        f'(must exceed {tol:.3g})')
    total = float(np.sum(moments))
    margins = total - 2.0 * moments                     # I_j + I_k - I_i for i = 1, 2, 3
    labels = ('I2 + I3 >= I1', 'I1 + I3 >= I2', 'I1 + I2 >= I3')
    for label, margin in zip(labels, margins, strict=True):
        if margin < -tol:
            failures.append(f'triangle inequality {label} violated by {-margin:.6g} kg m^2 '
                            f'(moments {moments[0]:.6g}, {moments[1]:.6g}, {moments[2]:.6g})')
    return PhysicalCheck(valid=not failures, failures=tuple(failures), moments=moments,
                         min_moment=i1, triangle_margins=margins, asymmetry=asym, tolerance=tol)


# Constraint rows A x >= b on principal moments x: x_i >= eps and x_i + x_j - x_k >= 0.
_CONE_A = np.array([[1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [0.0, 0.0, 1.0],
                    [-1.0, 1.0, 1.0],
                    [1.0, -1.0, 1.0],
                    [1.0, 1.0, -1.0]])
_ACTIVE_SETS = [list(s) for k in range(4) for s in itertools.combinations(range(6), k)]


def _project_moments(lam: np.ndarray, eps: float) -> np.ndarray:
    """Euclidean projection of ``lam`` (3,) onto {x_i >= eps, x_i + x_j >= x_k}.

    The set is a convex polyhedron, so the projection is the feasible point nearest ``lam``
    among the projections onto the affine hulls of its faces (at most three active rows).
    """
    b = np.array([eps, eps, eps, 0.0, 0.0, 0.0])
    slack_tol = 1e-12 * max(1.0, float(np.max(np.abs(lam))), eps)
    best, best_d = None, np.inf
    for active in _ACTIVE_SETS:
        if active:
            A = _CONE_A[active]
            gram = A @ A.T
            if abs(np.linalg.det(gram)) < 1e-9:
                continue
            x = lam - A.T @ np.linalg.solve(gram, A @ lam - b[active])
        else:
            x = lam.copy()
        if np.all(_CONE_A @ x - b >= -slack_tol):
            d = float(np.sum((x - lam) ** 2))
            if d < best_d:
                best, best_d = x, d
    assert best is not None  # eps * (1, 1, 1) is always a vertex candidate
    return best


def nearest_physical(I: Any, *, min_moment: float | None = None) -> np.ndarray:
    """The physically valid inertia matrix closest to ``I`` in the Frobenius norm.

    The principal moments of the symmetric part are projected onto the convex set
    ``{I_i >= min_moment, I_i + I_j >= I_k}`` (Euclidean projection) and the principal axes are
    kept.  Because that set is invariant under permuting the moments, this is the exact
    Frobenius-nearest symmetric matrix with such a spectrum; and since symmetric and
    antisymmetric parts are orthogonal, also the nearest to an asymmetric ``I``.  A valid
    tensor is returned unchanged (up to round-off).

    Parameters
    ----------
    I : array_like, shape (3, 3), or InertiaTensor
        Inertia matrix [kg m^2]; asymmetric input is accepted (its symmetric part is used).
    min_moment : float, optional
        Lower bound for every principal moment [kg m^2], making the result positive definite.
        Default ``1e-9 * max |moment|``.

    Returns
    -------
    ndarray, shape (3, 3)
        The projected symmetric matrix [kg m^2].

    Raises
    ------
    ValueError
        Wrong shape, NaN/inf, negative ``min_moment``, or an all-zero ``I`` with no
        ``min_moment`` (no scale to take the default from).
    """
    if hasattr(I, 'matrix') and not isinstance(I, np.ndarray):
        I = I.matrix
    arr = _as_float_array(I, 'I')
    if arr.shape != (3, 3):
        raise ValueError(f'I: expected shape (3, 3), got {arr.shape}')
    _check_finite(arr, 'I')
    sym = 0.5 * (arr + arr.T)
    lam, vecs = np.linalg.eigh(sym)
    scale = float(np.max(np.abs(lam)))
    if min_moment is None:
        if scale == 0.0:
            raise ValueError('I: all principal moments are zero, so there is no scale for the '
                             'default min_moment; pass min_moment explicitly')
        eps = 1e-9 * scale
    else:
        eps = float(min_moment)
        if not (np.isfinite(eps) and eps >= 0.0):
            raise ValueError(f'min_moment: must be a finite number >= 0, got {min_moment!r}')
    x = _project_moments(lam, eps)
    if np.array_equal(x, lam):
        return sym
    out = (vecs * x) @ vecs.T
    return 0.5 * (out + out.T)


# ---------------------------------------------------------------------------------------------
# Euler's equations
# ---------------------------------------------------------------------------------------------
def _as_stack_matrix(I: Any) -> np.ndarray:
    """Validated (3, 3) or (..., 3, 3) inertia for broadcasting in Euler's equations."""
    return as_inertia_matrix(I, 'I', stacked=True)


def euler_torque(I: Any, omega: Any, omega_dot: Any) -> np.ndarray:
    """Torque from Euler's rotational equation, ``tau = I w_dot + w x (I w)``.

    All quantities about the centre of mass, in body axes.  Vectorised: leading dimensions
    of ``omega`` and ``omega_dot`` (and of ``I`` if stacked) broadcast.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    omega_dot : array_like, shape (..., 3)
        Angular acceleration [rad/s^2].

    Returns
    -------
    ndarray, shape (..., 3)
        Torque about the centre of mass [N m].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I``, or shapes that do not broadcast.
    """
    m = _as_stack_matrix(I)
    w = _as_vectors(omega, 'omega')
    wd = _as_vectors(omega_dot, 'omega_dot')
    try:
        Iw = np.einsum('...ij,...j->...i', m, w)
        return np.einsum('...ij,...j->...i', m, wd) + np.cross(w, Iw)
    except ValueError as exc:
        raise ValueError(f'omega, omega_dot: shapes {w.shape}, {wd.shape} and I {m.shape} do '
                         f'not broadcast ({exc})') from None


def euler_omega_dot(I: Any, omega: Any, tau: Any) -> np.ndarray:
    """Angular acceleration from Euler's equation, ``w_dot = I^-1 (tau - w x (I w))``.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2]; must be invertible.
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    tau : array_like, shape (..., 3)
        Torque about the centre of mass [N m].

    Returns
    -------
    ndarray, shape (..., 3)
        Angular acceleration [rad/s^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric or singular ``I``.
    """
    m = _as_stack_matrix(I)
    w = _as_vectors(omega, 'omega')
    t = _as_vectors(tau, 'tau')
    try:
        rhs = t - np.cross(w, np.einsum('...ij,...j->...i', m, w))
    except ValueError as exc:
        raise ValueError(f'omega, tau: shapes {w.shape}, {t.shape} and I {m.shape} do not '
                         f'broadcast ({exc})') from None
    lam = np.linalg.eigvalsh(m)
    scale = np.max(np.abs(lam), axis=-1)
    if np.any(np.abs(lam).min(axis=-1) <= 1e-14 * scale) or np.any(scale == 0.0):
        raise ValueError('I: singular (a principal moment is zero), so Euler\'s equation cannot '
                         'be solved for omega_dot')
    batch = np.broadcast_shapes(m.shape[:-2], rhs.shape[:-1])
    m_b = np.broadcast_to(m, batch + (3, 3))
    rhs_b = np.broadcast_to(rhs, batch + (3,))[..., None]
    return np.linalg.solve(m_b, rhs_b)[..., 0]
