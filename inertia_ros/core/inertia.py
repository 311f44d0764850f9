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
says so.  This module holds the array functions, the :class:`InertiaTensor` value type,
composite bodies (:func:`composite`, ``+``, ``-``) and the dynamics helpers (angular momentum,
kinetic energy, pendulum period, the power identity); the textbook primitives (point mass,
rod, lamina, ... cone) are in :mod:`inertia_ros.core.bodies`.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    'STANDARD_GRAVITY',
    'THETA_NAMES',
    'Ellipsoid',
    'InertiaTensor',
    'PhysicalCheck',
    'angular_momentum',
    'angular_momentum_about_point',
    'as_inertia_matrix',
    'axes_to_quaternion',
    'check_physical',
    'composite',
    'euler_omega_dot',
    'euler_torque',
    'kinetic_energy',
    'kinetic_energy_rate',
    'matrix_to_theta',
    'mechanical_power',
    'moment_about_axis',
    'nearest_physical',
    'parallel_axis',
    'parallel_axis_to_com',
    'pendulum_period',
    'power_identity_residual',
    'principal_axes',
    'rotational_kinetic_energy',
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
DEGENERACY_RTOL = 1e-13


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


def _matrix33(I: Any, name: str) -> np.ndarray:
    """``I`` (array-like or anything with ``.matrix``) as a finite float (3, 3) array."""
    if hasattr(I, 'matrix') and not isinstance(I, np.ndarray):
        I = I.matrix
    arr = _as_float_array(I, name)
    if arr.shape != (3, 3):
        raise ValueError(f'{name}: expected shape (3, 3), got {arr.shape}')
    _check_finite(arr, name)
    return arr


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
@dataclass(frozen=True, eq=False)
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
    arr = _matrix33(I, 'I')
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
_CONE_B = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0])     # b = eps * _CONE_B


def _face_projectors() -> tuple[np.ndarray, np.ndarray]:
    """Affine projectors onto every face of the constraint polyhedron.

    For each set S of at most three linearly independent active rows, the projection of
    ``lam`` onto {A_S x = eps b_S} is ``M_S lam + eps c_S`` with
    ``M_S = 1 - A_S^T G^-1 A_S``, ``c_S = A_S^T G^-1 b_S`` and ``G = A_S A_S^T``.
    """
    mats, offs = [np.eye(3)], [np.zeros(3)]
    for k in range(1, 4):
        for active in itertools.combinations(range(6), k):
            A = _CONE_A[list(active)]
            gram = A @ A.T
            if abs(np.linalg.det(gram)) < 1e-9:
                continue
            ginv = np.linalg.inv(gram)
            mats.append(np.eye(3) - A.T @ ginv @ A)
            offs.append(A.T @ ginv @ _CONE_B[list(active)])
    return np.array(mats), np.array(offs)


_FACE_M, _FACE_C = _face_projectors()


def _project_moments(lam: np.ndarray, eps: float) -> np.ndarray:
    """Euclidean projection of ``lam`` (3,) onto {x_i >= eps, x_i + x_j >= x_k}.

    The set is a convex polyhedron, so the projection is the feasible point nearest ``lam``
    among the projections onto the affine hulls of its faces (at most three active rows);
    all candidates are evaluated at once.
    """
    cand = _FACE_M @ lam + eps * _FACE_C                  # (K, 3)
    # Relative to the tensor's own scale: an absolute floor would call tiny tensors valid.
    slack_tol = 1e-12 * max(float(np.max(np.abs(lam))), eps, np.finfo(float).tiny)
    feasible = np.all(cand @ _CONE_A.T - eps * _CONE_B >= -slack_tol, axis=1)
    dist = np.where(feasible, np.sum((cand - lam) ** 2, axis=1), np.inf)
    if feasible[0]:                                       # already valid: exactly unchanged
        return lam
    return cand[int(np.argmin(dist))]                    # eps * (1, 1, 1) is always feasible


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
        Default ``1e-8 * max |moment|`` (so the result passes :func:`check_physical`
        at its default tolerance).

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
    arr = _matrix33(I, 'I')
    sym = 0.5 * (arr + arr.T)
    lam, vecs = np.linalg.eigh(sym)
    scale = float(np.max(np.abs(lam)))
    if min_moment is None:
        if scale == 0.0:
            raise ValueError('I: all principal moments are zero, so there is no scale for the '
                             'default min_moment; pass min_moment explicitly')
        eps = 1e-8 * scale
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
def _matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``m @ v`` for m (3, 3) or (..., 3, 3) and v (..., 3), broadcasting leading dims."""
    if m.ndim == 2:
        return v @ m.T
    return np.einsum('...ij,...j->...i', m, v)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (faster than np.cross for small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


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
        return _matvec(m, wd) + _cross(w, _matvec(m, w))
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
        rhs = t - _cross(w, _matvec(m, w))
    except ValueError as exc:
        raise ValueError(f'omega, tau: shapes {w.shape}, {t.shape} and I {m.shape} do not '
                         f'broadcast ({exc})') from None
    lam = np.linalg.eigvalsh(m)
    scale = np.max(np.abs(lam), axis=-1)
    if np.any(np.abs(lam).min(axis=-1) <= 1e-14 * scale) or np.any(scale == 0.0):
        raise ValueError('I: singular (a principal moment is zero), so Euler\'s equation cannot '
                         'be solved for omega_dot')
    if m.ndim == 2:                                    # one inertia: invert once, multiply
        return _matvec(np.linalg.inv(m), rhs)
    batch = np.broadcast_shapes(m.shape[:-2], rhs.shape[:-1])
    m_b = np.broadcast_to(m, batch + (3, 3))
    rhs_b = np.broadcast_to(rhs, batch + (3,))[..., None]
    return np.linalg.solve(m_b, rhs_b)[..., 0]


# ---------------------------------------------------------------------------------------------
# parallel-axis theorem and scalar helpers on arrays
# ---------------------------------------------------------------------------------------------
#: Standard gravity [m/s^2] (the default for pendulum periods).
STANDARD_GRAVITY = 9.80665


def _as_mass(m: Any, name: str = 'mass', *, positive: bool = False) -> float:
    """A finite mass >= 0 (> 0 when ``positive``) as float; ValueError names ``name``."""
    try:
        val = float(m)
    except (TypeError, ValueError):
        raise ValueError(f'{name}: expected a number [kg], got {m!r}') from None
    if not np.isfinite(val):
        raise ValueError(f'{name}: must be finite, got {val!r}')
    if val < 0.0 or (positive and val == 0.0):
        raise ValueError(f'{name}: must be {"> 0" if positive else ">= 0"} kg, got {val!r}')
    return val


def _as_unit_axis(n: Any, name: str = 'axis') -> np.ndarray:
    """Normalise a non-zero finite (..., 3) direction; ValueError names ``name``."""
    v = _as_vectors(n, name)
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(norm == 0.0):
        raise ValueError(f'{name}: zero vector has no direction; pass a non-zero axis')
    return v / norm


def _as_rotation(R: Any, name: str = 'rotation', atol: float = 1e-9) -> np.ndarray:
    """A (3, 3) proper rotation matrix (orthonormal within ``atol``, det +1)."""
    arr = _as_float_array(R, name)
    if arr.shape != (3, 3):
        raise ValueError(f'{name}: expected shape (3, 3), got {arr.shape}')
    _check_finite(arr, name)
    err = float(np.max(np.abs(arr @ arr.T - np.eye(3))))
    if err > atol:
        raise ValueError(f'{name}: not orthonormal: max |R R^T - 1| = {err:.3g} '
                         f'exceeds {atol:.1g}')
    if np.linalg.det(arr) < 0.0:
        raise ValueError(f'{name}: det = -1 is a reflection, not a proper rotation')
    return arr


def _shift_term(mass: float, r: np.ndarray) -> np.ndarray:
    """``m (|r|^2 1 - r r^T)``, shape (3, 3) [kg m^2]."""
    return mass * (np.dot(r, r) * np.eye(3) - np.outer(r, r))


def parallel_axis(I_com: Any, mass: Any, r: Any) -> np.ndarray:
    """Parallel-axis theorem in tensor form: inertia about a point P from that about the CoM.

    ``I_P = I_C + m (|r|^2 1 - r r^T)`` with ``r = P - C`` (the sign of ``r`` does not matter).

    Parameters
    ----------
    I_com : array_like, shape (3, 3), or InertiaTensor
        Inertia about the centre of mass C [kg m^2].
    mass : float
        Mass [kg], >= 0.
    r : array_like, shape (3,)
        Offset between P and C [m], in the frame of ``I_com``.

    Returns
    -------
    ndarray, shape (3, 3)
        Inertia about P [kg m^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I_com`` or negative ``mass``.
    """
    return as_inertia_matrix(I_com, 'I_com') + _shift_term(_as_mass(mass), _as_vector3(r, 'r'))


def parallel_axis_to_com(I_point: Any, mass: Any, r: Any) -> np.ndarray:
    """Inverse parallel-axis theorem: inertia about the CoM from that about a point P.

    ``I_C = I_P - m (|r|^2 1 - r r^T)`` with ``r = P - C``.

    Parameters
    ----------
    I_point : array_like, shape (3, 3), or InertiaTensor
        Inertia about P [kg m^2].
    mass : float
        Mass [kg], >= 0.
    r : array_like, shape (3,)
        Offset between P and C [m].

    Returns
    -------
    ndarray, shape (3, 3)
        Inertia about the centre of mass [kg m^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I_point`` or negative ``mass``.
    """
    return (as_inertia_matrix(I_point, 'I_point')
            - _shift_term(_as_mass(mass), _as_vector3(r, 'r')))


def moment_about_axis(I: Any, axis: Any) -> np.ndarray | float:
    """Moment of inertia about an axis through the reference point, ``n^T I n`` with |n| = 1.

    Parameters
    ----------
    I : array_like, shape (3, 3), or InertiaTensor
        Inertia matrix [kg m^2].
    axis : array_like, shape (3,) or (..., 3)
        Axis direction(s), any non-zero length (normalised here).

    Returns
    -------
    float or ndarray, shape (...)
        Moment(s) of inertia [kg m^2].

    Raises
    ------
    ValueError
        Bad shapes, NaN/inf, asymmetric ``I`` or a zero axis.
    """
    m = as_inertia_matrix(I, 'I')
    n = _as_unit_axis(axis)
    val = np.einsum('...i,ij,...j->...', n, m, n)
    return float(val) if val.ndim == 0 else val


def axes_to_quaternion(axes: Any) -> np.ndarray:
    """Quaternion ``[x, y, z, w]`` (ROS order, w >= 0) of a proper rotation matrix.

    Useful for publishing principal axes or an ellipsoid orientation
    (geometry_msgs/Quaternion): the rotation maps body axes onto the given columns.

    Parameters
    ----------
    axes : array_like, shape (3, 3)
        Proper rotation matrix, columns are the rotated x, y, z axes.

    Returns
    -------
    ndarray, shape (4,)
        Unit quaternion ``[x, y, z, w]`` with ``w >= 0``.

    Raises
    ------
    ValueError
        Not a proper rotation matrix.
    """
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(_as_rotation(axes, 'axes')).as_quat()
    return -q if q[3] < 0 else q


# ---------------------------------------------------------------------------------------------
# dynamics on arrays
# ---------------------------------------------------------------------------------------------
def angular_momentum(I: Any, omega: Any) -> np.ndarray:
    """Angular momentum about the centre of mass, ``L = I w``.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s], same frame as ``I``.

    Returns
    -------
    ndarray, shape (..., 3)
        Angular momentum [kg m^2/s].
    """
    return np.einsum('...ij,...j->...i', _as_stack_matrix(I), _as_vectors(omega, 'omega'))


def angular_momentum_about_point(I_com: Any, mass: Any, omega: Any, r_pc: Any,
                                 v_com: Any) -> np.ndarray:
    """Angular momentum about a point P, ``L_P = I_C w + m r_PC x v_C``.

    Parameters
    ----------
    I_com : array_like, shape (3, 3), or InertiaTensor
        Inertia about the centre of mass C [kg m^2].
    mass : float
        Mass [kg].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    r_pc : array_like, shape (..., 3)
        Position of C relative to P, ``C - P`` [m].
    v_com : array_like, shape (..., 3)
        Velocity of C [m/s] (relative to the frame P is fixed in).

    Returns
    -------
    ndarray, shape (..., 3)
        Angular momentum about P [kg m^2/s]; all vectors in one frame.
    """
    m = _as_mass(mass)
    r = _as_vectors(r_pc, 'r_pc')
    v = _as_vectors(v_com, 'v_com')
    return angular_momentum(I_com, omega) + m * np.cross(r, v)


def rotational_kinetic_energy(I: Any, omega: Any) -> np.ndarray | float:
    """Rotational kinetic energy ``T_rot = 1/2 w . (I w)``.

    Parameters
    ----------
    I : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].

    Returns
    -------
    float or ndarray, shape (...)
        Energy [J].
    """
    w = _as_vectors(omega, 'omega')
    val = 0.5 * np.einsum('...i,...i->...', w, angular_momentum(I, w))
    return float(val) if np.ndim(val) == 0 else val


def kinetic_energy(I_com: Any, mass: Any, omega: Any, v_com: Any) -> np.ndarray | float:
    """Total kinetic energy ``T = 1/2 m |v_C|^2 + 1/2 w . (I_C w)`` (Koenig's theorem).

    Parameters
    ----------
    I_com : array_like, shape (3, 3) or (..., 3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    mass : float
        Mass [kg].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    v_com : array_like, shape (..., 3)
        Velocity of the centre of mass [m/s].

    Returns
    -------
    float or ndarray, shape (...)
        Energy [J].
    """
    v = _as_vectors(v_com, 'v_com')
    val = 0.5 * _as_mass(mass) * np.einsum('...i,...i->...', v, v) \
        + rotational_kinetic_energy(I_com, omega)
    return float(val) if np.ndim(val) == 0 else val


def pendulum_period(I_pivot: Any, mass: Any, h: Any,
                    g: float = STANDARD_GRAVITY) -> np.ndarray | float:
    """Small-amplitude period of a physical pendulum, ``2 pi sqrt(I / (m g h))``.

    Parameters
    ----------
    I_pivot : float or array_like
        Moment of inertia about the pivot axis [kg m^2], > 0.
    mass : float
        Mass [kg], > 0.
    h : float or array_like
        Distance from the pivot axis to the centre of mass [m], > 0.
    g : float
        Gravitational acceleration [m/s^2], > 0.

    Returns
    -------
    float or ndarray
        Period [s].

    Raises
    ------
    ValueError
        Non-positive or non-finite inputs.
    """
    i = _as_float_array(I_pivot, 'I_pivot')
    hh = _as_float_array(h, 'h')
    for arr, name in ((i, 'I_pivot'), (hh, 'h')):
        _check_finite(arr, name)
        if np.any(arr <= 0.0):
            raise ValueError(f'{name}: must be > 0, got {arr.min():.6g}')
    m = _as_mass(mass, positive=True)
    gg = _as_mass(g, 'g', positive=True)
    val = 2.0 * np.pi * np.sqrt(i / (m * gg * hh))
    return float(val) if np.ndim(val) == 0 else val


def mechanical_power(velocity: Any, force: Any, omega: Any, torque: Any) -> np.ndarray | float:
    """Power delivered to a rigid body, ``P = v_C . F + w . M``.

    ``F`` is the resultant force and ``M`` the resultant torque about the centre of mass; ``v_C``
    and ``F`` share one frame, ``w`` and ``M`` share one frame (e.g. body axes).

    Parameters
    ----------
    velocity : array_like, shape (..., 3)
        Velocity of the centre of mass [m/s].
    force : array_like, shape (..., 3)
        Resultant force [N].
    omega : array_like, shape (..., 3)
        Angular velocity [rad/s].
    torque : array_like, shape (..., 3)
        Resultant torque about the centre of mass [N m].

    Returns
    -------
    float or ndarray, shape (...)
        Power [W].
    """
    v = _as_vectors(velocity, 'velocity')
    f = _as_vectors(force, 'force')
    w = _as_vectors(omega, 'omega')
    t = _as_vectors(torque, 'torque')
    val = np.einsum('...i,...i->...', v, f) + np.einsum('...i,...i->...', w, t)
    return float(val) if np.ndim(val) == 0 else val


def kinetic_energy_rate(I_com: Any, mass: Any, velocity: Any, acceleration: Any, omega: Any,
                        omega_dot: Any) -> np.ndarray | float:
    """Analytic ``dT/dt = m v_C . a_C + w . (I_C w_dot)`` for a rigid body.

    Valid with ``v``, ``a`` in an inertial frame and ``w``, ``w_dot``, ``I_C`` in body axes
    (where ``I_C`` is constant).  By Newton and Euler it equals :func:`mechanical_power`
    (the power identity ``dT/dt = v . F + w . M``), because ``w . (w x I w) = 0``.

    Parameters
    ----------
    I_com : array_like, shape (3, 3), or InertiaTensor
        Inertia about the centre of mass [kg m^2].
    mass : float
        Mass [kg].
    velocity, acceleration : array_like, shape (..., 3)
        Velocity [m/s] and acceleration [m/s^2] of the centre of mass.
    omega, omega_dot : array_like, shape (..., 3)
        Angular velocity [rad/s] and acceleration [rad/s^2].

    Returns
    -------
    float or ndarray, shape (...)
        Rate of change of kinetic energy [W].
    """
    v = _as_vectors(velocity, 'velocity')
    a = _as_vectors(acceleration, 'acceleration')
    w = _as_vectors(omega, 'omega')
    val = _as_mass(mass) * np.einsum('...i,...i->...', v, a) \
        + np.einsum('...i,...i->...', w, angular_momentum(I_com, omega_dot))
    return float(val) if np.ndim(val) == 0 else val


def power_identity_residual(t: Any, energy: Any, velocity: Any, force: Any, omega: Any,
                            torque: Any) -> np.ndarray:
    """Check the power identity on sampled data: ``dT/dt - (v . F + w . M)``.

    ``dT/dt`` is taken from the sampled kinetic energy by second-order finite differences
    (:func:`numpy.gradient`), so the residual is O(dt^2) for smooth motion and exposes
    wrong inertia, wrong frames or unmodelled forces/torques.

    Parameters
    ----------
    t : array_like, shape (N,)
        Strictly increasing sample times [s], N >= 3.
    energy : array_like, shape (N,)
        Kinetic energy at each sample [J] (e.g. from :func:`kinetic_energy`).
    velocity, force, omega, torque : array_like, shape (N, 3)
        As in :func:`mechanical_power` [m/s, N, rad/s, N m].

    Returns
    -------
    ndarray, shape (N,)
        Residual power [W].

    Raises
    ------
    ValueError
        Bad shapes, fewer than 3 samples, non-increasing ``t`` or NaN/inf.
    """
    tt = _as_float_array(t, 't')
    e = _as_float_array(energy, 'energy')
    if tt.ndim != 1 or tt.size < 3:
        raise ValueError(f't: expected shape (N,) with N >= 3, got {tt.shape}')
    if e.shape != tt.shape:
        raise ValueError(f'energy: expected shape {tt.shape} like t, got {e.shape}')
    _check_finite(tt, 't')
    _check_finite(e, 'energy')
    if np.any(np.diff(tt) <= 0.0):
        raise ValueError('t: must be strictly increasing')
    p = mechanical_power(velocity, force, omega, torque)
    if np.shape(p) != tt.shape:
        raise ValueError(f'velocity, force, omega, torque: expected shape ({tt.size}, 3), '
                         f'giving power of shape {np.shape(p)}')
    return np.gradient(e, tt, edge_order=2) - p


# ---------------------------------------------------------------------------------------------
# the value type
# ---------------------------------------------------------------------------------------------
def _readonly(a: np.ndarray) -> np.ndarray:
    """A read-only float64 copy of ``a``."""
    out = np.array(a, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


def _vector_from_msg(x: Any, name: str) -> np.ndarray:
    """(3,) from a sequence or from an object with ``x``, ``y``, ``z`` (geometry_msgs/Vector3)."""
    if all(hasattr(x, k) for k in ('x', 'y', 'z')):
        x = (x.x, x.y, x.z)
    return _as_vector3(x, name)


@dataclass(frozen=True, eq=False)
class Ellipsoid:
    """An ellipsoid for drawing a tensor: centre, semi-axes and orientation.

    Attributes
    ----------
    center : ndarray, shape (3,)
        Centre [m] (the tensor's reference point).
    semi_axes : ndarray, shape (3,)
        Semi-axis lengths along the columns of ``axes`` (units depend on the kind: [m] for
        ``'equivalent'`` and ``'gyration'``, [kg^-1/2 m^-1] for ``'inertia'``).
    axes : ndarray, shape (3, 3)
        Proper rotation; column k is the direction of semi-axis k (the principal axes).
    kind : str
        ``'inertia'``, ``'equivalent'`` or ``'gyration'`` (see :meth:`InertiaTensor.ellipsoid`).
    """

    center: np.ndarray
    semi_axes: np.ndarray
    axes: np.ndarray
    kind: str

    @property
    def quaternion(self) -> np.ndarray:
        """Orientation as quaternion ``[x, y, z, w]`` (ROS order), shape (4,)."""
        return axes_to_quaternion(self.axes)

    @property
    def diameters(self) -> np.ndarray:
        """Full lengths ``2 * semi_axes``, shape (3,) (visualization_msgs Marker scale)."""
        return 2.0 * self.semi_axes

    def surface(self, n: int = 24) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Surface grid for plotting (e.g. matplotlib ``plot_surface``).

        Parameters
        ----------
        n : int
            Number of latitude samples (>= 3); longitude uses ``2 n``.

        Returns
        -------
        x, y, z : ndarray, shape (n, 2 n)
            Surface point coordinates, in the units of ``semi_axes``, offset by ``center``.
        """
        if int(n) != n or n < 3:
            raise ValueError(f'n: must be an integer >= 3, got {n!r}')
        n = int(n)
        u = np.linspace(0.0, np.pi, n)[:, None]
        v = np.linspace(0.0, 2.0 * np.pi, 2 * n)[None, :]
        local = np.stack([np.sin(u) * np.cos(v), np.sin(u) * np.sin(v),
                          np.cos(u) * np.ones_like(v)], axis=-1) * self.semi_axes
        world = local @ self.axes.T + self.center
        return world[..., 0], world[..., 1], world[..., 2]


@dataclass(frozen=True, eq=False)
class InertiaTensor:
    """Immutable inertia tensor of a rigid body about a reference point.

    The matrix is about :attr:`point` (by default the centre of mass), expressed in the axes
    of the frame all the vectors here are in.  Arrays are stored read-only.  Validation on
    construction: ``matrix`` finite, shape (3, 3), symmetric within ``1e-9`` relative (the
    symmetric part is stored); ``mass`` finite and >= 0 if given; ``com`` and ``point``
    finite, shape (3,).  Physical validity is *not* enforced (estimates may be unphysical);
    use :meth:`check` or :func:`check_physical`.

    Parameters
    ----------
    matrix : array_like, shape (3, 3)
        Inertia about ``point`` [kg m^2].
    mass : float, optional
        Mass [kg]; needed for the parallel-axis theorem, composites, radius of gyration.
    com : array_like, shape (3,), optional
        Centre of mass position [m]; default the origin.
    point : array_like, shape (3,), optional
        Reference point the matrix is about [m]; default ``com``.

    Notes
    -----
    ``a + b`` (and :func:`composite`) combine bodies about their common centre of mass;
    ``a - b`` removes a part (a hole).  Equality is exact; use :meth:`allclose` for floats.
    """

    matrix: np.ndarray
    mass: float | None = None
    com: np.ndarray = None  # type: ignore[assignment]
    point: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        """Validate and freeze the fields."""
        object.__setattr__(self, 'matrix', _readonly(as_inertia_matrix(self.matrix, 'matrix')))
        if self.mass is not None:
            object.__setattr__(self, 'mass', _as_mass(self.mass))
        com = np.zeros(3) if self.com is None else _as_vector3(self.com, 'com')
        object.__setattr__(self, 'com', _readonly(com))
        point = com if self.point is None else _as_vector3(self.point, 'point')
        object.__setattr__(self, 'point', _readonly(point))

    # -- constructors ------------------------------------------------------------------------
    @classmethod
    def from_theta(cls, theta: Any, mass: float | None = None, com: Any = None,
                   point: Any = None) -> InertiaTensor:
        """From ``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2] (matrix elements, DESIGN order).

        Parameters
        ----------
        theta : array_like, shape (6,)
            The six unique elements [kg m^2].
        mass, com, point
            As in the class signature.

        Returns
        -------
        InertiaTensor
        """
        th = _as_float_array(theta, 'theta')
        if th.shape != (6,):
            raise ValueError(f'theta: expected shape (6,), got {th.shape}')
        return cls(theta_to_matrix(th), mass, com, point)

    @classmethod
    def from_matrix(cls, matrix: Any, mass: float | None = None, com: Any = None,
                    point: Any = None, *, rtol: float = SYMMETRY_RTOL) -> InertiaTensor:
        """From a 3x3 matrix, validated finite and symmetric within ``rtol``.

        Parameters
        ----------
        matrix : array_like, shape (3, 3)
            Inertia [kg m^2] about ``point``.
        mass, com, point
            As in the class signature.
        rtol : float
            Symmetry tolerance relative to max |I_ij|; the symmetric part is kept.

        Returns
        -------
        InertiaTensor
        """
        return cls(as_inertia_matrix(matrix, 'matrix', rtol=rtol), mass, com, point)

    @classmethod
    def from_principal(cls, moments: Any, axes: Any = None, mass: float | None = None,
                       com: Any = None, point: Any = None) -> InertiaTensor:
        """From principal moments and axes, ``I = R diag(moments) R^T``.

        Parameters
        ----------
        moments : array_like, shape (3,)
            Principal moments [kg m^2], any order (matching the columns of ``axes``).
        axes : array_like, shape (3, 3), optional
            Proper rotation whose columns are the principal axes; default identity.
        mass, com, point
            As in the class signature.

        Returns
        -------
        InertiaTensor
        """
        mom = _as_vector3(moments, 'moments')
        R = np.eye(3) if axes is None else _as_rotation(axes, 'axes')
        mat = (R * mom) @ R.T
        return cls(0.5 * (mat + mat.T), mass, com, point)

    @classmethod
    def from_inertia_msg(cls, m: Any, com: Any, ixx: float, ixy: float, ixz: float,
                         iyy: float, iyz: float, izz: float) -> InertiaTensor:
        """From geometry_msgs/Inertia-shaped data (plain numbers; no ROS import).

        The message's tensor is about its centre of mass ``com``.  ``m = 0`` (unknown mass,
        as estimators publish) gives ``mass=None``.  ``InertiaTensor.from_inertia_msg(
        **t.to_inertia_msg())`` round-trips.

        Parameters
        ----------
        m : float
            Mass [kg], >= 0.
        com : array_like, shape (3,), or an object with ``x``, ``y``, ``z``
            Centre of mass [m].
        ixx, ixy, ixz, iyy, iyz, izz : float
            Matrix elements [kg m^2].

        Returns
        -------
        InertiaTensor
            About the centre of mass.
        """
        mass = _as_mass(m, 'm')
        c = _vector_from_msg(com, 'com')
        theta = []
        for name, val in (('ixx', ixx), ('iyy', iyy), ('izz', izz), ('ixy', ixy),
                          ('ixz', ixz), ('iyz', iyz)):
            try:
                theta.append(float(val))
            except (TypeError, ValueError):
                raise ValueError(f'{name}: expected a number [kg m^2], got {val!r}') from None
            if not np.isfinite(theta[-1]):
                raise ValueError(f'{name}: must be finite, got {theta[-1]!r}')
        return cls(theta_to_matrix(theta), mass if mass > 0.0 else None, c, c)

    @classmethod
    def from_point_masses(cls, positions: Any, masses: Any) -> InertiaTensor:
        """From a cloud of point masses (e.g. a sampled or voxelised body), about its CoM.

        ``M = sum m_k``, ``C = sum m_k p_k / M``, ``I_C = sum m_k (|r_k|^2 1 - r_k r_k^T)``
        with ``r_k = p_k - C``.

        Parameters
        ----------
        positions : array_like, shape (N, 3)
            Point positions [m], N >= 1.
        masses : float or array_like, shape (N,)
            Point masses [kg], each >= 0, total > 0 (a scalar is used for every point).

        Returns
        -------
        InertiaTensor
            About the centre of mass, with the total mass.
        """
        p = _as_vectors(positions, 'positions')
        if p.ndim != 2 or p.shape[0] < 1:
            raise ValueError(f'positions: expected shape (N, 3) with N >= 1, got {p.shape}')
        w = _as_float_array(masses, 'masses')
        if w.ndim == 0:
            w = np.full(p.shape[0], float(w))
        if w.shape != (p.shape[0],):
            raise ValueError(f'masses: expected a scalar or shape ({p.shape[0]},), '
                             f'got {w.shape}')
        _check_finite(w, 'masses')
        if np.any(w < 0.0):
            raise ValueError(f'masses: must be >= 0 kg, smallest is {w.min()!r}')
        total = float(np.sum(w))
        if not total > 0.0:
            raise ValueError('masses: total mass must be > 0 kg')
        c = w @ p / total
        r = p - c
        mat = np.sum(w * np.einsum('ki,ki->k', r, r)) * np.eye(3) - (r.T * w) @ r
        return cls(0.5 * (mat + mat.T), total, c, c)

    def to_inertia_msg(self) -> dict[str, Any]:
        """geometry_msgs/Inertia fields as plain numbers, about the centre of mass.

        Returns
        -------
        dict
            ``m`` [kg] (0.0 when the mass is unknown), ``com`` (x, y, z) [m], and ``ixx``,
            ``ixy``, ``ixz``, ``iyy``, ``iyz``, ``izz`` [kg m^2].

        Raises
        ------
        ValueError
            The tensor is not about its centre of mass and the mass is unknown.
        """
        c = self.about_com()
        mat = c.matrix
        return {'m': 0.0 if c.mass is None else c.mass,
                'com': tuple(float(v) for v in c.com),
                'ixx': float(mat[0, 0]), 'ixy': float(mat[0, 1]), 'ixz': float(mat[0, 2]),
                'iyy': float(mat[1, 1]), 'iyz': float(mat[1, 2]), 'izz': float(mat[2, 2])}

    # -- derived quantities ------------------------------------------------------------------
    @property
    def theta(self) -> np.ndarray:
        """``[ixx, iyy, izz, ixy, ixz, iyz]`` [kg m^2], shape (6,)."""
        return self.matrix[_THETA_ROWS, _THETA_COLS]

    @property
    def principal_moments(self) -> np.ndarray:
        """Principal moments, ascending [kg m^2], shape (3,)."""
        return principal_axes(self.matrix)[0]

    @property
    def principal_axes(self) -> np.ndarray:
        """Principal axes as columns of a proper rotation, shape (3, 3) (DESIGN convention)."""
        return principal_axes(self.matrix)[1]

    def principal(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal moments (3,) ascending [kg m^2] and axes (3, 3) in one decomposition."""
        return principal_axes(self.matrix)

    @property
    def trace(self) -> float:
        """Trace of the matrix [kg m^2]."""
        return float(np.trace(self.matrix))

    @property
    def is_about_com(self) -> bool:
        """True when the reference point is the centre of mass."""
        return bool(np.array_equal(self.point, self.com))

    def check(self, rtol: float = 1e-9, *, allow_singular: bool = False) -> PhysicalCheck:
        """Physical validity of the matrix: :func:`check_physical` (see there).

        Parameters
        ----------
        rtol : float
            Relative tolerance.
        allow_singular : bool
            Accept a zero smallest moment (thin rods, point masses).

        Returns
        -------
        PhysicalCheck
        """
        return check_physical(self.matrix, rtol, allow_singular=allow_singular)

    def about_axis(self, axis: Any) -> float:
        """Moment about an axis through :attr:`point`, ``n^T I n`` [kg m^2].

        Parameters
        ----------
        axis : array_like, shape (3,)
            Direction, any non-zero length.
        """
        return float(moment_about_axis(self.matrix, _as_vector3(axis, 'axis')))

    def _require_mass(self, what: str, positive: bool = False) -> float:
        """The mass, or ValueError explaining that ``what`` needs it."""
        if self.mass is None:
            raise ValueError(f'mass: {what} needs the mass, but this tensor has mass=None')
        if positive and self.mass <= 0.0:
            raise ValueError(f'mass: {what} needs mass > 0, got {self.mass!r}')
        return self.mass

    def radius_of_gyration(self, axis: Any) -> float:
        """Radius of gyration about an axis through :attr:`point`, ``sqrt(I_n / m)`` [m].

        Parameters
        ----------
        axis : array_like, shape (3,)
            Direction, any non-zero length.
        """
        m = self._require_mass('radius_of_gyration', positive=True)
        return float(np.sqrt(max(self.about_axis(axis), 0.0) / m))

    def principal_radii_of_gyration(self) -> np.ndarray:
        """Radii of gyration about the principal axes, ``sqrt(I_k / m)`` [m], shape (3,)."""
        m = self._require_mass('principal_radii_of_gyration', positive=True)
        return np.sqrt(np.clip(self.principal_moments, 0.0, None) / m)

    def ellipsoid(self, kind: str = 'inertia') -> Ellipsoid:
        """An ellipsoid picturing the tensor, centred at :attr:`point`, along principal axes.

        Parameters
        ----------
        kind : {'inertia', 'equivalent', 'gyration'}
            ``'inertia'``: Poinsot's inertia ellipsoid ``x^T I x = 1``, semi-axes
            ``1 / sqrt(I_k)`` [kg^-1/2 m^-1] (longest about the axis of least inertia);
            needs positive moments.  ``'equivalent'``: the uniform solid ellipsoid with the
            same mass and tensor, semi-axes ``sqrt(5 (I_j + I_k - I_i) / (2 m))`` [m] (the
            body's "shape"); needs mass and the triangle inequalities.  ``'gyration'``:
            semi-axes are the principal radii of gyration ``sqrt(I_k / m)`` [m].

        Returns
        -------
        Ellipsoid
        """
        moments, axes = self.principal()
        if kind == 'inertia':
            if moments[0] <= 0.0:
                raise ValueError('kind: the inertia ellipsoid needs positive principal '
                                 f'moments, smallest is {moments[0]:.6g}')
            semi = 1.0 / np.sqrt(moments)
        elif kind == 'equivalent':
            m = self._require_mass("ellipsoid(kind='equivalent')", positive=True)
            margins = np.sum(moments) - 2.0 * moments
            tol = 1e-9 * float(np.max(np.abs(moments)))
            if np.any(margins < -tol):
                raise ValueError('kind: the equivalent ellipsoid needs the triangle '
                                 f'inequalities, margins {margins}')
            semi = np.sqrt(2.5 * np.clip(margins, 0.0, None) / m)
        elif kind == 'gyration':
            semi = self.principal_radii_of_gyration()
        else:
            raise ValueError(f"kind: expected 'inertia', 'equivalent' or 'gyration', "
                             f'got {kind!r}')
        return Ellipsoid(center=self.point.copy(), semi_axes=semi, axes=axes, kind=kind)

    # -- moving the reference point and the frame --------------------------------------------
    def about_com(self) -> InertiaTensor:
        """The same body with the tensor about its centre of mass (inverse parallel axis)."""
        if self.is_about_com:
            return self
        return self.shifted(self.com)

    def shifted(self, point: Any) -> InertiaTensor:
        """The same body with the tensor about another point (parallel-axis theorem).

        Goes through the centre of mass: ``I_C = I_P - m S(P - C)``, then
        ``I_Q = I_C + m S(Q - C)`` with ``S(r) = |r|^2 1 - r r^T``.

        Parameters
        ----------
        point : array_like, shape (3,)
            New reference point Q [m].

        Returns
        -------
        InertiaTensor
            With ``point = Q``; mass and centre of mass unchanged.
        """
        q = _as_vector3(point, 'point')
        if np.array_equal(q, self.point):
            return self
        m = self._require_mass('shifted (parallel-axis theorem)')
        mat = self.matrix - _shift_term(m, self.point - self.com) + _shift_term(m, q - self.com)
        return InertiaTensor(mat, m, self.com, q)

    def transformed(self, rotation: Any = None, translation: Any = None) -> InertiaTensor:
        """The body expressed in (or moved to) another frame: ``x' = R x + t``.

        The matrix becomes ``R I R^T``; centre of mass and reference point map as points.

        Parameters
        ----------
        rotation : array_like, shape (3, 3), optional
            Proper rotation ``R`` (default identity).
        translation : array_like, shape (3,), optional
            Offset ``t`` [m] (default zero).

        Returns
        -------
        InertiaTensor
        """
        R = np.eye(3) if rotation is None else _as_rotation(rotation)
        t = np.zeros(3) if translation is None else _as_vector3(translation, 'translation')
        mat = R @ self.matrix @ R.T
        return InertiaTensor(0.5 * (mat + mat.T), self.mass, R @ self.com + t,
                             R @ self.point + t)

    def rotated(self, rotation: Any) -> InertiaTensor:
        """:meth:`transformed` with a rotation only (``R I R^T``)."""
        return self.transformed(rotation=rotation)

    def translated(self, translation: Any) -> InertiaTensor:
        """:meth:`transformed` with a translation only (matrix unchanged)."""
        return self.transformed(translation=translation)

    # -- dynamics ----------------------------------------------------------------------------
    def angular_momentum(self, omega: Any, velocity: Any = None,
                         point: Any = None) -> np.ndarray:
        """Angular momentum ``I_C w`` about the CoM, or ``I_C w + m r_PC x v_C`` about P.

        Parameters
        ----------
        omega : array_like, shape (..., 3)
            Angular velocity [rad/s].
        velocity : array_like, shape (..., 3), optional
            Velocity of the centre of mass [m/s] (needed with ``point``).
        point : array_like, shape (3,), optional
            Point P [m] the momentum is taken about; default the centre of mass.

        Returns
        -------
        ndarray, shape (..., 3)
            Angular momentum [kg m^2/s].
        """
        c = self.about_com()
        if point is None:
            return angular_momentum(c.matrix, omega)
        if velocity is None:
            raise ValueError('velocity: angular momentum about a point needs the centre of '
                             'mass velocity')
        m = self._require_mass('angular momentum about a point')
        r_pc = self.com - _as_vector3(point, 'point')
        return angular_momentum_about_point(c.matrix, m, omega, r_pc, velocity)

    def kinetic_energy(self, omega: Any, velocity: Any = None) -> np.ndarray | float:
        """Kinetic energy: rotational ``1/2 w.I_C w`` plus ``1/2 m |v_C|^2`` if ``velocity``.

        Parameters
        ----------
        omega : array_like, shape (..., 3)
            Angular velocity [rad/s].
        velocity : array_like, shape (..., 3), optional
            Velocity of the centre of mass [m/s].

        Returns
        -------
        float or ndarray, shape (...)
            Energy [J].
        """
        c = self.about_com()
        if velocity is None:
            return rotational_kinetic_energy(c.matrix, omega)
        return kinetic_energy(c.matrix, self._require_mass('kinetic energy'), omega, velocity)

    def pendulum_period(self, pivot: Any, axis: Any, g: float = STANDARD_GRAVITY) -> float:
        """Small-oscillation period swinging about an axis through ``pivot``.

        ``T = 2 pi sqrt(I_axis / (m g h))`` with ``I_axis`` about the pivot axis and ``h`` the
        distance of the centre of mass from that axis.

        Parameters
        ----------
        pivot : array_like, shape (3,)
            A point on the (horizontal) pivot axis [m].
        axis : array_like, shape (3,)
            Pivot axis direction, any non-zero length.
        g : float
            Gravitational acceleration [m/s^2].

        Returns
        -------
        float
            Period [s].
        """
        m = self._require_mass('pendulum_period', positive=True)
        n = _as_unit_axis(_as_vector3(axis, 'axis'))
        p = _as_vector3(pivot, 'pivot')
        d = self.com - p
        h = float(np.linalg.norm(d - np.dot(d, n) * n))
        if h == 0.0:
            raise ValueError('pivot: the centre of mass lies on the pivot axis (h = 0), '
                             'so the body does not swing')
        return float(pendulum_period(self.shifted(p).about_axis(n), m, h, g))

    # -- composites --------------------------------------------------------------------------
    def __add__(self, other: object) -> InertiaTensor:
        """Composite of two bodies about their common centre of mass."""
        if not isinstance(other, InertiaTensor):
            return NotImplemented
        return composite([self, other])

    def __radd__(self, other: object) -> InertiaTensor:
        """Support ``sum(parts)`` (``0 + part``)."""
        if isinstance(other, int | float) and other == 0:
            return self
        return NotImplemented

    def __sub__(self, other: object) -> InertiaTensor:
        """Remove a part (e.g. a hole) from a body: the composite with negative mass."""
        if not isinstance(other, InertiaTensor):
            return NotImplemented
        return composite([self, other], signs=[1.0, -1.0])

    # -- comparison --------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        """Exact equality of all fields."""
        if not isinstance(other, InertiaTensor):
            return NotImplemented
        return (self.mass == other.mass and np.array_equal(self.matrix, other.matrix)
                and np.array_equal(self.com, other.com)
                and np.array_equal(self.point, other.point))

    def __hash__(self) -> int:
        """Hash of all fields (consistent with exact equality)."""
        return hash((self.matrix.tobytes(), self.mass, self.com.tobytes(),
                     self.point.tobytes()))

    def allclose(self, other: InertiaTensor, rtol: float = 1e-9, atol: float = 0.0) -> bool:
        """Whether matrix, mass, com and point agree within ``rtol``/``atol``.

        Parameters
        ----------
        other : InertiaTensor
            Tensor to compare with.
        rtol : float
            Relative tolerance: to the largest matrix element for the matrix, to the mass, and
            to max(1 m, largest coordinate) for ``com`` and ``point``.
        atol : float
            Absolute tolerance, applied to every field in its own units.

        Returns
        -------
        bool
            False also when one mass is known and the other is None.
        """
        if (self.mass is None) != (other.mass is None):
            return False
        scale = max(float(np.max(np.abs(self.matrix))), float(np.max(np.abs(other.matrix))))
        if not np.all(np.abs(self.matrix - other.matrix) <= atol + rtol * scale):
            return False
        if self.mass is not None and not np.isclose(self.mass, other.mass, rtol=rtol,
                                                    atol=atol):
            return False
        lscale = max(1.0, float(np.max(np.abs(np.r_[self.com, other.com]))))
        return bool(np.all(np.abs(self.com - other.com) <= atol + rtol * lscale)
                    and np.all(np.abs(self.point - other.point) <= atol + rtol * lscale))

    def __repr__(self) -> str:
        """Compact representation."""
        th = ', '.join(f'{k}={v:.6g}' for k, v in zip(THETA_NAMES, self.theta, strict=True))
        extra = '' if self.is_about_com else f', point={self.point.tolist()}'
        return f'InertiaTensor({th}, mass={self.mass}, com={self.com.tolist()}{extra})'


def composite(parts: Any, signs: Any = None) -> InertiaTensor:
    """Combine bodies into one, about their common centre of mass.

    ``M = sum m_i``, ``C = sum m_i c_i / M`` and ``I_C = sum (I_Ci + m_i S(c_i - C))`` with
    ``S(r) = |r|^2 1 - r r^T``.  Every part's tensor must be in the same frame; parts may be
    about any reference point (they are moved to their own centre of mass first).

    Parameters
    ----------
    parts : sequence of InertiaTensor
        At least one part, each with a mass.
    signs : sequence of float, optional
        +1 to add, -1 to remove a part (e.g. a hole); default all +1.

    Returns
    -------
    InertiaTensor
        About the composite centre of mass, with the total mass.

    Raises
    ------
    ValueError
        No parts, a part without mass, or a total mass <= 0.
    """
    parts = list(parts)
    if not parts:
        raise ValueError('parts: need at least one InertiaTensor')
    for k, p in enumerate(parts):
        if not isinstance(p, InertiaTensor):
            raise ValueError(f'parts[{k}]: expected InertiaTensor, got {type(p).__name__}')
        if p.mass is None:
            raise ValueError(f'parts[{k}]: mass is None; composites need every part\'s mass')
    s = np.ones(len(parts)) if signs is None else _as_float_array(signs, 'signs')
    if s.shape != (len(parts),):
        raise ValueError(f'signs: expected shape ({len(parts)},), got {s.shape}')
    masses = s * np.array([p.mass for p in parts])
    total = float(np.sum(masses))
    if not total > 0.0:
        raise ValueError(f'parts: total mass must be > 0 kg, got {total!r}')
    coms = np.array([p.com for p in parts])
    c = masses @ coms / total
    mat = np.zeros((3, 3))
    for sign, p, m_i in zip(s, parts, masses, strict=True):
        mat += sign * p.about_com().matrix + _shift_term(float(m_i), p.com - c)
    return InertiaTensor(0.5 * (mat + mat.T), total, c, c)
