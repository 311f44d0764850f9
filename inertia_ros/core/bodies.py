"""Textbook rigid-body primitives, each an :class:`InertiaTensor` about its centre of mass.

Axis convention (all primitives): the body sits at the origin with its centre of mass there;
a body with a symmetry axis (rod, disc, ring, cylinders, cone) has it along z; laminae lie in
the xy plane; boxes and laminae have their edges along x, y (, z).  Place a primitive in an
assembly with :meth:`InertiaTensor.transformed` (``x' = R x + t``) and combine parts with ``+``
or :func:`~inertia_ros.core.inertia.composite`.

Formulas (m mass, r radius, L / h length along z, a / b / c edge lengths along x / y / z):

==========================  ===========================  ==================  =============
body                        I_xx                         I_yy                I_zz
==========================  ===========================  ==================  =============
point mass                  0                            0                   0
thin rod (centre), along z  m L^2 / 12                   m L^2 / 12          0
thin rod (end), along +z    m L^2 / 3                    m L^2 / 3           0
rectangular lamina (xy)     m b^2 / 12                   m a^2 / 12          m (a^2+b^2)/12
thin disc (xy)              m r^2 / 4                    m r^2 / 4           m r^2 / 2
thin ring (xy)              m r^2 / 2                    m r^2 / 2           m r^2
solid sphere                2/5 m r^2                    2/5 m r^2           2/5 m r^2
hollow sphere (thin shell)  2/3 m r^2                    2/3 m r^2           2/3 m r^2
solid box                   m (b^2+c^2) / 12             m (a^2+c^2) / 12    m (a^2+b^2)/12
solid cylinder              m (3 r^2 + h^2) / 12         same                m r^2 / 2
thin-walled cylinder        m (6 r^2 + h^2) / 12         same                m r^2
hollow cylinder (r1 < r2)   m (3 (r1^2+r2^2) + h^2) / 12 same                m (r1^2+r2^2)/2
solid cone (about CoM)      3/80 m (4 r^2 + h^2)         same                3/10 m r^2
==========================  ===========================  ==================  =============

References: any mechanics text's table of moments of inertia, e.g. Goldstein, Poole & Safko,
*Classical Mechanics* (3rd ed.), ch. 5; Meriam & Kraige, *Engineering Mechanics: Dynamics*,
appendix B.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from inertia_ros.core._validate import as_mass, as_vector3
from inertia_ros.core.inertia import InertiaTensor

__all__ = [
    'hollow_cylinder',
    'hollow_sphere',
    'point_mass',
    'rectangular_lamina',
    'solid_box',
    'solid_cone',
    'solid_cylinder',
    'solid_sphere',
    'thin_disc',
    'thin_ring',
    'thin_rod',
    'thin_walled_cylinder',
]


def _length(x: Any, name: str, *, allow_zero: bool = False) -> float:
    """A finite length > 0 (>= 0 with ``allow_zero``) [m]; ValueError names ``name``."""
    try:
        val = float(x)
    except (TypeError, ValueError):
        raise ValueError(f'{name}: expected a number [m], got {x!r}') from None
    if not np.isfinite(val):
        raise ValueError(f'{name}: must be finite, got {val!r}')
    if val < 0.0 or (val == 0.0 and not allow_zero):
        raise ValueError(f'{name}: must be {">= 0" if allow_zero else "> 0"} m, got {val!r}')
    return val


def _diag(m: float, ixx: float, iyy: float, izz: float) -> InertiaTensor:
    """A body at the origin with a diagonal tensor about its centre of mass."""
    return InertiaTensor(np.diag([ixx, iyy, izz]), m)


def point_mass(m: float, position: Any = (0.0, 0.0, 0.0)) -> InertiaTensor:
    """A point mass: zero tensor about itself.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    position : array_like, shape (3,)
        Where the mass is (its centre of mass) [m].

    Returns
    -------
    InertiaTensor
        Zero matrix about ``position``; shift it to get ``m (|r|^2 1 - r r^T)``.
    """
    mass = as_mass(m, 'm', positive=True)
    p = as_vector3(position, 'position')
    return InertiaTensor(np.zeros((3, 3)), mass, p, p)


def thin_rod(m: float, length: float, about: str = 'center') -> InertiaTensor:
    """A thin uniform rod along z.

    ``about='center'``: centred at the origin, tensor about the centre of mass:
    ``I_xx = I_yy = m L^2 / 12``, ``I_zz = 0``.
    ``about='end'``: one end at the origin, rod along +z (centre of mass at ``(0, 0, L/2)``),
    tensor about that end: ``I_xx = I_yy = m L^2 / 3``, ``I_zz = 0``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    length : float
        Length L [m], > 0.
    about : {'center', 'end'}
        Reference point of the tensor.

    Returns
    -------
    InertiaTensor
    """
    mass = as_mass(m, 'm', positive=True)
    L = _length(length, 'length')
    if about == 'center':
        return _diag(mass, mass * L**2 / 12.0, mass * L**2 / 12.0, 0.0)
    if about == 'end':
        return InertiaTensor(np.diag([mass * L**2 / 3.0, mass * L**2 / 3.0, 0.0]), mass,
                             com=[0.0, 0.0, L / 2.0], point=[0.0, 0.0, 0.0])
    raise ValueError(f"about: expected 'center' or 'end', got {about!r}")


def rectangular_lamina(m: float, a: float, b: float) -> InertiaTensor:
    """A thin uniform rectangular plate in the xy plane, sides a (along x) and b (along y).

    ``I_xx = m b^2 / 12``, ``I_yy = m a^2 / 12``, ``I_zz = m (a^2 + b^2) / 12``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    a, b : float
        Side lengths along x and y [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre of mass (the plate's centre).
    """
    mass = as_mass(m, 'm', positive=True)
    a, b = _length(a, 'a'), _length(b, 'b')
    return _diag(mass, mass * b**2 / 12.0, mass * a**2 / 12.0, mass * (a**2 + b**2) / 12.0)


def thin_disc(m: float, r: float) -> InertiaTensor:
    """A thin uniform disc in the xy plane (axis z).

    ``I_xx = I_yy = m r^2 / 4``, ``I_zz = m r^2 / 2``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r : float
        Radius [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre.
    """
    mass = as_mass(m, 'm', positive=True)
    r = _length(r, 'r')
    return _diag(mass, mass * r**2 / 4.0, mass * r**2 / 4.0, mass * r**2 / 2.0)


def thin_ring(m: float, r: float) -> InertiaTensor:
    """A thin uniform ring (hoop) in the xy plane (axis z).

    ``I_xx = I_yy = m r^2 / 2``, ``I_zz = m r^2``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r : float
        Radius [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre.
    """
    mass = as_mass(m, 'm', positive=True)
    r = _length(r, 'r')
    return _diag(mass, mass * r**2 / 2.0, mass * r**2 / 2.0, mass * r**2)


def solid_sphere(m: float, r: float) -> InertiaTensor:
    """A uniform solid sphere: ``I = 2/5 m r^2`` about every axis through the centre.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r : float
        Radius [m], > 0.

    Returns
    -------
    InertiaTensor
    """
    mass = as_mass(m, 'm', positive=True)
    r = _length(r, 'r')
    i = 0.4 * mass * r**2
    return _diag(mass, i, i, i)


def hollow_sphere(m: float, r: float) -> InertiaTensor:
    """A thin uniform spherical shell: ``I = 2/3 m r^2`` about every axis through the centre.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r : float
        Radius [m], > 0.

    Returns
    -------
    InertiaTensor
    """
    mass = as_mass(m, 'm', positive=True)
    r = _length(r, 'r')
    i = 2.0 / 3.0 * mass * r**2
    return _diag(mass, i, i, i)


def solid_box(m: float, a: float, b: float, c: float) -> InertiaTensor:
    """A uniform solid cuboid with edges a, b, c along x, y, z.

    ``I_xx = m (b^2 + c^2) / 12``, ``I_yy = m (a^2 + c^2) / 12``, ``I_zz = m (a^2 + b^2) / 12``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    a, b, c : float
        Edge lengths along x, y, z [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre.
    """
    mass = as_mass(m, 'm', positive=True)
    a, b, c = _length(a, 'a'), _length(b, 'b'), _length(c, 'c')
    return _diag(mass, mass * (b**2 + c**2) / 12.0, mass * (a**2 + c**2) / 12.0,
                 mass * (a**2 + b**2) / 12.0)


def solid_cylinder(m: float, r: float, h: float) -> InertiaTensor:
    """A uniform solid cylinder, axis z, centred at the origin.

    ``I_xx = I_yy = m (3 r^2 + h^2) / 12``, ``I_zz = m r^2 / 2``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r : float
        Radius [m], > 0.
    h : float
        Height (length along z) [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre.
    """
    mass = as_mass(m, 'm', positive=True)
    r, h = _length(r, 'r'), _length(h, 'h')
    it = mass * (3.0 * r**2 + h**2) / 12.0
    return _diag(mass, it, it, mass * r**2 / 2.0)


def thin_walled_cylinder(m: float, r: float, h: float) -> InertiaTensor:
    """A thin-walled open tube (no end caps), axis z, centred at the origin.

    ``I_xx = I_yy = m (6 r^2 + h^2) / 12 = m (r^2 / 2 + h^2 / 12)``, ``I_zz = m r^2``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r : float
        Radius [m], > 0.
    h : float
        Height (length along z) [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre.
    """
    mass = as_mass(m, 'm', positive=True)
    r, h = _length(r, 'r'), _length(h, 'h')
    it = mass * (6.0 * r**2 + h**2) / 12.0
    return _diag(mass, it, it, mass * r**2)


def hollow_cylinder(m: float, r_outer: float, r_inner: float, h: float) -> InertiaTensor:
    """A thick-walled uniform tube (no end caps), axis z, centred at the origin.

    ``I_xx = I_yy = m (3 (r1^2 + r2^2) + h^2) / 12``, ``I_zz = m (r1^2 + r2^2) / 2``.  It is
    :func:`solid_cylinder` for ``r_inner = 0`` and :func:`thin_walled_cylinder` for
    ``r_inner = r_outer``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r_outer : float
        Outer radius r2 [m], > 0.
    r_inner : float
        Inner radius r1 [m], 0 <= r1 <= r2.
    h : float
        Height (length along z) [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre.
    """
    mass = as_mass(m, 'm', positive=True)
    r2, r1 = _length(r_outer, 'r_outer'), _length(r_inner, 'r_inner', allow_zero=True)
    h = _length(h, 'h')
    if r1 > r2:
        raise ValueError(f'r_inner: must be <= r_outer = {r2!r} m, got {r1!r}')
    s = r1**2 + r2**2
    it = mass * (3.0 * s + h**2) / 12.0
    return _diag(mass, it, it, mass * s / 2.0)


def solid_cone(m: float, r: float, h: float) -> InertiaTensor:
    """A uniform solid right circular cone, axis z, about its centre of mass.

    The centre of mass is a quarter of the height above the base, so with it at the origin
    the base disc lies in the plane ``z = -h/4`` and the apex is at ``(0, 0, 3h/4)``.
    ``I_xx = I_yy = 3/80 m (4 r^2 + h^2)``, ``I_zz = 3/10 m r^2``.

    Parameters
    ----------
    m : float
        Mass [kg], > 0.
    r : float
        Base radius [m], > 0.
    h : float
        Height [m], > 0.

    Returns
    -------
    InertiaTensor
        About the centre of mass.
    """
    mass = as_mass(m, 'm', positive=True)
    r, h = _length(r, 'r'), _length(h, 'h')
    it = 3.0 / 80.0 * mass * (4.0 * r**2 + h**2)
    return _diag(mass, it, it, 0.3 * mass * r**2)
