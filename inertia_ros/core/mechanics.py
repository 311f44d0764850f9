"""What a rigid body's inertia tensor says about its motion: the :class:`BodyMechanics` part of
:class:`.inertia.InertiaTensor` (radii of gyration, the ellipsoids that picture the tensor,
angular momentum, kinetic energy, the pendulum period) and the :class:`Ellipsoid` it draws.

Kept apart from the value type itself (construction, validation, conversions, the reference
point and the frame, composites, comparison), which lives in :mod:`.inertia`; both are
re-exported there.  Conventions as :mod:`.inertia`: SI units, vectors in the tensor's frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ._validate import as_unit_axis, as_vector3
from .dynamics import (
    STANDARD_GRAVITY,
    angular_momentum,
    angular_momentum_about_point,
    kinetic_energy,
    pendulum_period,
    rotational_kinetic_energy,
)
from .tensor import axes_to_quaternion

if TYPE_CHECKING:
    from .inertia import InertiaTensor

__all__ = ['BodyMechanics', 'Ellipsoid']


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



class BodyMechanics:
    """Mechanics of the body a tensor describes (mixed into :class:`.inertia.InertiaTensor`).

    Uses the value type's fields (``matrix`` [kg m^2] about ``point``, ``mass`` [kg] or
    ``None``, ``com`` and ``point`` [m], shape (3,)) and its frame operations
    (:meth:`~.inertia.InertiaTensor.about_com`, ``shifted``, ``about_axis``, ``principal``).
    """

    if TYPE_CHECKING:
        matrix: np.ndarray
        mass: float | None
        com: np.ndarray
        point: np.ndarray

        @property
        def principal_moments(self) -> np.ndarray: ...
        def principal(self) -> tuple[np.ndarray, np.ndarray]: ...
        def about_axis(self, axis: Any) -> float: ...
        def about_com(self) -> InertiaTensor: ...
        def shifted(self, point: Any) -> InertiaTensor: ...

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
        r_pc = self.com - as_vector3(point, 'point')
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
        n = as_unit_axis(as_vector3(axis, 'axis'))
        p = as_vector3(pivot, 'pivot')
        d = self.com - p
        h = float(np.linalg.norm(d - np.dot(d, n) * n))
        if h == 0.0:
            raise ValueError('pivot: the centre of mass lies on the pivot axis (h = 0), '
                             'so the body does not swing')
        return float(pendulum_period(self.shifted(p).about_axis(n), m, h, g))
