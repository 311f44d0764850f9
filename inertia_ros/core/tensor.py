"""Tensor conventions: the ``theta`` <-> matrix index table, principal axes, physical validity.

Conventions (DESIGN.md, contract): SI units (kg m^2); the tensor elements are the matrix
entries, as in geometry_msgs/Inertia and URDF::

    I = [[ixx, ixy, ixz],
         [ixy, iyy, iyz],
         [ixz, iyz, izz]]

(``ixy`` is the matrix element, not a negated product of inertia) and the parameter order is
``theta = [ixx, iyy, izz, ixy, ixz, iyz]`` (:data:`THETA_NAMES`).  :data:`THETA_ROWS`,
:data:`THETA_COLS` and :data:`MATRIX_INDEX` are the one index table between the two forms:
``theta = I[..., THETA_ROWS, THETA_COLS]`` and ``I = theta[..., MATRIX_INDEX]``.  Principal
moments are ascending (I1 <= I2 <= I3); principal axes are the columns of a proper rotation
matrix, the first two each with its largest-magnitude component positive, the third their
cross product.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validate import (
    as_float_array,
    as_matrix33,
    as_rotation,
    check_symmetric,
    max_asymmetry,
    require_finite,
)

__all__ = [
    'DEGENERACY_RTOL',
    'MATRIX_INDEX',
    'SYMMETRY_RTOL',
    'THETA_COLS',
    'THETA_NAMES',
    'THETA_ROWS',
    'PhysicalCheck',
    'as_inertia_matrix',
    'axes_to_quaternion',
    'check_physical',
    'matrix_to_theta',
    'nearest_physical',
    'principal_axes',
    'theta_to_matrix',
]

#: Names of the six unique tensor elements, in the parameter order of ``theta`` (contract).
THETA_NAMES: tuple[str, ...] = ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')

#: (row, column) of each theta element in the 3x3 matrix, in THETA_NAMES order.
THETA_ROWS = np.array([0, 1, 2, 0, 0, 1])
THETA_COLS = np.array([0, 1, 2, 1, 2, 2])
#: theta index of each matrix element (row-major), for theta_to_matrix.
MATRIX_INDEX = np.array([[0, 3, 4],
                         [3, 1, 5],
                         [4, 5, 2]])

#: Default relative tolerance for "symmetric within tolerance" (relative to max |I_ij|).
SYMMETRY_RTOL = 1e-9
#: Relative spread (to the largest |moment|) below which principal moments count as repeated.
DEGENERACY_RTOL = 1e-13
for _table in (THETA_ROWS, THETA_COLS, MATRIX_INDEX):
    _table.setflags(write=False)      # one table for the whole package: never modified
del _table


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
    arr = as_float_array(I, name)
    if stacked:
        if arr.ndim < 2 or arr.shape[-2:] != (3, 3):
            raise ValueError(f'{name}: expected shape (..., 3, 3), got {arr.shape}')
    elif arr.shape != (3, 3):
        raise ValueError(f'{name}: expected shape (3, 3), got {arr.shape}')
    if check_finite:
        require_finite(arr, name)
    check_symmetric(arr, name, rtol)
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
    arr = as_float_array(theta, 'theta')
    if arr.ndim < 1 or arr.shape[-1] != 6:
        raise ValueError(f'theta: expected shape (..., 6), got {arr.shape}')
    if check_finite:
        require_finite(arr, 'theta')
    return arr[..., MATRIX_INDEX]


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
    return sym[..., THETA_ROWS, THETA_COLS]


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
    arr = as_matrix33(I, 'I')
    sym = 0.5 * (arr + arr.T)
    asym = max_asymmetry(arr)
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
    arr = as_matrix33(I, 'I')
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

    q = Rotation.from_matrix(as_rotation(axes, 'axes')).as_quat()
    return -q if q[3] < 0 else q

