"""Rigid-body inertia tensors: the :class:`InertiaTensor` value type, :class:`Ellipsoid` (from
:mod:`.mechanics`, with the body's mechanics) and :func:`composite` bodies.

The public path of the whole tensor toolkit: the conventions and array functions live in
:mod:`.tensor` (``theta`` <-> matrix, principal axes, physical validity, quaternions) and
:mod:`.dynamics` (Euler's equations, momentum, energy, pendulum, parallel axis), and are
re-exported here, so ``from inertia_ros.core.inertia import X`` works for all of them.  The
textbook primitives (point mass, rod, lamina, ... cone) are in :mod:`inertia_ros.core.bodies`.

Conventions (DESIGN.md, contract): SI units; ``theta = [ixx, iyy, izz, ixy, ixz, iyz]``
(:data:`THETA_NAMES`), the matrix entries as in geometry_msgs/Inertia and URDF.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._validate import (
    as_float_array,
    as_mass,
    as_rotation,
    as_vector3,
    as_vectors,
    require_finite,
)
from .dynamics import (
    STANDARD_GRAVITY,
    angular_momentum,
    angular_momentum_about_point,
    euler_omega_dot,
    euler_torque,
    kinetic_energy,
    kinetic_energy_rate,
    mechanical_power,
    moment_about_axis,
    parallel_axis,
    parallel_axis_to_com,
    pendulum_period,
    power_identity_residual,
    rotational_kinetic_energy,
    shift_term,
)
from .mechanics import BodyMechanics, Ellipsoid
from .tensor import (
    DEGENERACY_RTOL,
    SYMMETRY_RTOL,
    THETA_COLS,
    THETA_NAMES,
    THETA_ROWS,
    PhysicalCheck,
    as_inertia_matrix,
    axes_to_quaternion,
    check_physical,
    matrix_to_theta,
    nearest_physical,
    principal_axes,
    theta_to_matrix,
)

__all__ = [
    'DEGENERACY_RTOL',
    'STANDARD_GRAVITY',
    'SYMMETRY_RTOL',
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
    return as_vector3(x, name)


@dataclass(frozen=True, eq=False)
class InertiaTensor(BodyMechanics):
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
    The mechanics of the body (radii of gyration, ellipsoids, angular momentum, kinetic
    energy, pendulum period) come from :class:`.mechanics.BodyMechanics`.
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
            object.__setattr__(self, 'mass', as_mass(self.mass))
        com = np.zeros(3) if self.com is None else as_vector3(self.com, 'com')
        object.__setattr__(self, 'com', _readonly(com))
        point = com if self.point is None else as_vector3(self.point, 'point')
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
        th = as_float_array(theta, 'theta')
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
        mom = as_vector3(moments, 'moments')
        R = np.eye(3) if axes is None else as_rotation(axes, 'axes')
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
        mass = as_mass(m, 'm')
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
        p = as_vectors(positions, 'positions')
        if p.ndim != 2 or p.shape[0] < 1:
            raise ValueError(f'positions: expected shape (N, 3) with N >= 1, got {p.shape}')
        w = as_float_array(masses, 'masses')
        if w.ndim == 0:
            w = np.full(p.shape[0], float(w))
        if w.shape != (p.shape[0],):
            raise ValueError(f'masses: expected a scalar or shape ({p.shape[0]},), '
                             f'got {w.shape}')
        require_finite(w, 'masses')
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
        return self.matrix[THETA_ROWS, THETA_COLS]

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
        return float(moment_about_axis(self.matrix, as_vector3(axis, 'axis')))

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
        q = as_vector3(point, 'point')
        if np.array_equal(q, self.point):
            return self
        m = self._require_mass('shifted (parallel-axis theorem)')
        mat = self.matrix - shift_term(m, self.point - self.com) + shift_term(m, q - self.com)
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
        R = np.eye(3) if rotation is None else as_rotation(rotation)
        t = np.zeros(3) if translation is None else as_vector3(translation, 'translation')
        mat = R @ self.matrix @ R.T
        return InertiaTensor(0.5 * (mat + mat.T), self.mass, R @ self.com + t,
                             R @ self.point + t)

    def rotated(self, rotation: Any) -> InertiaTensor:
        """:meth:`transformed` with a rotation only (``R I R^T``)."""
        return self.transformed(rotation=rotation)

    def translated(self, translation: Any) -> InertiaTensor:
        """:meth:`transformed` with a translation only (matrix unchanged)."""
        return self.transformed(translation=translation)

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
    s = np.ones(len(parts)) if signs is None else as_float_array(signs, 'signs')
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
        mat += sign * p.about_com().matrix + shift_term(float(m_i), p.com - c)
    return InertiaTensor(0.5 * (mat + mat.T), total, c, c)

